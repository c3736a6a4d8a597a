"""Missing data: low-rank completion of the measurement matrix W (paper Sec. 4e-ii).

The paper completes W (Cabral et al.) and runs on the completed matrix; so does
:func:`nrsfm.reconstruct`, through :func:`complete`. ``soft_impute`` (:mod:`.soft_impute`):
nuclear-norm completion of the time-lagged W, a full SVD per iteration; ``factorisation``
(:mod:`.factorisation`): a rank-3K factorisation of the observed entries (it scales to
video); ``auto``: soft-impute where the lags rule (:func:`choose_lags`) asks for time lags
(few points per frame for the rank, where the SVD is cheap), else the factorisation. Why
these defaults: ``docs/studies/missing_data.md``.
"""

from __future__ import annotations

import warnings

from ...warnings_catalog import text
from .factorisation import complete_low_rank, fill_gain
from .lags import choose_lags, observed_entries, observed_mask
from .result import MAX_GAIN, Completion
from .settings import MeasurementSettings
from .soft_impute import complete_measurements

__all__ = ["MAX_GAIN", "Completion", "MeasurementSettings", "choose_lags", "complete", "fill_gain"]
__all__ += ["complete_low_rank", "complete_measurements", "observed_entries", "observed_mask"]


def complete(W, K, settings):
    """Fill the missing entries of W for K shape bases, as ``settings`` say.

    Parameters
    ----------
    W : (2F, P) ndarray
        NaN where missing.
    K : int
        The completion's rank is 3K (Eq. 1).
    settings : MeasurementSettings

    Returns
    -------
    Completion
        With ``method`` the completion that ran (``auto`` resolved).

    Raises
    ------
    ValueError
        A frame or point with too few observations (named), bad shapes.

    Warns
    -----
    RuntimeWarning
        ``W-completion-cap`` (``docs/warnings.md``): stopped at the iteration cap.
    """
    lags = choose_lags(observed_mask(W), 3 * K) if settings.lags == "auto" else settings.lags
    method = settings.completion
    if method == "auto":  # the full SVD is cheap exactly where lags are due
        method = "soft_impute" if len(lags) > 1 else "factorisation"
    if method == "soft_impute":
        result = complete_measurements(W, lags)
    else:
        result = complete_low_rank(W, 3 * K, lags)
    if not result.converged:
        warnings.warn(text("W-completion-cap", n_iter=result.n_iter), RuntimeWarning, stacklevel=3)
    return result
