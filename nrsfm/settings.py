"""Every setting of one ``reconstruct`` run: the method (:data:`METHODS`: how many triplets,
which prior) and each stage's own settings class, which owns and validates its fields
(:class:`MeasurementSettings`, :class:`RotationSettings`, :class:`BilinearSettings` or
:class:`AdmmSettings`). One run is configured one way: ``reconstruct(W, K, **keywords)``,
each keyword one field of :class:`Settings` (:data:`KEYWORDS`), or ``settings=``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Optional, Union

from .stages.completion import MeasurementSettings
from .stages.perspective import PerspectiveSettings
from .stages.rotations import RotationSettings
from .stages.shape import SOLVERS, AdmmSettings, BilinearSettings
from .validation import check_choice

__all__ = ["KEYWORDS", "METHODS", "Settings"]


class Method(NamedTuple):
    """What a method computes: one corrective triplet (``single``) or K averaged, and its
    shape prior (None: the rank-K truncation of the pseudo-inverse shape, no solver)."""

    single: bool
    prior: Optional[str]


#: method -> what it computes
METHODS = {
    "organic": Method(False, "organic"),  # the paper: K triplets averaged, Eq. 10
    "bmm": Method(True, "nuclear"),  # Dai et al.: the first triplet, Eq. 7
    "wnn": Method(False, "weighted"),  # every singular value weighted, Eq. 8
    "pseudo_inverse": Method(False, None),  # rank-K truncation of pinv(R) W (Table 1)
}

#: the rotation fields that a single triplet does not use (``bmm``: nothing to average)
_AVERAGING = ("window", "delta", "max_iter", "eps")


@dataclass(frozen=True)
class Settings:
    """Every setting of one ``reconstruct`` run.

    Parameters
    ----------
    method : {"organic", "bmm", "wnn", "pseudo_inverse"}
        What the stages compute (:data:`METHODS`).
    measurement : MeasurementSettings
    rotation : RotationSettings
    shape : BilinearSettings or AdmmSettings or None
        The shape solver; None: ``BilinearSettings()``, or no solver for
        ``pseudo_inverse``.
    perspective : PerspectiveSettings
        The perspective refinement (used with ``reconstruct(..., intrinsics=)`` only).

    Raises
    ------
    ValueError
        Unknown method, a stage's settings of the wrong type, a shape solver with
        ``pseudo_inverse`` (it has none), or averaging settings with ``bmm`` (one triplet):
        nothing given is ignored.

    Examples
    --------
    >>> Settings(method="bmm").shape_solver, Settings(method="bmm").prior
    ('bilinear', 'nuclear')
    >>> Settings(shape=AdmmSettings(N=2)).shape.N
    2
    """

    method: str = "organic"
    measurement: MeasurementSettings = MeasurementSettings()
    rotation: RotationSettings = RotationSettings()
    shape: Union[BilinearSettings, AdmmSettings, None] = None
    perspective: PerspectiveSettings = PerspectiveSettings()

    def __post_init__(self):
        check_choice("method", self.method, METHODS)
        for name, cls in (
            ("measurement", MeasurementSettings),
            ("rotation", RotationSettings),
            ("perspective", PerspectiveSettings),
        ):
            if not isinstance(getattr(self, name), cls):
                raise ValueError(f"{name} must be a {cls.__name__}; got {getattr(self, name)!r}")
        if self.method == "pseudo_inverse":
            if self.shape is not None:
                raise ValueError(
                    f"method 'pseudo_inverse' has no shape solver; got shape={self.shape!r}"
                )
        elif self.shape is None:
            object.__setattr__(self, "shape", BilinearSettings())
        elif not isinstance(self.shape, tuple(SOLVERS.values())):
            raise ValueError(
                f"shape must be a BilinearSettings or an AdmmSettings; got {self.shape!r}"
            )
        if self.method == "bmm":
            given = [
                f for f in _AVERAGING if getattr(self.rotation, f) != getattr(RotationSettings(), f)
            ]
            if given:
                raise ValueError(
                    f"method 'bmm' uses one triplet: {', '.join(given)} of the "
                    f"rotation settings would be ignored"
                )

    @property
    def prior(self):
        """The shape prior of the method (None for ``pseudo_inverse``)."""
        return METHODS[self.method].prior

    @property
    def shape_solver(self):
        """The shape solver's name (None for ``pseudo_inverse``)."""
        return None if self.shape is None else self.shape.name

    @classmethod
    def from_keywords(cls, method="organic", shape_solver=None, missing="complete"):
        """The settings of ``reconstruct``'s keywords (:data:`KEYWORDS`), the stages'
        defaults elsewhere.

        Raises
        ------
        ValueError
            Unknown method, shape solver or missing-data rule (the choices are named).
        """
        shape = None
        if shape_solver is not None:
            shape = SOLVERS[check_choice("shape_solver", shape_solver, SOLVERS)]()
        return cls(method=method, shape=shape, measurement=MeasurementSettings(missing=missing))


#: ``reconstruct``'s keywords and the :class:`Settings` field each one sets
KEYWORDS = {
    "method": "method",
    "shape_solver": "shape (BilinearSettings() or AdmmSettings())",
    "missing": "measurement.missing",
}
