"""How well the points that were not seen are filled: per-point errors, e3d over the seen
points, and the plain baseline a motion-capture user would try (rigid-neighbour fill)."""

from __future__ import annotations

import numpy as np

from ..geometry import align_similarity, centre_points, procrustes_so3
from ..validation import check_integer, check_shapes


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

    Returns
    -------
    (F, P) ndarray
        ``|x_gt - x_aligned|`` divided by the frame's RMS radius
        ``||X_gt,f - centroid||_F / sqrt(P)``: the RMS over a frame's points is its e3d.
    """
    X_est, X_gt = _checked(X_est, X_gt)
    B = centre_points(X_gt)
    err = np.linalg.norm(B - align_similarity(X_est, X_gt), axis=1)
    return err / (np.linalg.norm(B, axis=(1, 2)) / np.sqrt(B.shape[2]))[:, None]


def e3d_seen(X_est, X_gt, observed):
    """e3d over the points seen in each frame (``observed``: (F, P) bool): per frame, the
    alignment and relative error of :func:`nrsfm.metrics.e3d` on those points alone,
    averaged over the frames that see at least 3 points."""
    X_est, X_gt = _checked(X_est, X_gt)
    observed = _observed(observed, X_gt.shape[0], X_gt.shape[2])
    errs = []
    for f in np.flatnonzero(observed.sum(axis=1) >= 3):
        A, B = X_est[f : f + 1][..., observed[f]], X_gt[f : f + 1][..., observed[f]]
        Bc = centre_points(B)
        errs.append(np.linalg.norm(Bc - align_similarity(A, B)) / np.linalg.norm(Bc))
    return float(np.mean(errs))


def lost_point_means(errors, observed):
    """(P,) mean of ``errors`` over the frames each point was not seen in (NaN for a point
    seen in every frame)."""
    missing = ~np.asarray(observed, bool)
    count = missing.sum(axis=0)
    total = np.where(missing, errors, 0.0).sum(axis=0)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _reference_frames(seen):
    """(F,) for one point: its last frame seen at or before each frame, else its first frame
    seen (-1 where it is never seen)."""
    last = np.maximum.accumulate(np.where(seen, np.arange(seen.size), -1))
    first = np.flatnonzero(seen)
    return np.where(last >= 0, last, first[0] if first.size else -1)


def _rigid_carry(A, B, x):
    """``x`` moved by the rotation + translation taking the points A onto B (3, k); by the
    mean translation alone when k < 3."""
    ca, cb = A.mean(axis=1, keepdims=True), B.mean(axis=1, keepdims=True)
    if A.shape[1] < 3:
        return x + (cb - ca)[:, 0]
    return procrustes_so3((B - cb) @ (A - ca).T) @ (x - ca[:, 0]) + cb[:, 0]


def rigid_neighbour_fill(shapes, observed, k=4):
    """Motion-capture "rigid body fill": each point ``p`` not seen in frame ``f`` carried
    from its reference frame ``r`` (the last one before ``f`` that saw it, else the first
    after) by the rotation and translation (Kabsch) that take its ``k`` nearest neighbours
    seen in both frames from ``r`` to ``f`` (fewer than 3: their mean translation).

    Parameters
    ----------
    shapes : (F, 3, P) ndarray
    observed : (F, P) bool array_like
        True where a point was seen.
    k : int

    Returns
    -------
    (F, 3, P) ndarray
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
            d = np.where(cand, np.linalg.norm(X[r] - X[r][:, p : p + 1], axis=0), np.inf)
            nb = np.argsort(d, kind="stable")[: min(k, int(cand.sum()))]
            out[f, :, p] = _rigid_carry(X[r][:, nb], X[f][:, nb], X[r][:, p])
    return out
