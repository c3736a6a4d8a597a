"""Noise level of W from W alone: the one estimate the shape stage and the diagnostics use.

``sigma = ||W - W_3K||_F / sqrt((2F - 3K)(P - 3K))``: the residual of the rank-3K fit
spread over the entries it leaves free. For W = low rank + i.i.d. noise of std s this
estimates s (slightly low: the rank-3K fit absorbs some noise, and row centring removes one
more column's worth, ``(2F - 3K)(P - 1 - 3K)`` degrees of freedom, a relative difference of
about ``1 / (2 (P - 3K))``). The bilinear shape solver's balance ``mu`` was measured with this
count, so it is the one kept. Model error (a shape not exactly of rank K) counts as noise.
"""

from __future__ import annotations

import math

import numpy as np

from .validation import check_measurements

__all__ = ["noise_from_singular_values", "noise_level"]


def noise_from_singular_values(singular_values, shape, K):
    """Noise level of a (2F, P) matrix from its singular values (see the module docstring).

    Parameters
    ----------
    singular_values : (min(2F, P),) array_like
        All singular values of W, decreasing.
    shape : (2F, P) tuple
    K : int

    Returns
    -------
    float
        In W's units; zero for an exactly rank-3K W.
    """
    s = np.asarray(singular_values, float)
    rows, cols = shape
    tail = float(np.sqrt(np.sum(s[3 * K:] ** 2)))
    dof = max((rows - 3 * K) * (cols - 3 * K), 1)
    return tail / math.sqrt(dof)


def noise_level(W, K):
    """Noise level of W (2F, P) beyond its rank-3K approximation, in W's units."""
    W = check_measurements(W)
    return noise_from_singular_values(np.linalg.svd(W, compute_uv=False), W.shape, K)
