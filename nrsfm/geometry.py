"""Rotations and alignments used by every stage: one home for each.

* :func:`project_to_so3`: the nearest rotation to a 3 x 3 matrix (also the SO(3)
  Procrustes solution, ``argmax_{R in SO(3)} trace(R' N)`` = ``project_to_so3(N)``).
* :func:`project_to_so3_batch`: the same map for many matrices at once (the fill's Kabsch
  steps), by Newton's polar iteration.
* :func:`procrustes_orthogonal`: the orthogonal (reflection allowed) Procrustes solution.
* :func:`align_similarity`: per-frame similarity alignment of shapes (the e3d metric).
* :func:`rotation_angle`: geodesic distance between rotations.
* :func:`average_rotations`: per-frame L1 single rotation averaging (paper Alg. 1).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["align_similarity", "average_rotations", "centre_points", "procrustes_orthogonal", "procrustes_so3",
           "project_to_so3", "project_to_so3_batch", "rotation_angle"]


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


def _cofactors(X):
    """(9, n) cofactor matrices (row-major entries) of the (9, n) 3 x 3 matrices X."""
    a, b, c, d, e, f, g, h, k = X
    return np.stack([e * k - f * h, f * g - d * k, d * h - e * g,
                     c * h - b * k, a * k - c * g, b * g - a * h,
                     b * f - c * e, c * d - a * f, a * e - b * d])


def _smallest_eigenvector(H):
    """Unit eigenvectors (3, n) of the least eigenvalues of the symmetric 3 x 3 matrices
    H (9, n), and the gaps ``(lambda_2 - lambda_3) / |lambda|_max`` (closed-form
    eigenvalues, Smith 1961; the vector as the largest cross product of two rows of
    ``H - lambda_3 I``)."""
    h00, h01, h02, _, h11, h12, _, _, h22 = H
    q = (h00 + h11 + h22) / 3.0
    p = np.sqrt(((h00 - q) ** 2 + (h11 - q) ** 2 + (h22 - q) ** 2
                 + 2.0 * (h01 * h01 + h02 * h02 + h12 * h12)) / 6.0)
    p = np.where(p > 0, p, 1.0)
    a, b, c = (h00 - q) / p, (h11 - q) / p, (h22 - q) / p
    d, e, f = h01 / p, h02 / p, h12 / p
    half_det = 0.5 * (a * (b * c - f * f) - d * (d * c - f * e) + e * (d * f - b * e))
    phi = np.arccos(np.clip(half_det, -1.0, 1.0)) / 3.0
    lam1 = q + 2.0 * p * np.cos(phi)
    lam3 = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    lam2 = 3.0 * q - lam1 - lam3
    rows = np.stack([np.stack([h00 - lam3, h01, h02]), np.stack([h01, h11 - lam3, h12]),
                     np.stack([h02, h12, h22 - lam3])])                  # (3, 3, n)
    cross = np.stack([np.cross(rows[i], rows[j], axis=0) for i, j in ((0, 1), (0, 2), (1, 2))])
    size = np.einsum("kin,kin->kn", cross, cross)
    v = np.take_along_axis(cross, size.argmax(axis=0)[None, None], axis=0)[0]
    v /= np.sqrt(np.maximum(size.max(axis=0), 1e-300))
    gap = (lam2 - lam3) / np.maximum(np.maximum(np.abs(lam1), np.abs(lam3)), 1e-300)
    return v, gap


#: matrices per pass of :func:`project_to_so3_batch` (its (9, n) arrays stay in cache)
_CHUNK = 1 << 14


def project_to_so3_batch(A, tol=1e-13, max_iter=20, min_det=1e-6, min_gap=1e-4):
    """Nearest rotations to the (n, 3, 3) matrices ``A``: :func:`project_to_so3`, faster
    for large n.

    Where ``|det A| > min_det (||A||_F / sqrt 3)^3`` the orthogonal polar factor Q of A is
    found by Newton's iteration ``X <- (g X + X^-T / g) / 2`` with the Frobenius-norm
    scaling g (Higham, "Functions of Matrices", 2008, section 8.6), on the entries as
    (9, n) arrays, until no entry moves by more than ``tol``. Q is the answer where
    ``det A > 0``; where ``det A < 0`` the answer is ``U diag(1, 1, -1) V' = Q (I - 2 v v')``
    with v the right singular vector of A's least singular value (the least eigenvector of
    ``Q' A = V S V'``), when that value is apart from the next by ``min_gap``. The others
    (nearly singular A, close singular values, no convergence in ``max_iter``) by
    :func:`project_to_so3`'s SVD. Agrees with it to about 1e-11 (the reflected ones;
    the others to about 1e-14). Runs over chunks of ``_CHUNK`` matrices (cache-sized).

    Parameters
    ----------
    A : (n, 3, 3) array_like
        Finite matrices, any scale.
    tol, max_iter : float, int
        Newton's stopping rule and cap.
    min_det, min_gap : float
        Below these (relative) the SVD decides.

    Returns
    -------
    R : (n, 3, 3) ndarray
        Rotations, ``argmax_{R in SO(3)} trace(R' A_i)``.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.random.default_rng(0).standard_normal((1000, 3, 3))
    >>> bool(np.allclose(project_to_so3_batch(A), project_to_so3(A), atol=1e-10))
    True
    """
    A = np.asarray(A, float)
    flat = A.reshape(-1, 9)
    out = np.empty_like(flat)
    for s in range(0, flat.shape[0], _CHUNK):
        out[s:s + _CHUNK] = _polar_chunk(flat[s:s + _CHUNK], tol, max_iter, min_det, min_gap)
    return out.reshape(A.shape)


def _polar_chunk(flat, tol, max_iter, min_det, min_gap):
    """:func:`project_to_so3_batch` of the (n, 9) matrices ``flat``, as (n, 9)."""
    out = np.empty_like(flat)
    X = np.ascontiguousarray(flat.T)
    big = np.abs(X).max(axis=0)
    X = X / np.where(big > 0, big, 1.0)                            # no overflow below
    norm = np.sqrt((X * X).sum(axis=0))
    C = _cofactors(X)
    det = X[0] * C[0] + X[1] * C[1] + X[2] * C[2]
    todo = np.flatnonzero(np.abs(det) > min_det * (norm / np.sqrt(3.0)) ** 3)
    A0 = X[:, todo]                             # the iteration below never writes into it
    X, moved = A0, np.full(todo.size, np.inf)   # none converged before an iteration
    for _ in range(max_iter if todo.size else 0):
        C = _cofactors(X)
        C /= X[0] * C[0] + X[1] * C[1] + X[2] * C[2]                # X^-T
        g = np.sqrt(np.sqrt(np.einsum("in,in->n", C, C) / np.einsum("in,in->n", X, X)))
        X = X * g
        C /= g
        X += C
        X *= 0.5
        moved = np.abs(X - C).max(axis=0)       # half the gap of g X and X^-T / g
        if moved.max() <= tol:
            break
    ok = moved <= tol
    flip = np.flatnonzero(ok & (det[todo] < 0))
    if flip.size:
        Q, N = X[:, flip].reshape(3, 3, -1), A0[:, flip].reshape(3, 3, -1)
        H = np.einsum("kin,kjn->ijn", Q, N)                     # Q' A, symmetric
        v, gap = _smallest_eigenvector((0.5 * (H + H.transpose(1, 0, 2))).reshape(9, -1))
        Qv = np.einsum("ijn,jn->in", Q, v)
        X[:, flip] = (Q - 2.0 * Qv[:, None] * v[None]).reshape(9, -1)
        ok[flip[gap < min_gap]] = False
    svd = np.ones(flat.shape[0], bool)
    svd[todo[ok]] = False
    out[~svd] = X[:, ok].T
    if svd.any():
        out[svd] = project_to_so3(flat[svd].reshape(-1, 3, 3)).reshape(-1, 9)
    return out


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
