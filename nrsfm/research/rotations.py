"""Research rotation variants that no method uses by default, kept runnable for the
ablations.

The production path (:mod:`nrsfm.stages`, which never imports this package) runs the ``organic`` and ``bmm`` rotation
strategies with the triplet search; this module holds what the measurements in
``docs/rotation_stage.md`` compared them with, built from the same stage functions:

* rotation strategies ``family`` (:mod:`nrsfm.research.family`), ``literal``,
  ``multistart``, ``windows``, ``bootstrap`` and the step
  variants (chordal filter metric, camera-scale gate and weights, bootstrap or random frame
  subsets, chordal L2 average, refit onto one triplet):
  :func:`estimate_rotations_ablation` with a
  :class:`nrsfm.research.settings.RotationAblationSettings`
  (``reconstruct(W, K, settings=research_settings("literal"))`` runs it);
* their settings, :class:`RotationAblationSettings` (the production
  :class:`~nrsfm.stages.rotations.RotationSettings` plus the research fields), the dict
  form :func:`rotation_settings` and :func:`research_settings` for a whole run;
* triplet starts other than the search and the rotation-fit helpers: :mod:`.triplets`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar, Optional

import numpy as np

from ..settings import Settings
from ..stages.corrective import triplet_cost
from ..stages.rotations import (RotationSettings, rotations_from_triplets,
                                run_rotation_stage, triplets_on_subsets, window_weights)
from ..stages.rotations.stage import MIN_WINDOW_FRAMES, average_samples, record_search
from ..validation import check_choice, check_integer, check_positive
from .family import combine_triplets
from .triplets import STARTS, chordal_mean, corrective_triplets_from, triplet_from_rotations

__all__ = ["STRATEGIES", "RotationAblationSettings", "estimate_rotations_ablation",
           "research_settings", "rotation_settings", "subset_weights"]

#: strategy name -> what it does
STRATEGIES = {
    "organic": "default: the best triplet plus K-1 triplets refined on temporal windows "
               "of 90% of the frames (leave-10%-out), registered, filtered at delta "
               "against their L1 average, L1-averaged (the paper's averaging)",
    "family": "organic, then the K triplets of the family consistent with the average, "
              "combined per frame by signal-to-noise weights (maximum-ratio combination; "
              "the default before issue 18)",
    "bmm": "Dai et al.: the best single triplet only",
    "literal": "the paper read literally: the K column triplets of the relaxed Gram "
               "matrix, each refined; register to the lowest-cost one; filter at delta; "
               "L1 average",
    "multistart": "the K lowest-cost refined minima from the multistart",
    "windows": "the best triplet plus K-1 triplets on half-length windows, plain L1 "
               "average (no filter): lowest e_R, worse e3d",
    "bootstrap": "as organic, with bootstrap resamples of the frames instead of windows: "
                 "e_R within 5% of the single triplet, e3d tied with the default",
}


# --------------------------------------------------------------------------- rotations
def estimate_rotations_ablation(M_hat, K, settings=None, seed=0, progress=None):
    """The rotation stage with any strategy and step variant.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    K : int
    settings : RotationAblationSettings or RotationSettings, optional
        Default ``RotationAblationSettings.preset("organic")``; production settings run
        with the research fields at their defaults (the production behaviour).
    seed : int
    progress : callable(str) or None

    Returns
    -------
    nrsfm.stages.rotations.RotationResult
    """
    if settings is None:
        settings = RotationAblationSettings.preset("organic")
    elif not isinstance(settings, RotationAblationSettings):
        if not isinstance(settings, RotationSettings):
            raise ValueError(f"settings must be RotationSettings; got {settings!r}")
        settings = RotationAblationSettings(**dataclasses.asdict(settings))
    return run_rotation_stage(
        M_hat, K, settings, seed, progress, _ablation_triplets,
        weigh=lambda coef, valid: _gated_weights(coef, valid, settings), average=_average, metric=settings.filter_metric,
        refit=_refit if settings.refit else None,
        combine=combine_triplets if settings.combine == "family" else None)


def _ablation_triplets(M, K, s, seed, info, say):
    """The m triplets of a strategy (m = n_triplets or K)."""
    m = int(s.n_triplets or K)
    starts = "columns" if s.strategy == "literal" else s.starts
    cor = corrective_triplets_from(
        M, K, starts=starts, seed=seed, n_random=s.n_random,
        n_full=max(s.n_full, m if s.strategy == "multistart" else 0),
        screen_frames=s.screen_frames, screen_iter=s.screen_iter, sdp_solver=s.sdp_solver,
        refine=s.refine, lam=s.lam, gram=s.gram, hits=s.hits, max_starts=s.max_starts)
    G_best = record_search(cor, info, say).G[0]
    if s.strategy == "bmm" or (m == 1 and s.strategy not in ("literal", "multistart")):
        return G_best[None]
    if s.strategy == "literal":
        return cor.G[:m]                                   # sorted by cost: reference first
    if s.strategy == "multistart":
        return _distinct(cor.G, cor.costs, m)
    weights, spans = subset_weights(M.shape[0] // 2, m - 1, s.window, s.subsets, seed)
    Gw, wcost = triplets_on_subsets(M, G_best, weights, method=s.refine)
    info.update(window_spans=np.array(spans), window_costs=wcost)
    return np.concatenate([G_best[None], Gw])


def subset_weights(F, n, window, subsets="windows", seed=0):
    """Frame weights of n subsets: temporal ``windows``
    (:func:`nrsfm.stages.rotations.window_weights`), ``bootstrap`` resamples (weights =
    counts of F draws with replacement) or ``random`` draws of ``window * F`` frames
    without replacement. Returns (weights, spans); spans are (-1, -1) for random subsets."""
    if subsets == "windows":
        return window_weights(F, n, window)
    L = int(min(F, max(MIN_WINDOW_FRAMES, round(window * F))))
    rng = np.random.default_rng(seed)
    weights = []
    for _ in range(n):
        w = np.zeros(F)
        if subsets == "bootstrap":
            w = np.bincount(rng.integers(0, F, F), minlength=F).astype(float)
        elif subsets == "random":
            w[rng.choice(F, L, replace=False)] = 1.0
        else:
            raise ValueError(f"unknown subsets {subsets!r}")
        weights.append(w)
    return weights, [(-1, -1)] * n


def _gated_weights(coef, valid, s):
    """Samples gated by camera scale, ``|c_fk| >= coef_gate * median_f |c_fk|``, and
    weighted by ``|c_fk| / median_f |c_fk|`` with ``coef_weights``."""
    if s.coef_gate == 0 and not s.coef_weights:
        return valid.copy(), valid.astype(float)
    med = np.array([np.median(c[v]) if v.any() else 0.0 for c, v in zip(coef, valid)])
    rel = coef / np.where(med > 0, med, 1.0)[:, None]     # |c_fk| / median_f |c_fk|
    rel = np.where(valid & np.isfinite(rel), rel, 0.0)
    usable = valid & (rel >= s.coef_gate)
    usable[0] |= valid[0]                                  # the reference always counts
    return usable, np.where(usable, rel if s.coef_weights else 1.0, 0.0)


def _average(registered, kept, weights, s):
    """L1 average (Alg. 1) or the chordal L2 mean."""
    if s.average == "chordal":
        F = registered.shape[1]
        return chordal_mean(registered, kept), dict(iterations=np.zeros(F, int),
                                                    empty=~kept.any(axis=0))
    return average_samples(registered, kept, weights, s)


def _refit(M, G, averaged, info):
    """Replace the average by the rotations of the single triplet that fits it best."""
    G_fit, _ = triplet_from_rotations(M, averaged, G[0])
    R_fit, _, ok = rotations_from_triplets(M, G_fit)
    info.update(G_refit=G_fit, refit_cost=triplet_cost(G_fit, M))
    return np.where(ok[:, None, None], R_fit, averaged)


def _distinct(G, costs, m, rtol=1e-4):
    """The m lowest-cost triplets whose costs differ (distinct minima), padded with the best."""
    out, seen = [], []
    for g, c in zip(G, costs):
        if all(abs(c - s) > rtol * max(abs(s), 1e-12) for s in seen):
            out.append(g)
            seen.append(c)
        if len(out) == m:
            break
    while len(out) < m:
        out.append(G[0])
    return np.stack(out)


# --------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class RotationAblationSettings(RotationSettings):
    """The rotation stage with the research variants no method uses by default
    (run by :func:`estimate_rotations_ablation`).

    Attributes
    ----------
    strategy : {"organic", "family", "bmm", "literal", "multistart", "windows",
                "bootstrap"}
        See :data:`STRATEGIES`.
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
        Starts of the triplet refinement (:func:`nrsfm.research.triplets.corrective_triplets_from`).
    lam : float
        Penalty of :func:`nrsfm.stages.relaxation.penalized_gram` (non-search starts).
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
        check_choice("starts", self.starts, STARTS)
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
        (:func:`estimate_rotations_ablation`)."""
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
