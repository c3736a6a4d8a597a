"""Noise level of W from W alone: the one estimate the shape stage and the diagnostics use.

``sigma = ||W - W_3K||_F / sqrt((2F - 3K)(P - 3K))``: the residual of the rank-3K fit spread
over the entries it leaves free; for low rank + i.i.d. noise of std s it estimates s
(slightly low: row centring frees one column less, but the bilinear shape solver's ``mu`` was
tuned with this count). Model error (a shape not exactly of rank K) counts as noise.
"""

from __future__ import annotations

import math

import numpy as np

from .validation import check_measurements


def noise_from_singular_values(singular_values, shape, K):
    """Noise level of a (2F, P) matrix of shape ``shape`` from all its singular values
    (decreasing), in its units; zero for an exactly rank-3K matrix."""
    s = np.asarray(singular_values, float)
    rows, cols = shape
    tail = float(np.sqrt(np.sum(s[3 * K :] ** 2)))
    dof = max((rows - 3 * K) * (cols - 3 * K), 1)
    return tail / math.sqrt(dof)


def noise_level(W, K):
    """Noise level of W (2F, P) beyond its rank-3K approximation, in W's units."""
    W = check_measurements(W)
    return noise_from_singular_values(np.linalg.svd(W, compute_uv=False), W.shape, K)
