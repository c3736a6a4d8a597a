"""The completion stage's one result type, returned by both completions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A track is *determined* when its fill amplifies measurement noise at most this much
#: (:func:`~nrsfm.stages.completion.fill_gain`); a track seen in a few frames
#: is filled by an extrapolation whose gain grows without bound, and its 3D cannot be trusted.
MAX_GAIN = 3.0


@dataclass
class Completion:
    """Result of the completion of W (:func:`nrsfm.stages.completion.complete`).

    Attributes
    ----------
    W : (2F, P) ndarray
        The completed matrix: observed entries unchanged, missing ones filled.
    observed : (F, P) bool ndarray
        True where the point was observed in the frame.
    method : {"factorisation", "soft_impute"}
    lags : tuple of int
    rank : int
        Rank of the fit (soft-impute: singular values left above its final threshold).
    n_iter : int
    converged : bool
        False when the completion stopped at its iteration cap.
    fill_gain : (P,) ndarray or None
        Factorisation: how much each track's filled entries amplify measurement noise under
        its own motion M (:attr:`nrsfm.Reconstruction.fill_gain`: under ``M_hat``).
    lam, M, B, t : float, (2F, r), (r, n_lags P), (2F,) ndarray, or None
        Factorisation: the ridge weight and the factors ``W ~ M B + t 1'``.
    """

    W: np.ndarray
    observed: np.ndarray
    method: str
    lags: tuple
    rank: int
    n_iter: int
    converged: bool
    fill_gain: np.ndarray = None
    lam: float = None
    M: np.ndarray = None
    B: np.ndarray = None
    t: np.ndarray = None
