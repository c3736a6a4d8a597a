"""Settings of the completion stage: what to do with missing observations, and how."""

from __future__ import annotations

from dataclasses import dataclass

from ...validation import check_choice
from .solvers import check_lags

MISSING = ("complete", "error")
COMPLETIONS = ("auto", "factorisation", "soft_impute")
FILLS = ("neighbours", "model")


@dataclass(frozen=True)
class MeasurementSettings:
    """Measurement stage's missing data: refuse it, or complete W, and how (why these
    defaults: ``docs/studies/missing_data.md``).

    Attributes
    ----------
    missing : {"complete", "error"}
        Missing observations (NaN or masked): fill W by low-rank completion
        (:mod:`nrsfm.stages.completion`), or refuse.
    completion : {"auto", "factorisation", "soft_impute"}
        See :mod:`nrsfm.stages.completion`; ``auto``: ``soft_impute`` where the lags rule
        asks for time lags, else ``factorisation``.
    lags : "auto" or tuple of int
        Temporal lags of the completed matrix (distinct, containing 0); ``auto``:
        :func:`nrsfm.stages.completion.choose_lags` of W's observation mask.
    fill : {"neighbours", "model"}
        The 3D of a point in the frames it was not seen in: ``neighbours``, from its
        neighbours for the points the data leave undetermined
        (:func:`nrsfm.stages.fill.fill_unseen`); ``model``: the shape stage's fill.
    """

    missing: str = MISSING[0]
    completion: str = COMPLETIONS[0]
    lags: object = "auto"
    fill: str = FILLS[0]

    def __post_init__(self):
        check_choice("missing", self.missing, MISSING)
        check_choice("completion", self.completion, COMPLETIONS)
        check_choice("fill", self.fill, FILLS)
        if self.lags != "auto":
            object.__setattr__(self, "lags", check_lags(self.lags))
