"""Settings of the research rotation variants: :class:`RotationAblationSettings` (the
production :class:`~nrsfm.stages.rotations.RotationSettings` plus the research fields), the
dict form :func:`rotation_settings`, and :func:`research_settings` for a whole run.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Optional

from ..settings import Settings
from ..stages.rotations import RotationSettings
from ..validation import check_choice, check_integer, check_positive

__all__ = ["RotationAblationSettings", "research_settings", "rotation_settings"]


@dataclass(frozen=True)
class RotationAblationSettings(RotationSettings):
    """The rotation stage with the research variants no method uses by default
    (run by :func:`nrsfm.research.rotations.estimate_rotations_ablation`).

    Attributes
    ----------
    strategy : {"organic", "family", "bmm", "literal", "multistart", "windows",
                "bootstrap"}
        See :data:`nrsfm.research.rotations.STRATEGIES`.
    combine : {"family"} or None
        Maximum-ratio combination of the triplet family consistent with the average
        (:mod:`nrsfm.research.family`).
    combine_iter, combine_tol : int, float
        At most ``combine_iter`` family <-> rotation alternations, stopped when the
        median per-frame change (rad) is below ``combine_tol``.
    filter_metric : {"angle", "chordal"}
    coef_gate : float
        Drop samples with ``|c_fk| < coef_gate * median_f |c_fk|``.
    coef_weights : bool
        Weight samples by ``|c_fk| / median_f |c_fk|`` in the average.
    subsets : {"windows", "bootstrap", "random"}
        Frame subsets of the K - 1 extra triplets.
    starts : {"search", "relaxed", "dai", "columns", "multistart"}
        Starts of the triplet refinement (:func:`nrsfm.research.rotations.corrective_triplets_from`).
    lam : float
        Penalty of :func:`nrsfm.stages.corrective.penalized_gram` (non-search starts).
    gram : {"penalized", "nuclear"}
        Relaxation whose column blocks ``starts="columns"`` refines.
    n_random, n_full, screen_frames, screen_iter : int
        The ``multistart`` starts.
    average : {"l1", "chordal"}
    refit : bool
        Project the average back onto the single triplet that fits it best.
    """

    STRATEGIES: ClassVar[tuple] = ("organic", "family", "bmm", "literal", "multistart",
                                   "windows", "bootstrap")
    combine: Optional[str] = None
    combine_iter: int = 5
    combine_tol: float = 1e-3
    filter_metric: str = "angle"
    coef_gate: float = 0.0
    coef_weights: bool = False
    subsets: str = "windows"
    starts: str = "search"
    lam: float = 1e2
    gram: str = "penalized"
    n_random: int = 32
    n_full: int = 4
    screen_frames: int = 80
    screen_iter: int = 30
    average: str = "l1"
    refit: bool = False

    def __post_init__(self):
        super().__post_init__()
        check_choice("combine", self.combine, ("family", None))
        check_integer(self.combine_iter, "combine_iter", minimum=1)
        check_positive("combine_tol", self.combine_tol, strict=False)
        check_choice("filter_metric", self.filter_metric, ("angle", "chordal"))
        check_positive("coef_gate", self.coef_gate, strict=False)
        check_choice("subsets", self.subsets, ("windows", "bootstrap", "random"))
        check_choice("starts", self.starts, ("search", "relaxed", "dai", "columns", "multistart"))
        check_positive("lam", self.lam)
        check_choice("gram", self.gram, ("penalized", "nuclear"))
        for name in ("n_random", "n_full", "screen_frames", "screen_iter"):
            check_integer(getattr(self, name), name, minimum=1)
        check_choice("average", self.average, ("l1", "chordal"))

    @classmethod
    def preset(cls, strategy="organic"):
        """Research strategies' settings (``docs/rotation_stage.md``)."""
        variants = {
            "organic": dict(window=0.9, filter_against="average"),
            "family": dict(window=0.9, filter_against="average", combine="family"),
            "bmm": dict(window=0.5, filter_against="reference"),
            "windows": dict(window=0.5, filter_against=None),
            "bootstrap": dict(subsets="bootstrap", window=0.5, filter_against="average"),
            "literal": dict(filter_against="reference", gram="nuclear"),
            "multistart": dict(filter_against="reference", starts="multistart"),
        }
        check_choice("rotation strategy", strategy, cls.STRATEGIES)
        return cls(strategy=strategy, **dict(dict(combine=None, window=0.5),
                                             **variants[strategy]))

    def estimate(self, M_hat, K, seed=0, progress=None):
        """Run the rotation stage with these settings
        (:func:`nrsfm.research.rotations.estimate_rotations_ablation`)."""
        from .rotations import estimate_rotations_ablation

        return estimate_rotations_ablation(M_hat, K, self, seed, progress)


def rotation_settings(strategy="organic", **options):
    """Research rotation settings from a strategy and option values (the dict form).

    Raises
    ------
    ValueError
        Unknown option (the known ones are named) or bad value.
    """
    fields = {f.name for f in dataclasses.fields(RotationAblationSettings)}
    unknown = set(options) - fields
    if unknown:
        raise ValueError(f"unknown rotation options {sorted(unknown)}; expected some of "
                         f"{sorted(fields)}")
    return dataclasses.replace(RotationAblationSettings.preset(strategy), **options)


def research_settings(strategy, method=None, **options):
    """:class:`nrsfm.settings.Settings` whose rotation stage is a research strategy.

    Parameters
    ----------
    strategy : str
        One of :attr:`RotationAblationSettings.STRATEGIES`.
    method : str, optional
        The preset giving the other stages (default ``organic``'s measurement and shape
        settings); the result's ``method`` is the preset whose strategy and prior match,
        else ``"custom"``.
    **options
        Fields of :class:`RotationAblationSettings`.

    Returns
    -------
    nrsfm.settings.Settings
    """
    base = Settings.preset(method or "organic")
    return Settings(measurement=base.measurement, rotation=rotation_settings(strategy, **options),
                    shape=base.shape)
