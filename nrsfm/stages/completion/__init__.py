"""Missing data: low-rank completion of the measurement matrix W (paper Sec. 4e-ii).

The paper completes W with Cabral et al.'s method and then runs its algorithm on the
completed matrix; :func:`nrsfm.reconstruct` does the same (``missing="complete"``) through
:func:`complete`, which returns one :class:`Completion`. Two completions, chosen by
:class:`MeasurementSettings` ``.completion``:

* ``soft_impute`` (:mod:`.soft_impute`): nuclear-norm completion of the time-lagged W,
  a full SVD per iteration;
* ``factorisation`` (:mod:`.factorisation`): a rank-3K factorisation of the observed
  entries, no SVD after the start (it scales to video);
* ``auto`` (default): soft-impute where the lags rule (:func:`choose_lags`) asks for time
  lags (few points per frame for the rank: MoCap-sized W, where the full SVD is cheap), the
  factorisation elsewhere (dense tracks). Measurements: ``docs/missing_data_scale.md``.

:func:`complete` reads the mask (:mod:`.masks`) and the lags (:mod:`.lags`) once, and
hands the checked, zero-filled W and the lagged matrix's copies to one solver, which then
works alone: each solver module holds its whole iteration (the factorisation also holds
its normal matrices and the fill gain they give, :func:`.factorisation.fill_gain`). The
modules import one way only: ``settings``, ``lags``, ``masks``, ``result`` (no imports
inside the package) <- ``soft_impute``, ``factorisation`` <- this module.
"""

from __future__ import annotations

import warnings

from ...warnings_catalog import text
from .factorisation import complete_low_rank, factorise_lagged, fill_gain
from .lags import NEIGHBOUR_LAGS, NO_LAGS, choose_lags, lag_copies
from .masks import observed_entries, observed_mask
from .result import MAX_GAIN, Completion
from .settings import COMPLETIONS, FILLS, MISSING, MeasurementSettings
from .soft_impute import complete_measurements, soft_impute_lagged

__all__ = ["COMPLETIONS", "Completion", "FILLS", "MAX_GAIN", "MISSING", "MeasurementSettings",
           "NEIGHBOUR_LAGS", "NO_LAGS", "choose_lags", "complete", "complete_low_rank",
           "complete_measurements", "fill_gain", "observed_entries", "observed_mask"]


def complete(W, K, settings):
    """Fill the missing entries of W for K shape bases, as ``settings`` say.

    Parameters
    ----------
    W : (2F, P) ndarray
        NaN where missing.
    K : int
        Rank of the completion: 3K (Eq. 1).
    settings : MeasurementSettings
        ``completion`` and ``lags``.

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
        When the completion stopped at its iteration cap before converging
        (``W-completion-cap``, ``docs/warnings.md``).
    """
    Wz, observed = observed_entries(W)
    rank = 3 * K
    lags = (choose_lags(observed, rank) if settings.lags == "auto"
            else tuple(settings.lags))
    copies = lag_copies(*observed.shape, lags)
    method = settings.completion
    if method == "auto":                  # the full SVD is cheap exactly where lags are due
        method = "soft_impute" if len(copies.lags) > 1 else "factorisation"
    if method == "soft_impute":
        result = soft_impute_lagged(Wz, observed, copies)
    else:
        result = factorise_lagged(Wz, observed, rank, copies)
    if not result.converged:
        warnings.warn(text("W-completion-cap", n_iter=result.n_iter), RuntimeWarning,
                      stacklevel=3)
    return result
