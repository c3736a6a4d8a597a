"""How well the points that were not seen are filled: per-point errors and the plain
baseline a motion-capture user would try (issue 24).

* :func:`point_errors`: the error of every point in every frame after the per-frame
  similarity alignment of :func:`nrsfm.metrics.e3d`, in units of the RMS radius of the
  ground-truth shape of that frame (so a frame's e3d is the RMS of its points' errors).
* :func:`e3d_seen`: e3d over the points seen in each frame only.
* :func:`rigid_neighbour_fill`: each point, in each frame it was not seen, carried
  rigidly with its nearest visible neighbours from the frame it was last seen in.
"""

from __future__ import annotations

import numpy as np

from ..geometry import align_similarity, centre_points, procrustes_so3
from ..validation import check_integer, check_shapes

__all__ = ["e3d_seen", "lost_point_means", "point_errors", "rigid_neighbour_fill"]


def _observed(observed, F, P):
    observed = np.asarray(observed, bool)
    if observed.shape != (F, P):
        raise ValueError(f"observed must have shape {(F, P)}; got {observed.shape}")
    return observed


def _checked(X_est, X_gt):
    X_gt = check_shapes(X_gt, "X_gt")
    return check_shapes(X_est, "X_est", X_gt.shape[0], X_gt.shape[2]), X_gt


def point_errors(X_est, X_gt):
    """Per-point, per-frame 3D error after e3d's per-frame similarity alignment.

    Parameters
    ----------
    X_est, X_gt : (F, 3, P) ndarray
        Estimated and ground-truth shapes; the whole estimated shape of each frame is
        aligned onto the centred ground truth (rotation, reflection, scale), as in
        :func:`nrsfm.metrics.e3d`.

    Returns
    -------
    (F, P) ndarray
        ``|x_gt - x_aligned|`` of each point divided by the frame's RMS radius
        ``||X_gt,f - centroid||_F / sqrt(P)``; the RMS over the points of a frame is that
        frame's e3d.
    """
    X_est, X_gt = _checked(X_est, X_gt)
    B = centre_points(X_gt)
    err = np.linalg.norm(B - align_similarity(X_est, X_gt), axis=1)
    radius = np.linalg.norm(B, axis=(1, 2)) / np.sqrt(B.shape[2])
    return err / radius[:, None]


def e3d_seen(X_est, X_gt, observed):
    """e3d over the points seen in each frame: per frame, the similarity alignment and the
    relative error of :func:`nrsfm.metrics.e3d` on those points alone, averaged over the
    frames that see at least 3 points.

    Parameters
    ----------
    X_est, X_gt : (F, 3, P) ndarray
    observed : (F, P) bool array_like
        True where a point was seen.

    Returns
    -------
    float
    """
    X_est, X_gt = _checked(X_est, X_gt)
    observed = _observed(observed, X_gt.shape[0], X_gt.shape[2])
    errs = []
    for f in np.flatnonzero(observed.sum(axis=1) >= 3):
        seen = observed[f]
        A, B = X_est[f:f + 1][..., seen], X_gt[f:f + 1][..., seen]
        Bc = centre_points(B)
        errs.append(np.linalg.norm(Bc - align_similarity(A, B)) / np.linalg.norm(Bc))
    return float(np.mean(errs))


def lost_point_means(errors, observed):
    """(P,) mean of ``errors`` over the frames each point was not seen in (NaN for a
    point seen in every frame)."""
    missing = ~np.asarray(observed, bool)
    total = np.where(missing, errors, 0.0).sum(axis=0)
    count = missing.sum(axis=0)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _reference_frames(seen):
    """(F,) for one point: its last frame seen at or before each frame, else its first
    frame seen after it (-1 where it is never seen)."""
    F = seen.size
    idx = np.where(seen, np.arange(F), -1)
    last = np.maximum.accumulate(idx)
    first = np.flatnonzero(seen)
    return np.where(last >= 0, last, first[0] if first.size else -1)


def _rigid_carry(A, B, x):
    """``x`` moved by the best rotation + translation taking the points A onto B (3, k);
    by the mean translation alone when k < 3."""
    ca, cb = A.mean(axis=1, keepdims=True), B.mean(axis=1, keepdims=True)
    if A.shape[1] < 3:
        return x + (cb - ca)[:, 0]
    return procrustes_so3((B - cb) @ (A - ca).T) @ (x - ca[:, 0]) + cb[:, 0]


def rigid_neighbour_fill(shapes, observed, k=4):
    """The motion-capture user's gap fill: each lost point carried rigidly with its ``k``
    nearest visible neighbours, in 3D on a reconstruction.

    For a point ``p`` not seen in frame ``f``: its reference frame ``r`` is the last frame
    before ``f`` that saw it (the first one after ``f`` for a track that starts late). Its
    neighbours are the ``k`` points nearest to it in ``shapes[r]`` among those seen in both
    ``r`` and ``f``; the rotation and translation that best take their positions in ``r``
    onto those in ``f`` (Kabsch, no reflection, no scale: markers on one body part move
    rigidly) carry ``shapes[r][:, p]`` to its fill in ``f``. With fewer than 3 such
    neighbours it moves with their mean translation (not at all with none). Points seen in
    a frame, and points never seen, keep their shapes.

    This is "rigid body fill" of motion-capture software, done on the reconstruction's 3D
    of the visible points (W holds 2D only): the fill a user of :func:`nrsfm.reconstruct`
    would make from its shapes without trusting its fills.

    Parameters
    ----------
    shapes : (F, 3, P) ndarray
        Reconstructed shapes (e.g. :attr:`nrsfm.Reconstruction.shapes`).
    observed : (F, P) bool array_like
        True where a point was seen.
    k : int
        Neighbours per fill (default 4).

    Returns
    -------
    (F, 3, P) ndarray
        ``shapes`` with every point's unseen frames replaced by the rigid fill.
    """
    X = check_shapes(shapes, "shapes")
    k = check_integer(k, "k", minimum=1)
    observed = _observed(observed, X.shape[0], X.shape[2])
    out = X.copy()
    for p in np.flatnonzero(~observed.all(axis=0) & observed.any(axis=0)):
        ref = _reference_frames(observed[:, p])
        for f in np.flatnonzero(~observed[:, p]):
            r = ref[f]
            cand = observed[r] & observed[f]
            cand[p] = False
            d = np.where(cand, np.linalg.norm(X[r] - X[r][:, p:p + 1], axis=0), np.inf)
            nb = np.argsort(d, kind="stable")[:min(k, int(cand.sum()))]
            out[f, :, p] = _rigid_carry(X[r][:, nb], X[f][:, nb], X[r][:, p])
    return out
