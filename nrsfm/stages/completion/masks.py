"""The observation mask of a W with missing entries.

A missing observation is a (frame, point) pair: both coordinates go together, so the mask
is per point and frame, ``observed`` (F, P), expanded to W's (2F, P) rows. A frame must
observe at least 3 points (an orthographic camera and its translation) and a point must be
observed in at least 2 frames (its depth); sparser rows or columns are refused by name.
"""

from __future__ import annotations

import numpy as np

__all__ = ["observed_entries", "observed_mask"]


def observed_mask(W, min_points=3, min_frames=2):
    """The (F, P) observation mask of a (2F, P) W with NaN for missing entries.

    A point counts as observed in a frame only when both of its coordinates are finite.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
    min_points : int
        Each frame must observe at least this many points (an orthographic camera and its
        translation need 3).
    min_frames : int
        Each point must be observed in at least this many frames (its depth needs 2).

    Returns
    -------
    observed : (F, P) bool ndarray

    Raises
    ------
    ValueError
        Bad shapes, infinite entries, or a frame / point with too few observations (named).
    """
    return _mask(_as_2f_p(W), None, min_points, min_frames)


def observed_entries(W, observed=None):
    """Split W into zero-filled values and the (F, P) observation mask.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        NaN marks a missing coordinate; a point is observed in a frame when both are finite.
    observed : (F, P) bool array_like, optional
        Further restricts the mask.

    Returns
    -------
    Wz : (2F, P) ndarray
        W with every unobserved entry set to 0.
    observed : (F, P) bool ndarray

    Raises
    ------
    ValueError
        Bad shapes, infinite entries, a frame observing fewer than 3 points or a point
        observed in fewer than 2 frames (named).
    """
    A = _as_2f_p(W)
    obs = _mask(A, observed, 3, 2)
    return np.where(np.repeat(obs, 2, axis=0), A, 0.0), obs


def _as_2f_p(W):
    """W as a float (2F, P) array (a copy); ValueError naming any other shape."""
    A = np.array(W, dtype=float)
    if A.ndim == 3 and A.shape[1] == 2:
        A = A.reshape(2 * A.shape[0], A.shape[2])
    if A.ndim != 2 or A.shape[0] % 2:
        raise ValueError(f"W must have shape (2F, P) or (F, 2, P); got {np.shape(W)}")
    return A


def _mask(A, observed, min_points, min_frames):
    """(F, P) mask of the finite pairs of A (2F, P), intersected with ``observed``."""
    if np.isinf(A).any():
        raise ValueError(f"W contains {int(np.isinf(A).sum())} infinite entries "
                         "(use NaN for a missing observation)")
    F, P = A.shape[0] // 2, A.shape[1]
    obs = np.isfinite(A).reshape(F, 2, P).all(axis=1)
    if observed is not None:
        observed = np.asarray(observed, dtype=bool)
        if observed.shape != (F, P):
            raise ValueError(f"observed must have shape (F, P) = ({F}, {P}); "
                             f"got {observed.shape}")
        obs &= observed
    _refuse_sparse(obs.sum(axis=1), min_points, "frame", "observes {n} points")
    _refuse_sparse(obs.sum(axis=0), min_frames, "point", "is observed in {n} frames")
    return obs


def _refuse_sparse(counts, minimum, what, observes):
    """ValueError naming the first of the frames (or points) with fewer than ``minimum``
    observations, and how many there are."""
    bad = np.flatnonzero(counts < minimum)
    if bad.size:
        raise ValueError(
            f"{what} {int(bad[0])} {observes.format(n=int(counts[bad[0]]))} (at least "
            f"{minimum} are needed to determine it); {bad.size} {what}(s) too sparse: "
            f"{bad[:10].tolist()}{' ...' if bad.size > 10 else ''}")
