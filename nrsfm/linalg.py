"""Weighted singular value thresholding, the kernel of the shape stage's ADMM and of the
completion's soft-impute."""

from __future__ import annotations

import numpy as np

__all__ = ["weighted_svt"]


def weighted_svt(M, thresholds):
    """Weighted singular value thresholding ``U diag(max(s - t, 0)) V'`` of M (m, n).

    For non-decreasing thresholds t this is the exact proximal operator of
    ``sum_i t_i sigma_i`` (Gu et al., CVPR 2014; Oh et al.'s PSVT when ``t_1 = 0``),
    computed from the eigen-decomposition of the Gram matrix of M's shorter side.

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
    s_new = np.maximum(s - thresholds[: s.size], 0.0)
    keep = s_new > 0
    coef = s_new[keep] / s[keep]
    Vk = V[:, keep]
    Y = (M @ Vk * coef) @ Vk.T if tall else (Vk * coef) @ (Vk.T @ M)
    return Y, s_new
