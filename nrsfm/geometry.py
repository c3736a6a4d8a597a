"""Rotations and alignments used by every stage: one home for each (projection onto SO(3),
Procrustes, the e3d alignment, geodesic angles, L1 rotation averaging of Alg. 1)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


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


#: matrices per pass of :func:`project_to_so3_batch` (its (9, n) arrays stay in cache)
_CHUNK = 1 << 13


def project_to_so3_batch(A, min_gap=1e-4, max_iter=30):
    """Nearest rotations to the (n, 3, 3) matrices ``A``: :func:`project_to_so3`, faster
    for large n (the fill's Kabsch steps), in closed form.

    With the signed singular values ``e = (s_1, s_2, sign(det A) s_3)`` and their symmetric
    functions ``I1 = sum e``, ``I2 = e_1 e_2 + e_1 e_3 + e_2 e_3``, ``I3 = det A``, the
    rotation ``U diag(1, 1, sign det A) V'`` is

        R = ((I1^2 - I2) A + I1 cof(A) - A A' A) / (I1 I2 - I3)

    (``cof`` the cofactor matrix: the three coefficients make ``e_i`` map to 1 for each i).
    ``I1`` is the largest root of ``x^4 - 2 t x^2 - 8 I3 x + t^2 - 4 e2(A'A)``
    (``t = ||A||_F^2``, ``e2`` the sum of the principal 2 x 2 minors), found by Newton's
    method from the upper bound ``sqrt(t + 2 sqrt(3 e2))``; then ``I2 = (I1^2 - t) / 2``.
    The denominator is ``(e_1 + e_2)(e_1 + e_3)(e_2 + e_3)``, zero where the rotation is not
    unique; where it is below ``min_gap I1^3`` (the formula loses digits faster than the SVD)
    or Newton has not converged in ``max_iter``, :func:`project_to_so3`'s SVD decides. One
    step of Newton's polar iteration, ``R <- (R + R^-T) / 2``, makes R orthogonal to
    rounding. Each matrix's answer is the same whatever else is passed.

    Parameters
    ----------
    A : (n, 3, 3) array_like
        Finite matrices, any scale.
    min_gap : float
        Relative denominator below which the SVD decides.
    max_iter : int
        Newton's cap for ``I1``.

    Returns
    -------
    R : (n, 3, 3) ndarray
        Rotations, ``argmax_{R in SO(3)} trace(R' A_i)``.
    """
    A = np.asarray(A, float)
    flat = A.reshape(-1, 9)
    out = np.empty_like(flat)
    for s in range(0, flat.shape[0], _CHUNK):
        part = flat[s : s + _CHUNK]
        R, ok = _so3_closed_form(np.ascontiguousarray(part.T), min_gap, max_iter)
        out[s : s + _CHUNK] = R.T
        if not ok.all():
            bad = s + np.flatnonzero(~ok)
            out[bad] = project_to_so3(flat[bad].reshape(-1, 3, 3)).reshape(-1, 9)
    return out.reshape(A.shape)


def _cofactor_rows(m):
    """(3, 3, n) cofactor matrices of the (3, 3, n) matrices m (row i: the cross product of
    the other two rows, in cyclic order)."""
    return np.stack(
        [np.cross(m[1], m[2], axis=0), np.cross(m[2], m[0], axis=0), np.cross(m[0], m[1], axis=0)]
    )


def _so3_closed_form(M, min_gap, max_iter):
    """(9, n) rotations of the (9, n) matrices M (row-major entries) by
    :func:`project_to_so3_batch`'s formula, and where it holds (n,) bool."""
    big = np.abs(M).max(axis=0)
    M = M / np.where(big > 0, big, 1.0)  # entries in [-1, 1]
    m = M.reshape(3, 3, -1)
    C = np.einsum("kin,kjn->ijn", m, m)  # A' A
    cof = _cofactor_rows(m)
    det = np.einsum("in,in->n", m[0], cof[0])
    t = C[0, 0] + C[1, 1] + C[2, 2]
    e2 = C[0, 0] * C[1, 1] - C[0, 1] ** 2 + C[0, 0] * C[2, 2] - C[0, 2] ** 2
    e2 = e2 + C[1, 1] * C[2, 2] - C[1, 2] ** 2  # the principal 2 x 2 minors of A'A
    c0 = t * t - 4.0 * e2
    lam = np.sqrt(t + 2.0 * np.sqrt(np.maximum(3.0 * e2, 0.0)))  # >= I1 (Cauchy-Schwarz)
    done = np.zeros(lam.size, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(max_iter):
            l2 = lam * lam
            step = ((l2 - 2.0 * t) * l2 - 8.0 * det * lam + c0) / (4.0 * lam * (l2 - t) - 8.0 * det)
            lam -= np.where(done, 0.0, step)  # each stops on its own:
            done |= np.abs(step) <= 1e-13 * lam  # quadratic, then exact
            if done.all():
                break
        I2 = 0.5 * (lam * lam - t)
        den = lam * I2 - det
        AC = np.einsum("ikn,kjn->ijn", m, C)
        R = ((lam * lam - I2) * m + lam * cof - AC) / den
        ok = done & (den > min_gap * lam**3) & (big > 0)
        cof = _cofactor_rows(R)
        R += cof / np.einsum("in,in->n", R[0], cof[0])  # one polar Newton step:
        R *= 0.5  # orthogonal to rounding
    return R.reshape(9, -1), ok


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
    Q = U @ Vt  # orthogonal, reflection allowed
    norm2 = np.einsum("fij,fij->f", A, A)
    scale = np.where(norm2 > 0, sig.sum(axis=1) / np.where(norm2 > 0, norm2, 1.0), 0.0)
    return scale[:, None, None] * (Q @ A)


def _median_start(samples, mask):
    """Element-wise median of the kept samples (``numpy.nanmedian``'s value, faster),
    projected onto SO(3) (Lee & Civera); the identity for a frame with no kept sample."""
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
    s = 0.5 * np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
        axis=-1,
    )
    ns = np.linalg.norm(s, axis=-1)
    theta = np.arctan2(ns, 0.5 * (np.einsum("...ii->...", R) - 1.0))
    small = ns < 1e-8
    factor = np.where(small, 1.0 + theta**2 / 6.0, theta / np.where(small, 1.0, ns))
    v = s * factor[..., None]
    far = theta > np.pi - 0.1
    if far.any():
        v[far] = Rotation.from_matrix(R[far]).as_rotvec()
    return v


def average_rotations(samples, mask=None, weights=None, max_iter=50, eps=1e-3, return_info=False):
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
    flat = samples.transpose(1, 0, 2, 3).reshape(F * m, 3, 3)  # frame-major
    wt = w.T  # (F, m)
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
