"""Every setting of one ``reconstruct`` run, composed from the stages' own settings, and the
presets of the four methods.

Each stage owns its settings class, its validation and its choice lists:

* :class:`MeasurementSettings`: what to do with missing observations, and how to complete
  them (the completion stage).
* :class:`~nrsfm.stages.rotations.RotationSettings` (:mod:`nrsfm.stages.rotations`): the
  ``organic`` and ``bmm`` rotation stage. Research variants:
  :mod:`nrsfm.research`.
* :class:`~nrsfm.stages.shape.ShapeSettings` (:mod:`nrsfm.stages.shape`): the prior and one
  solver's settings (:class:`~nrsfm.stages.shape.bilinear.BilinearSettings`,
  :class:`~nrsfm.stages.shape.admm.AdmmSettings`, ...; the registry
  :data:`nrsfm.stages.shape.SOLVERS`).

This module composes them: :class:`Settings` (``Settings(method="bmm")`` is the BMM
baseline: a method is a preset, not a label) and :func:`method_settings`, the dict form
that ``reconstruct(method=..., shape_solver=..., rotation_options=..., shape_options=...)``
uses.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple, Optional

from .stages.rotations import RotationSettings
from .stages.shape import SOLVERS, ShapeSettings, solver_settings
from .stages.shape.admm import AdmmSettings
from .stages.shape.bilinear import BilinearSettings, ClosedFormSettings
from .stages.shape.constrained import ConstrainedSettings
from .stages.shape.pseudo_inverse import PseudoInverseSettings
from .validation import check_choice

__all__ = ["AdmmSettings", "BilinearSettings", "ClosedFormSettings", "ConstrainedSettings",
           "METHODS", "MeasurementSettings", "Method", "PseudoInverseSettings",
           "RotationSettings", "Settings", "ShapeSettings", "method_settings",
           "shape_solvers"]


# ----------------------------------------------------------------------------- measurement
@dataclass(frozen=True)
class MeasurementSettings:
    """Measurement stage (centring, scale, rank-3K SVD; missing data).

    Attributes
    ----------
    missing : {"complete", "error"}
        Missing observations (NaN or masked): fill W by low-rank completion
        (:mod:`nrsfm.stages.completion`), or refuse.
    completion : {"auto", "factorisation", "soft_impute"}
        How W is completed: ``factorisation``, a rank-3K factorisation of the observed
        entries (:func:`nrsfm.stages.completion_fast.complete_low_rank`; it scales to dense
        tracks), or ``soft_impute``, the nuclear-norm completion of the time-lagged matrix
        with a full SVD per iteration (:func:`nrsfm.stages.completion.complete_measurements`).
        ``auto`` (default): ``soft_impute`` where the lags rule asks for time lags (few
        points per frame for the rank: a small W, where the full SVD is cheap and the lagged
        factorisation measured 2-10x slower and stops at its iteration cap), else
        ``factorisation``. Measurements: ``docs/missing_data_scale.md``.
    lags : "auto" or tuple of int
        Temporal lags of the completed matrix (distinct, containing 0); ``auto``: the rule
        of :func:`nrsfm.stages.completion.choose_lags`, computed from W's observation mask.
    """

    missing: str = "complete"
    completion: str = "auto"
    lags: object = "auto"

    def __post_init__(self):
        check_choice("missing", self.missing, ("complete", "error"))
        check_choice("completion", self.completion, ("auto", "factorisation", "soft_impute"))
        if self.lags != "auto":
            lags = tuple(self.lags) if isinstance(self.lags, (tuple, list)) else None
            if (lags is None or not all(isinstance(d, int) for d in lags) or 0 not in lags
                    or len(set(lags)) != len(lags)):
                raise ValueError(f"lags must be 'auto' or distinct integers including 0; "
                                 f"got {self.lags!r}")
            object.__setattr__(self, "lags", lags)


# ----------------------------------------------------------------------------- methods
class Method(NamedTuple):
    """What a method fixes: its rotation strategy, its shape prior (None: no prior) and,
    for a method defined by its solver, that solver's name."""

    strategy: str
    prior: Optional[str]
    solver: Optional[str] = None


#: method -> what it fixes. The other settings are the stages' defaults.
METHODS = {
    "organic": Method("organic", "organic"),    # all K triplets, averaged; partial-sum WNN
    "bmm": Method("bmm", "nuclear"),            # Dai et al.: first triplet, nuclear norm
    "wnn": Method("organic", "weighted"),       # weighted nuclear norm over all values
    "pseudo_inverse": Method("organic", None, "pseudo_inverse"),   # rank-K pinv(R) W
}


def _preset_stages(method):
    """(RotationSettings, ShapeSettings) of a method's preset."""
    m = METHODS[method]
    shape = (ShapeSettings(prior=None, solver=SOLVERS[m.solver]()) if m.solver else
             ShapeSettings(prior=m.prior))
    return RotationSettings.preset(m.strategy), shape


def _agrees(method, rotation, shape):
    """Why the stage settings do not make ``method`` (None when they do)."""
    m = METHODS[method]
    if rotation.strategy != m.strategy:
        return f"rotation strategy {rotation.strategy!r} (the method's is {m.strategy!r})"
    if m.solver is not None and shape.solver.name != m.solver:
        return f"shape solver {shape.solver.name!r} (the method's is {m.solver!r})"
    if m.solver is None and shape.solver.name in {s for _, _, s in METHODS.values() if s}:
        return f"shape solver {shape.solver.name!r} (that is method {shape.solver.name!r})"
    if shape.solver.uses_prior and shape.prior != m.prior:
        return f"shape prior {shape.prior!r} (the method's is {m.prior!r})"
    return None


