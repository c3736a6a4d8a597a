"""The observed entries of W and their time lags, shared by both completions.

A missing observation is a (frame, point) pair: both coordinates go together, so the mask
is ``observed`` (F, P). A frame must observe at least 3 points (an orthographic camera and
its translation) and a point must be observed in at least 2 frames (its depth).

The time-lagged matrix of W (2F, P) for lags ``d_1, ..., d_n`` (frames) is

    H(W) = [S_{d_1} W, ..., S_{d_n} W]      (2F, n P),   S_d: frames shifted by d,

edges repeated. With the lags ``(-1, 0, 1)`` a missing point is seen through its own
trajectory at the adjacent frames as well as through the other points (the rows of H stay
low-rank when the trajectories are smooth); ``(0,)`` is W itself (frames in any order).
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

from ...validation import check_measurements

NEIGHBOUR_LAGS = (-1, 0, 1)
NO_LAGS = (0,)
LAG_RATIO = 2  # lags when a frame observes fewer than this many points per unknown


@dataclass(frozen=True)
class Copies:
    """The entries of the lagged matrix H (2F, n P) as copies of W's (2F, P) entries, as
    index arrays (all None for the lags ``(0,)``, where H is W): ``H = W.ravel()[gather]``,
    the same for the (F, P) mask with ``gather_mask``; ``order`` the entries of H lag by
    lag, ``target`` the flat index in W of each, ``counts`` the copies of each entry of W
    (an edge frame is repeated)."""

    lags: tuple
    gather: np.ndarray = None
    gather_mask: np.ndarray = None
    order: np.ndarray = None
    target: np.ndarray = None
    counts: np.ndarray = None

    def lag(self, Z, mask=False):
        """H of Z (2F, P), or of an (F, P) mask: a new array."""
        if self.gather is None:
            return np.array(Z)
        return Z.ravel()[self.gather_mask if mask else self.gather]

    def mean(self, L, shape):
        """The mean of the copies of each entry of a (2F, P) ``shape`` from L shaped like H."""
        if self.gather is None:
            return np.array(L).reshape(shape)
        size = int(np.prod(shape))
        return (np.bincount(self.target, L.ravel()[self.order], size) / self.counts).reshape(shape)


def check_lags(lags):
    """``lags`` as a tuple of int; ValueError (naming them) unless distinct and with 0."""
    try:
        out = tuple(operator.index(d) for d in lags)
    except TypeError:
        out = ()
    if 0 not in out or len(set(out)) != len(out):
        raise ValueError(f"lags must be distinct integers including 0; got {lags!r}")
    return out


def choose_lags(observed, rank):
    """Temporal lags for completing W at rank r, from its (F, P) observation mask alone.

    Each frame's two rows and offset (r + 1 unknowns) are fitted to the points the frame
    observes. When the frame observing the fewest points has fewer than ``LAG_RATIO * (r +
    1)`` of them (MoCap: 41 markers at r = 3K = 30-36), its own observations barely
    determine its rows and :data:`NEIGHBOUR_LAGS` add its neighbours'; otherwise (dense
    tracks) :data:`NO_LAGS`.
    """
    fewest = int(np.asarray(observed, bool).sum(axis=1).min())
    return NEIGHBOUR_LAGS if fewest < LAG_RATIO * (int(rank) + 1) else NO_LAGS


def lag_copies(F, P, lags):
    """The :class:`Copies` of the lagged matrix of a (2F, P) W for ``lags`` (checked)."""
    lags = check_lags(lags)
    if lags == NO_LAGS:
        return Copies(lags)
    frames = np.clip(np.arange(F)[:, None] + np.asarray(lags)[None, :], 0, F - 1)  # (F, n)
    points = np.arange(P)
    rows = 2 * frames[:, None, :, None] + np.arange(2)[None, :, None, None]  # (F, 2, n, 1)
    gather = (rows * P + points).reshape(2 * F, -1)
    order = np.arange(gather.size).reshape(2 * F, len(lags), P).transpose(1, 0, 2).ravel()
    target = gather.ravel()[order]
    mask = (frames[:, :, None] * P + points).reshape(F, -1)
    counts = np.bincount(target, minlength=2 * F * P).astype(float)
    return Copies(lags, gather, mask, order, target, counts)


def observed_entries(W):
    """Split W into zero-filled values and the (F, P) observation mask.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        NaN (or masked) marks a missing coordinate; a point is observed in a frame when both
        of its coordinates are.

    Returns
    -------
    Wz : (2F, P) ndarray
        W with every unobserved entry set to 0.
    observed : (F, P) bool ndarray

    Raises
    ------
    ValueError
        As :func:`nrsfm.validation.check_measurements`, and a frame observing fewer than 3
        points or a point observed in fewer than 2 frames (named).
    """
    A = check_measurements(W, allow_missing=True)
    F, P = A.shape[0] // 2, A.shape[1]
    obs = np.isfinite(A).reshape(F, 2, P).all(axis=1)
    _refuse_sparse(obs.sum(axis=1), 3, "frame", "observes {n} points")
    _refuse_sparse(obs.sum(axis=0), 2, "point", "is observed in {n} frames")
    return np.where(np.repeat(obs, 2, axis=0), A, 0.0), obs


def observed_mask(W):
    """The (F, P) observation mask of W, checked as by :func:`observed_entries`."""
    return observed_entries(W)[1]


def _refuse_sparse(counts, minimum, what, observes):
    """ValueError naming the first frame (or point) with fewer than ``minimum`` observations."""
    bad = np.flatnonzero(counts < minimum)
    if bad.size:
        raise ValueError(
            f"{what} {int(bad[0])} {observes.format(n=int(counts[bad[0]]))} (at least "
            f"{minimum} are needed to determine it); {bad.size} {what}(s) too sparse: "
            f"{bad[:10].tolist()}{' ...' if bad.size > 10 else ''}"
        )
