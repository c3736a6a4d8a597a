"""Settings of the completion stage: what to do with missing observations, and how."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["COMPLETIONS", "FILLS", "MISSING", "MeasurementSettings"]

#: What to do with missing observations (``MeasurementSettings.missing``).
MISSING = ("complete", "error")
#: How W is completed (``MeasurementSettings.completion``); the first is the default.
COMPLETIONS = ("auto", "factorisation", "soft_impute")
#: How the shapes of the points not seen are filled (``MeasurementSettings.fill``); the
#: first is the default (``neighbours`` fills lost tracks better: on MoCap with 30 % of the
#: tracks lost, mean fill error .033 - .088 against .059 - .27 with ``model``; it costs
#: 0.7 - 2 s on the synthetic videos and doubles reconstruct's time on 20,000 x 100 dense
#: tracks, within issue 24's bound of 5 x: docs/missing_data_scale.md)
FILLS = ("neighbours", "model")


def _choices(values):
    """``{"a", "b"}``: a tuple of allowed values as numpydoc writes a parameter's type."""
    return "{" + ", ".join(f'"{v}"' for v in values) + "}"


def _one_of(name, value, allowed):
    if value not in allowed:
        raise ValueError(f"{name} must be one of {list(allowed)}; got {value!r}")


@dataclass(frozen=True)
class MeasurementSettings:
    __doc__ = f"""Measurement stage's missing data: refuse it, or complete W, and how.

    Attributes
    ----------
    missing : {_choices(MISSING)}
        Missing observations (NaN or masked): fill W by low-rank completion
        (:mod:`nrsfm.stages.completion`), or refuse.
    completion : {_choices(COMPLETIONS)}
        How W is completed: ``factorisation``, a rank-3K factorisation of the observed
        entries (:func:`nrsfm.stages.completion.factorisation.complete_low_rank`; it
        scales to dense tracks), or ``soft_impute``, the nuclear-norm completion of the
        time-lagged matrix with a full SVD per iteration
        (:func:`nrsfm.stages.completion.soft_impute.complete_measurements`). ``auto``
        (default): ``soft_impute`` where the lags rule asks for time lags (few points per
        frame for the rank: a small W such as MoCap's, where the full SVD is cheap), else
        ``factorisation``. Measurements: ``docs/missing_data_scale.md``.
    lags : "auto" or tuple of int
        Temporal lags of the completed matrix (distinct, containing 0); ``auto``: the rule
        of :func:`nrsfm.stages.completion.choose_lags`, computed from W's observation mask.
    fill : {_choices(FILLS)}
        The 3D of a point in the frames it was not seen in: ``neighbours`` (default), for
        the points the data leave undetermined, the median of its rigid, template and
        affine fills from its neighbours and of the shape stage's fill
        (:func:`nrsfm.stages.fill.fill_unseen`, issue 24), the shape stage's fill for the
        others; ``model``, the shape stage's fill everywhere.
    """

    missing: str = MISSING[0]
    completion: str = COMPLETIONS[0]
    lags: object = "auto"
    fill: str = FILLS[0]

    def __post_init__(self):
        _one_of("missing", self.missing, MISSING)
        _one_of("completion", self.completion, COMPLETIONS)
        _one_of("fill", self.fill, FILLS)
        if self.lags != "auto":
            lags = tuple(self.lags) if isinstance(self.lags, (tuple, list)) else None
            if (lags is None or not all(isinstance(d, int) for d in lags) or 0 not in lags
                    or len(set(lags)) != len(lags)):
                raise ValueError(f"lags must be 'auto' or distinct integers including 0; "
                                 f"got {self.lags!r}")
            object.__setattr__(self, "lags", lags)
