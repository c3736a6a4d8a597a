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


def drop_tracks(W, fraction, seed=0, pattern="uniform"):
    """Mark (frame, point) observations missing; both coordinates go together.

    Parameters
    ----------
    W : (2F, P) array_like
    fraction : float
        In [0, 1). ``uniform``: each point-frame is missing with this probability.
        ``tracking``: each track (point) is lost with this probability, from a frame drawn
        uniformly in ``[2, F)`` to the end, so every point keeps at least two frames
        (about ``fraction / 2`` of the observations go).
    seed : int
    pattern : {"uniform", "tracking"}
        The two patterns used in the NRSfM literature (uniform as in Lee et al., CVPR
        2013; tracking as a tracker losing a point).

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
    if W.ndim != 2 or W.shape[0] % 2:
        raise ValueError(f"W must have shape (2F, P); got {W.shape}")
    F, P = W.shape[0] // 2, W.shape[1]
    rng = np.random.default_rng(seed)
    if pattern == "uniform":
        mask = rng.random((F, P)) >= fraction
    elif pattern == "tracking":
        if F < 3:
            raise ValueError(f"the tracking pattern needs at least 3 frames; got F={F}")
        lost = rng.random(P) < fraction
        start = rng.integers(2, F, size=P)
        mask = ~(lost[None, :] & (np.arange(F)[:, None] >= start[None, :]))
    else:
        raise ValueError(f"pattern must be 'uniform' or 'tracking'; got {pattern!r}")
    out = W.copy().reshape(F, 2, P)
    out[~np.broadcast_to(mask[:, None, :], out.shape)] = np.nan
    return out.reshape(2 * F, P), mask
