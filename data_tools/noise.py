"""Noise and missing-data generators for measurement matrices."""

from __future__ import annotations

import numpy as np


def add_noise(W, sigma, seed=0, relative=True):
    """Add Gaussian noise to W (2F, P).

    Parameters
    ----------
    sigma : float
        Standard deviation; with ``relative`` a fraction of W's mean row std.

    Returns
    -------
    (2F, P) ndarray, row-centred again.
    """
    W = np.asarray(W, float)
    if sigma < 0:
        raise ValueError(f"sigma must be >= 0; got {sigma}")
    std = sigma * (np.mean(np.std(W, axis=1)) if relative else 1.0)
    out = W + std * np.random.default_rng(seed).standard_normal(W.shape)
    return out - out.mean(axis=1, keepdims=True)


def drop_tracks(W, fraction, seed=0):
    """Mark a random fraction of the (frame, point) observations missing.

    Returns
    -------
    W_missing : (2F, P) ndarray
        Copy of W with NaN where an observation is missing (both rows of the frame).
    mask : (F, P) bool ndarray
        True where observed.
    """
    W = np.asarray(W, float)
    if not 0 <= fraction < 1:
        raise ValueError(f"fraction must be in [0, 1); got {fraction}")
    F, P = W.shape[0] // 2, W.shape[1]
    mask = np.random.default_rng(seed).random((F, P)) >= fraction
    out = W.copy().reshape(F, 2, P)
    out[~np.broadcast_to(mask[:, None, :], out.shape)] = np.nan
    return out.reshape(2 * F, P), mask
