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

from .stages.completion import MeasurementSettings
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

    def params(self, K, seed, scale, rotations_given):
        """What a run with these settings ran, as plain values (``Reconstruction.params``;
        ``params["settings"]`` holds the settings themselves)."""
        shape = self.shape
        return dict(method=self.method, K=K, seed=seed,
                    rotation_strategy=None if rotations_given else self.rotation.strategy,
                    rotation_options=None if rotations_given else
                    dataclasses.asdict(self.rotation),
                    shape_prior=shape.prior, shape_solver=shape.solver.name,
                    shape_options=dataclasses.asdict(shape.solver),
                    select_rotations=shape.select_rotations and not rotations_given,
                    scale=scale, rotations_given=rotations_given,
                    missing=self.measurement.missing,
                    completion=self.measurement.completion, settings=self)


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
