"""Rotations and alignments used by every stage: one home for each.

* :func:`project_to_so3`: the nearest rotation to a 3 x 3 matrix (also the SO(3)
  Procrustes solution, ``argmax_{R in SO(3)} trace(R' N)`` = ``project_to_so3(N)``).
* :func:`procrustes_orthogonal`: the orthogonal (reflection allowed) Procrustes solution.
* :func:`align_similarity`: per-frame similarity alignment of shapes (the e3d metric).
* :func:`rotation_angle`: geodesic distance between rotations.
* :func:`average_rotations`: per-frame L1 single rotation averaging (paper Alg. 1).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["align_similarity", "average_rotations", "centre_points", "procrustes_orthogonal", "procrustes_so3",
           "project_to_so3", "rotation_angle"]


def project_to_so3(A):
    """Nearest rotation(s) to ``A`` (..., 3, 3): ``U diag(1, 1, det(UV')) V'``.

    For ``A = N`` this is also ``argmax_{R in SO(3)} trace(R' N)`` (SO(3) Procrustes).
    """
    A = np.asarray(A, float)
    U, _, Vt = np.linalg.svd(A)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    return U @ Vt


#: ``argmax_{R in SO(3)} trace(R' N)`` for N (..., 3, 3): the same map as the projection.
procrustes_so3 = project_to_so3


def procrustes_orthogonal(N):
    """``argmax_{Q orthogonal} trace(Q' N)`` = ``U V'`` (reflection allowed), N (..., n, n)."""
    U, _, Vt = np.linalg.svd(np.asarray(N, float))
    return U @ Vt


def rotation_angle(R1, R2):
    """Geodesic angle (radians) between rotations, broadcasting over leading axes."""
    c = (np.einsum("...ij,...ij->...", R1, R2) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def centre_points(X):
    """Subtract each frame's centroid: (..., 3, P) -> (..., 3, P)."""
    return X - X.mean(axis=-1, keepdims=True)


def align_similarity(X_est, X_gt):
    """Per-frame similarity Procrustes of ``X_est`` onto ``X_gt`` (reflection allowed).

    Parameters
    ----------
    X_est, X_gt : (F, 3, P) ndarray
        Both are centred per frame first.

    Returns
    -------
    aligned : (F, 3, P) ndarray
        ``s_f Q_f X_est_f`` (centred) closest to the centred ``X_gt_f``.
    """
    A = centre_points(np.asarray(X_est, float))
    B = centre_points(np.asarray(X_gt, float))
    U, sig, Vt = np.linalg.svd(B @ A.transpose(0, 2, 1))
    Q = U @ Vt                                      # orthogonal, reflection allowed
    norm2 = np.einsum("fij,fij->f", A, A)
    scale = np.where(norm2 > 0, sig.sum(axis=1) / np.where(norm2 > 0, norm2, 1.0), 0.0)
    return scale[:, None, None] * (Q @ A)


def _median_start(samples, mask):
    """Element-wise median of the kept samples, projected onto SO(3) (Lee & Civera).

    The median of the n_f kept values per entry: the middle one of the sorted values, or
    the mean of the two middle ones (``numpy.nanmedian``'s value, without its per-slice
    overhead); a frame with no kept sample gets the identity."""
    S = np.sort(np.where(mask[..., None, None], samples, np.inf), axis=0)
    n = mask.sum(axis=0)
    lo = np.maximum(n - 1, 0) // 2
    hi = np.where(n > 0, n // 2, 0)
    a = np.take_along_axis(S, lo[None, :, None, None], axis=0)[0]
    b = np.take_along_axis(S, hi[None, :, None, None], axis=0)[0]
    med = np.where((n > 0)[:, None, None], (a + b) / 2.0, np.eye(3))
    return project_to_so3(med)


def _log_so3(R):
    """Rotation vectors of rotations (..., 3, 3): ``theta u`` with ``theta =
    atan2(|s|, (tr R - 1) / 2)``, ``s = sin(theta) u`` the skew part (accurate at small
    angles); angles within 0.1 of pi (where the skew part loses the axis) by scipy."""
    s = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                        R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    ns = np.linalg.norm(s, axis=-1)
    theta = np.arctan2(ns, 0.5 * (np.einsum("...ii->...", R) - 1.0))
    small = ns < 1e-8
    factor = np.where(small, 1.0 + theta ** 2 / 6.0, theta / np.where(small, 1.0, ns))
    v = s * factor[..., None]
    far = theta > np.pi - 0.1
    if far.any():
        v[far] = Rotation.from_matrix(R[far]).as_rotvec()
    return v


def average_rotations(samples, mask=None, weights=None, max_iter=50, eps=1e-3,
                      return_info=False):
    """L1 single rotation averaging per frame (Alg. 1), vectorised over frames.

    Start: element-wise median of the samples projected onto SO(3); then Weiszfeld steps
    in the tangent space, ``v_i = log(R_i R')``, ``dv = sum w_i v_i/|v_i| / sum w_i/|v_i|``,
    ``R <- exp(dv) R``, at most ``max_iter`` iterations, a frame stops when ``|dv| < eps``.

    Parameters
    ----------
    samples : (m, F, 3, 3) ndarray
    mask : (m, F) bool, optional
        Samples to use. A frame with no sample gets the identity (and ``info["empty"]``).
    weights : (m, F) ndarray, optional
        Non-negative sample weights (weighted L1 mean); default 1.

    Returns
    -------
    R : (F, 3, 3) ndarray
    info : dict (iterations, converged per frame, empty frames) if ``return_info``
    """
    samples = np.asarray(samples, float)
    m, F = samples.shape[:2]
    mask = np.ones((m, F), bool) if mask is None else np.asarray(mask, bool)
    w = np.ones((m, F)) if weights is None else np.asarray(weights, float)
    w = np.where(mask, w, 0.0)
    empty = ~(w > 0).any(axis=0)
    R = _median_start(samples, w > 0)
    active = ~empty
    flat = samples.transpose(1, 0, 2, 3).reshape(F * m, 3, 3)     # frame-major
    wt = w.T                                                       # (F, m)
    iters = np.zeros(F, int)
    for it in range(max_iter):
        if not active.any():
            break
        idx = np.flatnonzero(active)
        Ra = R[idx]
        rel = flat.reshape(F, m, 3, 3)[idx] @ Ra[:, None].transpose(0, 1, 3, 2)
        v = _log_so3(rel)
        nv = np.linalg.norm(v, axis=2)
        inv = wt[idx] / np.maximum(nv, 1e-12)
        den = inv.sum(axis=1)
        dv = np.einsum("fm,fmi->fi", inv, v) / np.where(den > 0, den, 1.0)[:, None]
        R[idx] = Rotation.from_rotvec(dv).as_matrix() @ Ra
        iters[idx] += 1
        step = np.linalg.norm(dv, axis=1)
        active[idx[step < eps]] = False
    R = project_to_so3(R)
    if return_info:
        return R, dict(iterations=iters, converged=~active, empty=empty)
    return R