@dataclass(frozen=True)
class Settings:
    """Every setting of one ``reconstruct`` run.

    Parameters
    ----------
    method : {"organic", "bmm", "wnn", "pseudo_inverse"} or None
        A preset (:data:`METHODS`): the stage settings not given are the method's, and the
        ones given must agree with it (its rotation strategy, its prior; a solver without
        a prior, such as ``closed_form``, may replace the prior). None: compose freely
        from the ``organic`` preset's defaults; ``method`` then becomes the preset the
        stages agree with, or ``"custom"``.
    measurement : MeasurementSettings, optional
    rotation : RotationSettings, optional
        Production or research (:mod:`nrsfm.research`) rotation settings.
    shape : ShapeSettings, optional

    Raises
    ------
    ValueError
        Unknown method, a stage setting of the wrong type, or stage settings that are not
        the named method's (what differs is named).

    Examples
    --------
    >>> Settings(method="bmm").rotation.strategy, Settings(method="bmm").shape.prior
    ('bmm', 'nuclear')
    >>> Settings(rotation=RotationSettings.preset("bmm")).method
    'custom'
    """

    method: Optional[str] = None
    measurement: Optional[MeasurementSettings] = None
    rotation: Optional[RotationSettings] = None
    shape: Optional[ShapeSettings] = None

    def __post_init__(self):
        if self.method is not None and self.method != "custom":
            check_choice("method", self.method, METHODS)
        given = self.method not in (None, "custom")
        rotation, shape = _preset_stages(self.method if given else "organic")
        defaults = dict(measurement=MeasurementSettings(), rotation=rotation, shape=shape)
        for name, cls in (("measurement", MeasurementSettings),
                          ("rotation", RotationSettings), ("shape", ShapeSettings)):
            value = getattr(self, name)
            if value is None:
                object.__setattr__(self, name, defaults[name])
            elif not isinstance(value, cls):
                raise ValueError(f"{name} must be a {cls.__name__}; got {value!r}")
        if given:
            why = _agrees(self.method, self.rotation, self.shape)
            if why is not None:
                raise ValueError(f"Settings(method={self.method!r}) with {why}: give the "
                                 f"method's settings, or method=None to compose freely")
        else:
            label = next((m for m in METHODS if _agrees(m, self.rotation, self.shape) is None
                          and type(self.rotation) is RotationSettings), "custom")
            object.__setattr__(self, "method", label)

    @classmethod
    def preset(cls, method="organic"):
        """The settings of a method (:data:`METHODS`)."""
        return cls(method=method)


def shape_solvers():
    """Names of the registered shape solvers a method can use (``shape_solver=``): every
    solver in :data:`nrsfm.stages.shape.SOLVERS` but those that are a method of their own."""
    own = {m.solver for m in METHODS.values()}
    return [name for name in SOLVERS if name not in own]


def method_settings(method="organic", shape_solver="bilinear", rotation_options=None,
                    shape_options=None, missing="complete"):
    """The preset of a method, with dict options converted into the typed settings.

    Parameters
    ----------
    method : {"organic", "bmm", "wnn", "pseudo_inverse"}
    shape_solver : str
        A solver registered in :data:`nrsfm.stages.shape.SOLVERS`. ``pseudo_inverse`` is
        the method of that name (its shape is the rank-K truncation), so it takes the
        default ``bilinear`` here or ``pseudo_inverse`` itself.
    rotation_options : dict, optional
        Fields of :class:`RotationSettings` that override the method's preset
        (``strategy``, which the method fixes, is refused: choose the method; research
        strategies: :func:`nrsfm.research.research_settings`).
    shape_options : dict, optional
        Fields of the solver's settings type.
    missing : {"complete", "error"}

    Returns
    -------
    Settings

    Raises
    ------
    ValueError
        Unknown method, solver or option (the known ones are named), or an option the
        method fixes.
    """
    check_choice("method", method, METHODS)
    rotation, shape = _preset_stages(method)
    options = dict(rotation_options or {})
    if "strategy" in options and options["strategy"] != rotation.strategy:
        raise ValueError(f"rotation strategy {options['strategy']!r} with method "
                         f"{method!r}: the method fixes the strategy "
                         f"({rotation.strategy!r}); choose the method (bmm: method='bmm'), "
                         f"or nrsfm.research.research_settings for a research strategy")
    fields = {f.name for f in dataclasses.fields(RotationSettings)}
    unknown = set(options) - fields
    if unknown:
        raise ValueError(f"unknown rotation options {sorted(unknown)}; expected some of "
                         f"{sorted(fields)}")
    rotation = dataclasses.replace(rotation, **options)
    if METHODS[method].solver is not None:
        if shape_solver not in ("bilinear", METHODS[method].solver) or shape_options:
            raise ValueError(f"method {method!r} is its own shape solver; it takes no "
                             f"shape_solver ({shape_solver!r}) or shape_options "
                             f"({sorted(shape_options or {})})")
    else:
        solver = solver_settings(shape_solver, shape_options)
        shape = ShapeSettings(prior=METHODS[method].prior if solver.uses_prior else None,
                              solver=solver)
    return Settings(method=method, measurement=MeasurementSettings(missing=missing),
                    rotation=rotation, shape=shape)
