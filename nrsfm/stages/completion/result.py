"""The completion stage's one result type, returned by both completions."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Completion", "MAX_GAIN"]

#: A track is "determined" when its fill amplifies measurement noise at most this much
#: (:func:`~nrsfm.stages.completion.factorisation.fill_gain`): a track seen in a few
#: frames only is filled by an extrapolation whose noise gain grows without bound as its
#: observed frames shrink; above this gain the data do not pin the track down (it is
#: *undetermined*: filled, but its 3D cannot be trusted).
MAX_GAIN = 3.0


@dataclass
class Completion:
    """Result of the completion of W (:func:`nrsfm.stages.completion.complete`, or of
    either completion called alone).

    Attributes
    ----------
    W : (2F, P) ndarray
        The completed matrix: observed entries unchanged, missing ones filled.
    observed : (F, P) bool ndarray
        True where the point was observed in the frame.
    method : {"factorisation", "soft_impute"}
        The completion that ran.
    lags : tuple of int
        Temporal lags (frames) of the completed matrix (:mod:`.lags`).
    rank : int
        Rank of the fit: r of the factorisation, or the number of singular values left
        above soft-impute's final threshold.
    n_iter : int
        Iterations (soft-impute: over the whole continuation).
    converged : bool
        False when the completion stopped at its iteration cap.
    fill_gain : (P,) ndarray or None
        How much each track's filled entries amplify measurement noise under the
        factorisation's own motion M, lag-0 columns
        (:func:`~nrsfm.stages.completion.factorisation.fill_gain`); None from soft-impute.
        :attr:`nrsfm.Reconstruction.fill_gain` is the gain under the rank-3K motion
        ``M_hat`` that the later stages use, for either completion.
    history : dict of ndarrays
        Per iteration. Soft-impute: ``tau`` and ``change`` (relative change of the filled
        entries); factorisation: ``cost`` (objective / (1/2 ||P_Omega(W - mean)||^2)).
    tau : float or None
        Soft-impute: the final singular value threshold (input units).
    lam : float or None
        Factorisation: the ridge weight (input units).
    M : (2F, r) ndarray or None
        Factorisation: the motion factor (row pairs per frame).
    B : (r, n_lags P) ndarray or None
        Factorisation: the structure factor (one column per point and lag, lag-major).
    t : (2F,) ndarray or None
        Factorisation: the per-row offset (the per-frame translation, before centring).
    """

    W: np.ndarray
    observed: np.ndarray
    method: str
    lags: tuple
    rank: int
    n_iter: int
    converged: bool
    fill_gain: np.ndarray = None
    history: dict = field(default_factory=dict)
    tau: float = None
    lam: float = None
    M: np.ndarray = None
    B: np.ndarray = None
    t: np.ndarray = None

    @property
    def missing_fraction(self):
        """Fraction of the (frame, point) observations that were missing."""
        return float(1.0 - self.observed.mean())

    def determined(self, max_gain=MAX_GAIN):
        """(P,) bool: tracks whose filled entries amplify noise at most ``max_gain`` x
        (needs :attr:`fill_gain`)."""
        if self.fill_gain is None:
            raise ValueError("determined() needs fill_gain, which soft-impute does not "
                             "compute; use the factorisation, or "
                             "nrsfm.Reconstruction.undetermined")
        return self.fill_gain <= max_gain

    def rms_residual(self):
        """RMS of the factorisation's lag-0 fit on the observed entries (input units)."""
        if self.M is None:
            raise ValueError(f"rms_residual() needs the factors M, B, t of the "
                             f"factorisation; this completion is {self.method!r}")
        o2 = np.repeat(self.observed, 2, axis=0)
        P = self.observed.shape[1]
        j = self.lags.index(0)
        fit = self.M @ self.B[:, j * P:(j + 1) * P] + self.t[:, None]
        return float(np.sqrt(np.mean((self.W - fit)[o2] ** 2)))
