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


#: The missing-data patterns of :func:`drop_tracks` (one choice list: the check, the
#: docstring and the benchmark read it).
PATTERNS = ("uniform", "tracking", "lost", "late", "block")


def _uniform(rng, F, P, fraction):
    """Each point-frame missing with probability ``fraction``."""
    return rng.random((F, P)) >= fraction


def _tracking(rng, F, P, fraction):
    """Each track lost with probability ``fraction`` from a frame in ``[2, F)`` on."""
    lost = rng.random(P) < fraction
    start = rng.integers(2, F, size=P)
    return ~(lost[None, :] & (np.arange(F)[:, None] >= start[None, :]))


def _chosen(rng, P, fraction):
    """``round(fraction * P)`` distinct tracks drawn at random, in drawing order."""
    return rng.choice(P, size=int(round(fraction * P)), replace=False)


def _lost(rng, F, P, fraction):
    """``round(fraction P)`` tracks lost from a frame in ``[ceil(F / 10), F)`` to the end."""
    tracks = _chosen(rng, P, fraction)
    start = rng.integers(-(-F // 10), F, size=tracks.size)
    mask = np.ones((F, P), bool)
    mask[:, tracks] = np.arange(F)[:, None] < start[None, :]
    return mask


def _late(rng, F, P, fraction):
    """``round(fraction P)`` tracks seen only from a frame in ``[1, F - ceil(F / 10)]`` on."""
    tracks = _chosen(rng, P, fraction)
    start = rng.integers(1, F - (-(-F // 10)) + 1, size=tracks.size)
    mask = np.ones((F, P), bool)
    mask[:, tracks] = np.arange(F)[:, None] >= start[None, :]
    return mask


def _block(rng, F, P, fraction):
    """``round(fraction P)`` tracks gone for a block of ``ceil(F / 10)`` to ``F // 2``
    frames, seen before and after it."""
    tracks = _chosen(rng, P, fraction)
    length = rng.integers(-(-F // 10), F // 2 + 1, size=tracks.size)
    start = rng.integers(1, F - length)  # frame 0 and F - 1 stay observed
    frames = np.arange(F)[:, None]
    mask = np.ones((F, P), bool)
    mask[:, tracks] = (frames < start[None, :]) | (frames >= (start + length)[None, :])
    return mask


_DRAW = dict(zip(PATTERNS, (_uniform, _tracking, _lost, _late, _block)))


def drop_tracks(W, fraction, seed=0, pattern="uniform"):
    """Mark (frame, point) observations missing; both coordinates go together.

    Parameters
    ----------
    W : (2F, P) array_like
    fraction : float
        In [0, 1): for ``uniform`` the probability of each point-frame being missing, for
        ``tracking`` the probability of each track being lost, for the other patterns the
        fraction of the tracks hit (exactly ``round(fraction * P)`` of them, drawn at
        random).
    seed : int
        Seed of the random draws: the same seed, W shape, fraction and pattern give the
        same mask.
    pattern : str, one of :data:`PATTERNS`
        ``uniform``: entries missing at random (Lee et al., CVPR 2013).
        ``tracking``: a tracker losing a point; each track lost with probability
        ``fraction`` from a frame drawn uniformly in ``[2, F)`` to the end (every point
        keeps two frames; about ``fraction / 2`` of the entries go).
        ``lost`` (lost to the end; the benchmark's pattern at fraction 0.3, seed 31): the
        chosen tracks lost from a frame drawn uniformly in ``[ceil(F / 10), F)`` to the
        end (seen in the first tenth; about ``0.45 fraction`` of the entries go).
        ``late`` (late start): the chosen tracks seen only from a frame drawn uniformly in
        ``[1, F - ceil(F / 10)]`` on (seen in the last tenth).
        ``block`` (occluded and back): each chosen track gone for one block of frames, its
        length drawn uniformly in ``[ceil(F / 10), F // 2]``, seen in frame 0 and F - 1.

    Returns
    -------
    W_missing : (2F, P) ndarray
        Copy of W with NaN where an observation is missing (both rows of the frame).
    mask : (F, P) bool ndarray
        True where observed.

    Raises
    ------
    ValueError
        ``fraction`` outside [0, 1), ``W`` not (2F, P), an unknown ``pattern``, or fewer
        than 3 frames for a pattern other than ``uniform``.
    """
    from nrsfm.validation import check_choice

    W = np.asarray(W, float)
    check_choice("pattern", pattern, PATTERNS)
    if not 0 <= fraction < 1:
        raise ValueError(f"fraction must be in [0, 1); got {fraction}")
    if W.ndim != 2 or W.shape[0] % 2:
        raise ValueError(f"W must have shape (2F, P); got {W.shape}")
    F, P = W.shape[0] // 2, W.shape[1]
    if pattern != "uniform" and F < 3:
        raise ValueError(f"the {pattern} pattern needs at least 3 frames; got F={F}")
    mask = _DRAW[pattern](np.random.default_rng(seed), F, P, fraction)
    out = W.copy().reshape(F, 2, P)
    out[~np.broadcast_to(mask[:, None, :], out.shape)] = np.nan
    return out.reshape(2 * F, P), mask
