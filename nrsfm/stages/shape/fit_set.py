"""The exact-fit set of the shape stage and the operations on it that the ``constrained``
solver iterates: with orthonormal camera rows R_f (2 x 3) and third row n_f, the shapes with
``R_f X_f = W_f`` are ``X_f = R_f' W_f + n_f z_f'`` (:func:`exact_fit_shapes`); the
projection onto ``||W - R X||_F <= eps`` (:func:`project_to_fit`); weighted singular value
thresholding (:func:`weighted_svt`).
"""

from __future__ import annotations

import numpy as np

from .common import check_shape_inputs

__all__ = ["apply_frames", "exact_fit_shapes", "project_to_fit", "weighted_svt"]


def apply_frames(M, X):
    """Per-frame product ``M_f X_f`` for M (F, a, b), X (F, b, P) as b broadcast
    multiply-adds (numpy's batched matmul with tiny inner sizes is slow for large P)."""
    out = M[:, :, 0, None] * X[:, None, 0, :]
    for j in range(1, M.shape[2]):
        out += M[:, :, j, None] * X[:, None, j, :]
    return out


def exact_fit_shapes(W, R, Z):
    """The exact-fit shapes ``X_f = R_f' W_f + n_f z_f'`` (n_f = r1 x r2).

    Parameters
    ----------
    W : (2F, P) ndarray
    R : (F, 2, 3) or (F, 3, 3) ndarray, orthonormal rows
    Z : (F, P) ndarray
        Depths along each frame's viewing direction.

    Returns
    -------
    X : (F, 3, P) ndarray, with ``R_f X_f = W_f`` for every f.
    """
    W, Rf, F, P = check_shape_inputs(W, R)
    Z = np.asarray(Z, dtype=float)
    if Z.shape != (F, P):
        raise ValueError(f"Z must be (F, P) = ({F}, {P}); got shape {Z.shape}")
    n = np.cross(Rf[:, 0], Rf[:, 1])
    return apply_frames(Rf.transpose(0, 2, 1), W.reshape(F, 2, P)) + n[:, :, None] * Z[:, None, :]


def project_to_fit(X, W, R, eps):
    """Euclidean projection of X (F, 3, P) onto ``{X : ||W - R X||_F <= eps}``.

    The in-plane part ``R_f X_f`` is pulled towards W_f (radially, all frames together) until
    the residual is eps; the depth part is unchanged (exact: the rows of R_f are
    orthonormal, so the map X -> R X is a partial isometry).
    """
    W, Rf, F, P = check_shape_inputs(W, R)
    X = np.asarray(X, dtype=float)
    if X.shape != (F, 3, P):
        raise ValueError(f"X must be (F, 3, P) = ({F}, 3, {P}); got shape {X.shape}")
    if not (np.isfinite(eps) and eps >= 0):
        raise ValueError(f"eps must be finite and non-negative; got {eps!r}")
    r = apply_frames(Rf, X) - W.reshape(F, 2, P)
    nr = float(np.linalg.norm(r))
    keep = 1.0 if nr <= eps else eps / nr
    return X - (1.0 - keep) * apply_frames(Rf.transpose(0, 2, 1), r)


def weighted_svt(M, thresholds):
    """Weighted singular value thresholding ``U diag(max(s - t, 0)) V'`` of M (m, n).

    For non-decreasing thresholds t this is the exact proximal operator of
    ``sum_i t_i sigma_i`` (Gu et al., CVPR 2014; Oh et al.'s PSVT when ``t_1 = 0``).
    Computed from the eigen-decomposition of the Gram matrix of M's shorter side (one
    ``min(m, n)``-sized eigenproblem); the singular values lost to rounding there are
    thresholded away by every positive t.

    Parameters
    ----------
    M : (m, n) ndarray
    thresholds : (>= min(m, n),) ndarray, non-negative, non-decreasing

    Returns
    -------
    Y : (m, n) ndarray
    s : (min(m, n),) ndarray
        Thresholded singular values (decreasing).
    """
    tall = M.shape[0] >= M.shape[1]
    G = M.T @ M if tall else M @ M.T
    ev, V = np.linalg.eigh(G)
    s = np.sqrt(np.maximum(ev[::-1], 0.0))
    V = V[:, ::-1]
    s_new = np.maximum(s - thresholds[:s.size], 0.0)
    keep = s_new > 0
    coef = s_new[keep] / s[keep]
    Vk = V[:, keep]
    Y = (M @ Vk * coef) @ Vk.T if tall else (Vk * coef) @ (Vk.T @ M)
    return Y, s_new
