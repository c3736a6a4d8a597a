"""Temporal lags of the completed matrix, shared by both completions.

The time-lagged matrix of W (2F, P) for lags ``d_1, ..., d_n`` (frames) is

    H(W) = [S_{d_1} W, ..., S_{d_n} W]      (2F, n P),   S_d: frames shifted by d,

edges repeated. With the lags ``(-1, 0, 1)`` a frame's row holds its neighbours' points
beside its own, so a missing point is seen through its own trajectory at the adjacent
frames as well as through the other points (the rows of H stay low-rank when the
trajectories are smooth); ``(0,)`` is W itself (frames in no particular order).
:func:`choose_lags` picks one of the two from the observation mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Copies", "LAG_RATIO", "NEIGHBOUR_LAGS", "NO_LAGS", "check_lags", "choose_lags",
           "lag_copies"]

#: A frame beside its two neighbours: what :func:`choose_lags` returns when a frame's own
#: observations are too few for the rank (MoCap-sized W), and the default of
#: :func:`~nrsfm.stages.completion.soft_impute.complete_measurements`.
NEIGHBOUR_LAGS = (-1, 0, 1)
#: No lag, W itself: what :func:`choose_lags` returns otherwise (dense tracks), and the
#: default of :func:`~nrsfm.stages.completion.factorisation.complete_low_rank`.
NO_LAGS = (0,)
#: :func:`choose_lags`: lags when a frame observes fewer than this many points per unknown
#: of its rows (r + 1).
LAG_RATIO = 2


@dataclass(frozen=True)
class Copies:
    """The entries of the lagged matrix H (2F, n P) of W (2F, P) as copies of W's entries,
    for lags ``d_1, ..., d_n``: index arrays, so that a completion lags a matrix, and
    averages the copies of each entry back, with one numpy expression each.

    With the lags ``(0,)`` H is W: the index arrays are then None and :meth:`lag` and
    :meth:`mean` are copies.

    Attributes
    ----------
    lags : tuple of int
    gather : (2F, n P) int ndarray
        ``H = W.ravel()[gather]``: the flat index in W of each entry of H.
    gather_mask : (F, n P) int ndarray
        The same for the (F, P) observation mask: ``observed.ravel()[gather_mask]``.
    order, target : (2F n P,) int ndarray
        The entries of H lag by lag, and the flat index in W of each of them: the mean of
        the copies of each entry of W, from a matrix L shaped like H, is
        ``np.bincount(target, L.ravel()[order], W.size) / counts`` (W's shape), summed
        lag by lag.
    counts : (2F P,) ndarray
        How many copies each entry of W has in H (an edge frame is repeated).
    """

    lags: tuple
    gather: np.ndarray
    gather_mask: np.ndarray
    order: np.ndarray
    target: np.ndarray
    counts: np.ndarray

    def lag(self, Z, mask=False):
        """H of Z (2F, P), or with ``mask`` of an (F, P) mask: a new array."""
        if self.gather is None:
            return np.array(Z)
        return Z.ravel()[self.gather_mask if mask else self.gather]

    def mean(self, L, shape):
        """The mean of the copies of each entry of a matrix ``shape`` (2F, P) from L
        shaped like H (summed lag by lag)."""
        if self.gather is None:
            return np.array(L).reshape(shape)
        size = int(np.prod(shape))
        return (np.bincount(self.target, L.ravel()[self.order], size)
                / self.counts).reshape(shape)


def check_lags(lags):
    """``lags`` as a tuple of int; ValueError (naming them) unless distinct and with 0."""
    lags = tuple(int(d) for d in lags)
    if 0 not in lags or len(set(lags)) != len(lags):
        raise ValueError(f"lags must be distinct integers including 0; got {lags}")
    return lags


def choose_lags(observed, rank):
    """Temporal lags for completing W at rank r, from its (F, P) observation mask alone.

    Each frame's two rows and offset (r + 1 unknowns per row) are fitted to the points the
    frame observes. When the frame observing the fewest points has fewer than
    ``LAG_RATIO * (r + 1)`` of them, a frame's own observations barely determine its rows
    (MoCap: 41 markers, r = 3K = 30-36, about 29 observed at 30 % missing) and the lags
    :data:`NEIGHBOUR_LAGS` add its neighbours' observations; otherwise (dense tracks:
    thousands of points per frame at r = 3-6) :data:`NO_LAGS`. Measurements:
    ``docs/missing_data_scale.md``.

    Parameters
    ----------
    observed : (F, P) bool ndarray
    rank : int

    Returns
    -------
    tuple of int
    """
    fewest = int(np.asarray(observed, bool).sum(axis=1).min())
    return NEIGHBOUR_LAGS if fewest < LAG_RATIO * (int(rank) + 1) else NO_LAGS


def lag_copies(F, P, lags):
    """The :class:`Copies` of the lagged matrix of a (2F, P) W for ``lags`` (checked by
    :func:`check_lags`)."""
    lags = check_lags(lags)
    if lags == NO_LAGS:
        return Copies(lags=lags, gather=None, gather_mask=None, order=None, target=None,
                      counts=None)
    frames = np.clip(np.arange(F)[:, None] + np.asarray(lags)[None, :], 0, F - 1)  # (F, n)
    points = np.arange(P)
    rows = 2 * frames[:, None, :, None] + np.arange(2)[None, :, None, None]   # (F, 2, n, 1)
    gather = (rows * P + points).reshape(2 * F, -1)
    n = len(lags)
    order = np.arange(gather.size).reshape(2 * F, n, P).transpose(1, 0, 2).ravel()
    target = gather.ravel()[order]
    return Copies(lags=lags, gather=gather,
                  gather_mask=(frames[:, :, None] * P + points).reshape(F, -1),
                  order=order, target=target,
                  counts=np.bincount(target, minlength=2 * F * P).astype(float))
