"""The rotation stage as one run: its settings, the triplets (the best one of the search
and K - 1 refined on temporal windows), the steps on them, and its result.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import ClassVar, Optional

import numpy as np

from ...geometry import average_rotations
from ...validation import (check_choice, check_flag, check_fraction, check_integer,
                           check_positive)
from ..corrective import corrective_triplets, refine_triplet, triplet_cost
from .lifting import filter_rotations, register_rotations, resolve_depth_signs, \
    rotations_from_triplets
from .subspace import in_determined_subspace, lift_result

__all__ = ["MIN_WINDOW_FRAMES", "RotationResult", "RotationSettings", "WINDOW_LM",
           "estimate_rotations", "register_triplets", "rotations_from_triplet_set",
           "run_rotation_stage", "triplets_on_subsets", "window_weights"]

#: at least this many frames in a window triplet
MIN_WINDOW_FRAMES = 8
#: the window refinements (:func:`triplets_on_subsets`) start from the best triplet, next
#: to their own minimum: initial damping 1e-6 of max diag(J'J) (the cold starts' 1e-3 took
#: 190 iterations on pickup's 11 windows; 1e-6: 120), J'J kept after steps below 1e-3 |G|
#: and the relative decrease tolerance 1e-11 instead of 1e-10 (each window's rotations
#: within 4e-7 of its exact minimum instead of 2e-6; ``docs/rotation_stage.md`` section 8)
WINDOW_LM = dict(lam0=1e-6, reuse=1e-3, tol=1e-11)


@dataclass(frozen=True)
class RotationSettings:
    """Rotation stage of the ``organic`` and ``bmm`` methods.

    Attributes
    ----------
    strategy : {"organic", "bmm"}
        ``organic``: the best triplet plus K - 1 triplets refined on temporal windows,
        registered, filtered, L1-averaged (the paper's averaging). ``bmm``: the best
        triplet only (Dai et al.).
    n_triplets : int or None
        Triplets averaged (default K).
    window : float
        Window length of the K - 1 window triplets, a fraction of F.
    delta : float
        Filter threshold (rad, geodesic angle; paper: 0.05).
    filter_against : {"average", "reference"} or None
        Filter the samples against their L1 average, the reference triplet (paper), or not.
    determined : bool
        W of numerical rank r < 3K (singular values below 1e-6 s_1): solve the triplets in
        the determined r-dimensional subspace of the motion factor (:mod:`.subspace`);
        False: search all 3K rows of G.
    max_iter, eps : int, float
        Weiszfeld iterations and step tolerance of the L1 average (Alg. 1).
    hits, max_starts : int
        Stopping rule of the triplet search (:func:`nrsfm.stages.corrective.search_triplet`).
    sdp_solver : {"admm", "cvxpy"}
        Solver of the relaxation that gives the first starts.
    refine : {"lm", "minpack", "lbfgs"}
        Refinement of the triplets.
    """

    STRATEGIES: ClassVar[tuple] = ("organic", "bmm")
    FILTERS: ClassVar[tuple] = ("average", "reference", None)
    SDP_SOLVERS: ClassVar[tuple] = ("admm", "cvxpy")
    REFINES: ClassVar[tuple] = ("lm", "minpack", "lbfgs")

    strategy: str = "organic"
    n_triplets: Optional[int] = None
    window: float = 0.9
    delta: float = 0.05
    filter_against: Optional[str] = "average"
    determined: bool = True
    max_iter: int = 50
    eps: float = 1e-3
    hits: int = 2
    max_starts: int = 40
    sdp_solver: str = "admm"
    refine: str = "lm"

    def __post_init__(self):
        check_choice("rotation strategy", self.strategy, self.STRATEGIES)
        if self.n_triplets is not None:
            check_integer(self.n_triplets, "n_triplets", minimum=1)
        check_fraction("window", self.window)
        check_positive("delta", self.delta)
        check_choice("filter_against", self.filter_against, self.FILTERS)
        check_flag("determined", self.determined)
        check_integer(self.max_iter, "max_iter", minimum=1)
        check_positive("eps", self.eps, strict=False)
        check_integer(self.hits, "hits", minimum=1)
        check_integer(self.max_starts, "max_starts", minimum=1)
        check_choice("sdp_solver", self.sdp_solver, self.SDP_SOLVERS)
        check_choice("refine", self.refine, self.REFINES)

    @classmethod
    def preset(cls, strategy="organic"):
        """The settings of a strategy (chosen by the measurements in
        ``docs/rotation_stage.md``)."""
        check_choice("rotation strategy", strategy, cls.STRATEGIES)
        if strategy == "bmm":
            return cls(strategy="bmm", window=0.5, filter_against="reference")
        return cls(strategy=strategy)

    def estimate(self, M_hat, K, seed=0, progress=None):
        """Run the rotation stage with these settings (:func:`estimate_rotations`)."""
        return run_rotation_stage(M_hat, K, self, seed, progress, production_triplets)

def window_weights(F, n_windows, window):
    """Frame weights of ``n_windows`` contiguous temporal windows of ``window * F`` frames
    (at least :data:`MIN_WINDOW_FRAMES`), starts spread evenly from the first to the last
    possible frame.

    Returns
    -------
    weights : list of (F,) ndarrays (1 inside the window)
    spans : list of (start, stop)
    """
    L = int(min(F, max(MIN_WINDOW_FRAMES, round(window * F))))
    starts = np.round(np.linspace(0, F - L, n_windows)).astype(int) \
        if n_windows > 1 else np.array([0])
    weights, spans = [], []
    for s in starts[:n_windows]:
        w = np.zeros(F)
        w[s:s + L] = 1.0
        weights.append(w)
        spans.append((s, s + L))
    return weights, spans


def triplets_on_subsets(M_hat, G0, weights, method="lm"):
    """Triplets refined from ``G0`` on weighted subsets of the frames.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    G0 : (3K, 3) ndarray
    weights : list of (F,) ndarrays
        Frame weights of each subset (e.g. :func:`window_weights`).

    Returns
    -------
    G : (n, 3K, 3) ndarray
    costs : (n,) ndarray, Dai's cost per frame on each subset
    """
    Gs, costs = [], []
    for w in weights:
        G, inf = refine_triplet(G0, M_hat, weights=w, method=method,
                                **(WINDOW_LM if method == "lm" else {}))
        Gs.append(G)
        costs.append(inf["cost"] / w.sum())
    return np.stack(Gs), np.array(costs)


# --------------------------------------------------------------------------- result
@dataclass
class RotationResult:
    """Output of :func:`estimate_rotations` (every intermediate of the rotation stage).

    Attributes
    ----------
    rotations : (F, 3, 3) ndarray
        Final per-frame rotations in SO(3) (depth sign resolved by smoothness).
    G : (m, 3K, 3) ndarray
        The triplets G^k (m = K for the averaging strategies, 1 for ``bmm``).
    per_triplet : (m, F, 3, 3) ndarray
        Lifted rotations R^k before registration.
    coefficients : (m, F) ndarray
        ``|c_fk|``, RMS norm of the rows of ``M_f G^k``.
    registration : (m, 3, 3) ndarray
        R_reg^k (identity for k = 0).
    registered : (m, F, 3, 3) ndarray
        After registration and flip handling.
    kept : (m, F) bool, the samples that passed the filter
    averaged : (F, 3, 3) ndarray
        The L1 average (before the smoothness sign rule).
    sign_from_smoothness : (F,) bool
        Frames whose depth sign was changed by the motion-smoothness rule.
    strategy, params, timings : str, dict, dict
    info : dict
        Triplet costs, their starts, flips, handedness, filter distances, ...
    """

    rotations: np.ndarray
    G: np.ndarray
    per_triplet: np.ndarray
    coefficients: np.ndarray
    registration: np.ndarray
    registered: np.ndarray
    kept: np.ndarray
    averaged: np.ndarray
    sign_from_smoothness: np.ndarray
    strategy: str
    params: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    @property
    def n_triplets(self):
        return self.G.shape[0]

    def candidates(self):
        """Rotation sets the shape stage may use: the stage's own result, then the best
        triplet's (:mod:`nrsfm.stages.selection` keeps the one whose shape has the lower
        shape objective).

        The averaged rotations (paper Sec. 3.1) are closer to the truth on the benchmark,
        but the shapes they give are not always better (stretch: e3d 1.07 x that of the
        best single triplet's rotations, ground-truth rotations 1.02 x).

        Returns
        -------
        list of (name, (F, 3, 3) ndarray)
            One entry when the stage used a single triplet.
        """
        out = [(self.strategy, self.rotations)]
        if self.G.shape[0] > 1:
            single, _ = resolve_depth_signs(self.per_triplet[0])
            out.append(("single_triplet", single))
        return out


# --------------------------------------------------------------------------- entry point
def check_motion(M_hat, K):
    """M_hat as a float (2F, 3K) array; ValueError naming the shape otherwise."""
    M = np.asarray(M_hat, float)
    if M.ndim != 2 or M.shape[1] != 3 * K or M.shape[0] % 2:
        raise ValueError(f"M_hat must have shape (2F, 3K) = (2F, {3 * K}); got {M.shape}")
    return M


def _say(progress):
    return progress if callable(progress) else (lambda msg: None)


def record_search(cor, info, say):
    """Step 1a: record the triplet search (a CorrectiveResult) into ``info``."""
    info.update(corrective_costs=cor.costs, corrective_starts=cor.info["starts"],
                corrective_search=cor.info.get("search"),
                sdp={k: cor.info[k] for k in ("penalized", "nuclear") if k in cor.info},
                corrective_timings=cor.timings)
    say(f"best corrective triplet: Dai cost {cor.costs[0]:.4g} "
        f"(start {cor.info['starts'][0]})")
    return cor


def production_triplets(M, K, settings, seed, info, say):
    """Step 1: the best triplet, and for ``organic`` K - 1 more on temporal windows."""
    cor = corrective_triplets(M, K, seed=seed, sdp_solver=settings.sdp_solver,
                              refine=settings.refine, hits=settings.hits,
                              max_starts=settings.max_starts)
    G_best = record_search(cor, info, say).G[0]
    m = int(settings.n_triplets or K)
    if settings.strategy == "bmm" or m == 1:
        return G_best[None]
    weights, spans = window_weights(M.shape[0] // 2, m - 1, settings.window)
    Gw, wcost = triplets_on_subsets(M, G_best, weights, method=settings.refine)
    info.update(window_spans=np.array(spans), window_costs=wcost)
    return np.concatenate([G_best[None], Gw])


def register_triplets(per_triplet, valid):
    """Step 3: register every triplet's rotations onto the first one's (Eq. 3).

    Returns
    -------
    registered : (m, F, 3, 3) ndarray
    registration : (m, 3, 3) ndarray
    info : dict (flips, mirrored, registration_cost)
    """
    m, F = per_triplet.shape[:2]
    registered = np.empty_like(per_triplet)
    registration = np.tile(np.eye(3), (m, 1, 1))
    flips = np.zeros((m, F), bool)
    mirrored = np.zeros(m, bool)
    reg_cost = np.zeros(m)
    registered[0] = per_triplet[0]
    ref_w = valid[0].astype(float)
    for k in range(1, m):
        registered[k], registration[k], flips[k], mirrored[k], reg_cost[k] = \
            register_rotations(per_triplet[0], per_triplet[k], weights=ref_w * valid[k])
    return registered, registration, dict(flips=flips, mirrored=mirrored,
                                          registration_cost=reg_cost)


def filter_samples(registered, usable, weights, settings, metric="angle"):
    """Step 4b: keep the samples within ``settings.delta`` of the reference triplet's
    rotations or of the L1 average of all samples (``settings.filter_against``); a frame
    with no sample left falls back on the reference."""
    if settings.filter_against == "reference":
        kept, dist = filter_rotations(registered, registered[0], settings.delta, metric,
                                      usable)
    elif settings.filter_against == "average":
        pre = average_rotations(registered, usable, weights, settings.max_iter, settings.eps)
        kept, dist = filter_rotations(registered, pre, settings.delta, metric, usable)
    else:
        kept, dist = usable.copy(), np.zeros(usable.shape)
    kept[0] |= ~kept.any(axis=0) & usable[0]
    return kept, dist


def average_samples(registered, kept, weights, settings):
    """Step 5: per-frame weighted L1 average (Alg. 1) of the kept samples."""
    return average_rotations(registered, kept, np.where(weights > 0, weights, 1.0),
                             settings.max_iter, settings.eps, return_info=True)


class _Clock:
    """Seconds per step, recorded into ``timings``."""

    def __init__(self, timings):
        self.timings, self.t0 = timings, time.perf_counter()

    def lap(self, name):
        t = time.perf_counter()
        self.timings[name] = t - self.t0
        self.t0 = t


def rotations_from_triplet_set(M, K, G, settings, *, info, timings, say, seed=0,
                               weigh=None, average=average_samples, refit=None,
                               combine=None, metric="angle"):
    """Steps 2-7 for given triplets G (m, 3K, 3): lift, register, filter, average,
    (refit, combine), depth signs. ``weigh(coefficients, valid) -> (usable, weights)``
    (default: the validly lifted samples, weight 1), ``average``, ``refit``, ``combine``
    and ``metric`` are the replaceable steps (:mod:`nrsfm.research` passes its variants)."""
    clock = _Clock(timings)
    info["triplet_costs"] = np.array([triplet_cost(g, M) for g in G])
    per_triplet, coef, valid = rotations_from_triplets(M, G)
    clock.lap("lift")
    registered, registration, reg_info = register_triplets(per_triplet, valid)
    info.update(reg_info)
    clock.lap("registration")
    if weigh is None:                                      # step 4a: usable samples
        usable, weights = valid.copy(), valid.astype(float)
    else:
        usable, weights = weigh(coef, valid)
    kept, dist = filter_samples(registered, usable, weights, settings, metric)
    info.update(filter_distance=dist)
    clock.lap("filtering")
    averaged, avg_info = average(registered, kept, weights, settings)
    if np.any(avg_info["empty"]):                          # frames with no usable sample
        averaged = _fill_empty(averaged, avg_info["empty"])
    info.update(averaging_iterations=avg_info["iterations"], empty_frames=avg_info["empty"])
    clock.lap("averaging")
    final = averaged
    if refit is not None and len(G) > 1:
        final = refit(M, G, averaged, info)
        clock.lap("refit")
    if combine is not None and K > 1:
        final = combine(M, K, final, settings, info)
        clock.lap("combine")
    rotations, flipped = resolve_depth_signs(final)
    say(f"rotations: {len(G)} triplet(s), {kept.sum()} of {kept.size} samples kept, "
        f"{int(flipped.sum())} frames' depth sign from smoothness")
    params = dict(vars(settings), seed=seed, K=K, n_triplets=len(G))
    return RotationResult(rotations=rotations, G=G, per_triplet=per_triplet,
                          coefficients=coef, registration=registration,
                          registered=registered, kept=kept, averaged=averaged,
                          sign_from_smoothness=flipped, strategy=settings.strategy,
                          params=params, timings=timings, info=info)


def estimate_rotations(M_hat, K, settings=None, seed=0, progress=None):
    """Camera rotations from the rank-3K motion factor (``organic`` or ``bmm``).

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
        The motion factor of the measurement stage (:mod:`nrsfm.stages.measurement`).
    K : int
    settings : RotationSettings, optional
        Default ``RotationSettings()`` (``organic``): the best triplet (the search of
        :func:`nrsfm.stages.corrective.corrective_triplets`) plus K - 1 triplets refined
        on temporal windows of 90% of the frames; register (flip-aware Eq. 3), filter at
        delta = 0.05 rad from the L1 average of the samples, per-frame L1 average
        (Alg. 1); depth signs by smoothness. ``determined``: W of numerical rank
        r < 3K is solved in the determined subspace with ``effective_K(r, K)`` triplets
        (``info["determined_rank"]``, ``info["effective_K"]``).
        ``RotationSettings.preset("bmm")``: the best triplet only (Dai et al.).
    seed : int
        Seed of the random refinement starts (deterministic per seed).
    progress : callable(str) or None

    Returns
    -------
    RotationResult

    Raises
    ------
    ValueError
        Settings that are not a RotationSettings, or M_hat not (2F, 3K).

    Notes
    -----
    The settings run themselves (``settings.estimate``): the research strategies of
    :mod:`nrsfm.research` derive from :class:`RotationSettings` and run here too.
    """
    settings = RotationSettings() if settings is None else settings
    if not isinstance(settings, RotationSettings):
        raise ValueError(f"settings must be a RotationSettings; got {settings!r}")
    return settings.estimate(M_hat, K, seed, progress)


def run_rotation_stage(M_hat, K, settings, seed, progress, find_triplets, **steps):
    """The stage's common frame: work in the determined subspace of M_hat (rank < 3K
    handled), find the triplets with ``find_triplets(M, k, settings, seed, info, say)``,
    then rotations, registration, filtering and averaging
    (:func:`rotations_from_triplet_set` with the optional ``steps``), lifted back."""
    say, timings = _say(progress), {}
    M, k, sub, info = in_determined_subspace(check_motion(M_hat, K), K, settings.determined,
                                             say)
    t0 = time.perf_counter()
    G = find_triplets(M, k, settings, seed, info, say)
    timings["triplets"] = time.perf_counter() - t0
    return lift_result(rotations_from_triplet_set(M, k, G, settings, info=info,
                                                  timings=timings, say=say, seed=seed,
                                                  **steps), sub, K)


def _fill_empty(R, empty):
    """Give frames without any sample the rotation of the nearest frame that has one."""
    R = R.copy()
    good = np.flatnonzero(~empty)
    if len(good) == 0:
        return np.tile(np.eye(3), (len(R), 1, 1))
    for f in np.flatnonzero(empty):
        R[f] = R[good[np.argmin(np.abs(good - f))]]
    return R
