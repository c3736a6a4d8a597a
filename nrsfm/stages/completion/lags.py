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

import numpy as np

__all__ = ["LAG_RATIO", "NEIGHBOUR_LAGS", "NO_LAGS", "check_lags", "choose_lags"]

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


def lag_index(F, lags):
    """(len(lags), F) frame index of each lagged copy (edges repeated)."""
    return np.clip(np.arange(F)[None, :] + np.asarray(lags)[:, None], 0, F - 1)


def lag(A, idx):
    """The lagged matrix ``[S_d A]_d`` (n_rows, n_lags P) of A (n_rows, P) whose rows come
    in equal groups per frame (W: 2 rows per frame; the mask (F, P): 1); ``idx`` from
    :func:`lag_index`."""
    F, P = idx.shape[1], A.shape[1]
    Af = A.reshape(F, -1, P)
    return np.concatenate([Af[i].reshape(-1, P) for i in idx], axis=1)


def average_copies(L, idx):
    """(2F, P): each entry of W as the mean of its copies in the lagged L (2F, n_lags P)."""
    n, F = idx.shape
    P = L.shape[1] // n
    acc, counts = np.zeros((F, 2, P)), np.zeros(F)
    for j, i in enumerate(idx):
        np.add.at(acc, i, L[:, j * P:(j + 1) * P].reshape(F, 2, P))
        np.add.at(counts, i, 1.0)
    return (acc / counts[:, None, None]).reshape(2 * F, P)
