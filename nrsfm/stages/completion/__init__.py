"""Missing data: low-rank completion of the measurement matrix W (paper Sec. 4e-ii).

The paper completes W (Cabral et al.) and runs on the completed matrix; so does
:func:`nrsfm.reconstruct`, through :func:`complete`. ``factorisation``
(:func:`complete_low_rank`): a rank-3K factorisation of the observed entries (it scales to
video); ``soft_impute`` (:func:`complete_measurements`): nuclear-norm completion of the
time-lagged W, a full SVD per iteration; ``auto``: soft-impute where the lags rule
(:func:`choose_lags`) asks for time lags (few points per frame for the rank, where the SVD
is cheap), else the factorisation. Both live in :mod:`.solvers`. Why these defaults:
``docs/studies/missing_data.md``.
"""

from __future__ import annotations

import warnings

from ...warnings_catalog import text
from .result import MAX_GAIN, Completion
from .settings import MeasurementSettings
from .solvers import choose_lags, complete_low_rank, complete_measurements, fill_gain
from .solvers import observed_entries, observed_mask

__all__ = ["MAX_GAIN", "Completion", "MeasurementSettings", "choose_lags", "complete", "fill_gain"]
__all__ += ["complete_low_rank", "complete_measurements", "observed_entries", "observed_mask"]


def complete(W, K, settings):
    """Fill the missing entries of W for K shape bases, as ``settings`` say.

    Parameters
    ----------
    W : (2F, P) ndarray
        As :func:`nrsfm.validation.check_problem` returns it: NaN marks a missing entry.
    K : int
        The completion's rank is 3K (Eq. 1), checked with W.
    settings : MeasurementSettings

    Returns
    -------
    Completion
        With ``method`` the completion that ran (``auto`` resolved).

    Raises
    ------
    ValueError
        A frame or point with too few observations (named).

    Warns
    -----
    RuntimeWarning
        ``W-completion-cap`` (``docs/warnings.md``): stopped at the iteration cap.
    """
    lags = choose_lags(observed_mask(W), 3 * K) if settings.lags == "auto" else settings.lags
    method = settings.completion
    if method == "auto":  # the full SVD is cheap exactly where lags are due
        method = "soft_impute" if len(lags) > 1 else "factorisation"
    if method == "factorisation":
        result = complete_low_rank(W, 3 * K, lags)
    else:
        result = complete_measurements(W, lags)
    if not result.converged:
        warnings.warn(text("W-completion-cap", n_iter=result.n_iter), RuntimeWarning, stacklevel=3)
    return result
