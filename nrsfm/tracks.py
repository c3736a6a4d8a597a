"""Reconstruction of point tracks that may be lost part-way (NaN entries), e.g. tracked
through a video: :func:`reconstruct_tracks`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class VideoReconstruction:
    """Result of :func:`reconstruct_tracks`: the :class:`nrsfm.Reconstruction` of the tracks
    ``used`` ((P,) bool), the numbers of tracks and of complete ones (observed in every
    frame), and whether the tracks with lost entries were passed as missing data (False:
    the complete tracks only)."""

    result: object
    used: np.ndarray
    n_tracks: int
    n_complete: int
    missing_data: bool


def reconstruct_tracks(W, K=1, *, missing="auto", **kw):
    """Reconstruct tracks that may hold NaN (lost) entries.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Pixel tracks, NaN where a track is lost.
    K : int
        Number of shape bases (dense input: the paper's K = 1).
    missing : {"auto", "complete"}
        ``auto``: every track seen in at least 2 frames, NaN included, as missing data; the
        complete tracks when the observations are too sparse for it. ``complete``: the
        complete tracks only.
    **kw
        Passed to :func:`nrsfm.reconstruct` (``method``, ``seed``, ``progress``, ...).

    Returns a :class:`VideoReconstruction`; ValueError for a bad shape, an unknown
    ``missing`` or too few complete tracks for K.
    """
    from .pipeline import reconstruct

    if missing not in ("auto", "complete"):
        raise ValueError(f"missing must be 'auto' or 'complete'; got {missing!r}")
    A = np.asarray(W, float)
    if A.ndim == 3:
        if A.shape[1] != 2:
            raise ValueError(f"tracks must have shape (F, 2, P); got {A.shape}")
        A = A.reshape(2 * A.shape[0], A.shape[2])
    if A.ndim != 2 or A.shape[0] % 2:
        raise ValueError(f"W must have shape (2F, P) or (F, 2, P); got {A.shape}")
    P, complete = A.shape[1], np.isfinite(A).all(axis=0)
    if missing == "auto" and not complete.all():
        # a track seen in fewer than 2 frames has no depth to recover: not used
        seen = np.isfinite(A).reshape(-1, 2, P).all(axis=1).sum(axis=0) >= 2
        try:
            res = reconstruct(A[:, seen], K, **kw)
            return VideoReconstruction(res, seen, P, int(complete.sum()), True)
        except ValueError as exc:  # e.g. a frame that observes too few tracks
            if not any(w in str(exc) for w in ("NaN", "observe", "too sparse")):
                raise
    n, need = int(complete.sum()), max(3, 3 * int(K))
    if n < need:
        complete = f"only {n} of {P} tracks are complete (observed in every frame)"
        raise ValueError(f"{complete}; K={K} needs at least {need}")
    return VideoReconstruction(reconstruct(A[:, complete], K, **kw), complete, P, n, False)
