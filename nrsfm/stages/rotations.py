"""Rotation stage (paper Sec. 3.1): triplets -> per-triplet rotations -> registration ->
filtering -> per-frame L1 single rotation averaging -> depth signs.

Conventions
-----------
* A triplet G (3K x 3) maps frame f's 2 x 3K block to ``M_f G = c_f R_f[:2]`` (a scaled
  orthographic camera).  Lifting it to SO(3) (:func:`rotations_from_triplets`) gives
  ``R_f`` when ``c_f > 0`` and ``diag(-1, -1, 1) R_f`` ("depth reversal" of frame f: the
  same image with the shape negated) when ``c_f < 0``; a triplet may also come out with
  the opposite handedness (``diag(1, 1, -1) R_f D``, D = diag(1, 1, -1)), which equals the
  depth reversal of every frame times a fixed rotation, so the per-frame flips absorb it.
* Registration (:func:`register_rotations`) solves Eq. 3 with one R_reg in SO(3) per
  triplet plus a per-frame choice of I or diag(-1, -1, 1).
* The final per-frame depth sign is chosen by motion smoothness (Dai's rule, see
  :func:`resolve_depth_signs`); ``sign_from_smoothness`` flags the frames it changed.

The K triplets (the paper says only "using Dai et al." for every k): the best one of the
search and K - 1 refined on temporal windows. W of numerical rank r < 3K: the stage runs in
the determined r-dimensional subspace of ``M_hat`` (:mod:`.rotation_select`).
:func:`estimate_rotations` runs ``organic`` and ``bmm``
(:class:`nrsfm.settings.RotationSettings`); research strategies (``family``: the family
combination after the average, the default before issue 18): :mod:`nrsfm.ablation`.
Measurements: ``docs/rotation_stage.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..geometry import average_rotations, procrustes_so3, project_to_so3, rotation_angle
from ..settings import RotationAblationSettings, RotationSettings
from .corrective import corrective_triplets, refine_triplet, triplet_cost
from .rotation_select import in_determined_subspace, lift_result

__all__ = ["FLIP", "MIRROR", "RotationResult", "estimate_rotations", "filter_rotations",
           "register_rotations", "register_triplets", "resolve_depth_signs",
           "rotations_from_triplet_set", "rotations_from_triplets", "triplets_on_subsets",
           "window_weights"]

FLIP = np.diag([-1.0, -1.0, 1.0])          # depth reversal of one frame (c_f < 0)
MIRROR = np.diag([1.0, 1.0, -1.0])         # handedness
#: a lifted frame is degenerate when |r1 x r2| is below this (parallel rows)
DEGENERATE_CROSS = 1e-8
#: ... or a row norm below this fraction of the largest camera scale
DEGENERATE_ROW = 1e-12
#: at least this many frames in a window triplet
MIN_WINDOW_FRAMES = 8


# --------------------------------------------------------------------------- lifting
def rotations_from_triplets(M_hat, G, handedness=1):
    """Per-triplet, per-frame rotations from ``M_f G^k``.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    G : (m, 3K, 3) or (3K, 3) ndarray
    handedness : {1, -1}
        -1 negates the third column of every 2 x 3 block before lifting.

    Returns
    -------
    R : (m, F, 3, 3) ndarray in SO(3)
        Rows scaled to unit length, ``r3 = r1 x r2``, projected onto SO(3). Never NaN: a
        frame where ``M_f G`` is degenerate (a zero row or parallel rows) gets the
        identity and ``valid`` False.
    coefficients : (m, F) ndarray
        ``|c_fk|``: RMS norm of the two rows of ``M_f G^k``.
    valid : (m, F) bool
    """
    G = np.asarray(G, float)
    single = G.ndim == 2
    if single:
        G = G[None]
    M = np.asarray(M_hat, float)
    F = M.shape[0] // 2
    B = np.einsum("ri,kij->krj", M, G).reshape(G.shape[0], F, 2, 3)
    if handedness == -1:
        B = B * np.array([1.0, 1.0, -1.0])
    norms = np.linalg.norm(B, axis=3)                             # (m, F, 2)
    coef = np.sqrt(0.5 * (norms ** 2).sum(axis=2))
    scale = np.max(coef, axis=1, keepdims=True)
    tiny = DEGENERATE_ROW * np.where(scale > 0, scale, 1.0)
    ok_rows = norms > tiny[..., None]
    U = B / np.where(ok_rows, norms, 1.0)[..., None]
    r3 = np.cross(U[:, :, 0], U[:, :, 1])
    valid = ok_rows.all(axis=2) & (np.linalg.norm(r3, axis=2) > DEGENERATE_CROSS)
    L = np.concatenate([U, r3[:, :, None]], axis=2)
    L = np.where(valid[..., None, None], L, np.eye(3))
    R = project_to_so3(L)
    coef = np.where(valid, coef, 0.0)
    if single:
        return R[0], coef[0], valid[0]
    return R, coef, valid


# --------------------------------------------------------------------------- registration
def _register_one(R_ref, R_k, w, max_iter=20):
    """Flip-aware registration of one triplet for one handedness: (R_reg, flips, cost)."""
    # Start from the third rows (a frame's depth reversal leaves them unchanged):
    # maximise sum_f w_f r3_ref . (R r3_k)  ->  N = sum_f w_f r3_ref r3_k'.
    N = np.einsum("f,fi,fj->ij", w, R_ref[:, 2], R_k[:, 2])
    R = procrustes_so3(N)
    flips = np.zeros(len(R_k), bool)
    for _ in range(max_iter):
        X = R_k @ R.T                                               # R_k R_reg'
        # flipping rows 1-2 of X changes trace(R_ref' X) by -2 (d1 + d2)
        d12 = np.einsum("fij,fij->f", R_ref[:, :2], X[:, :2])
        new_flips = d12 < 0
        S = np.where(new_flips[:, None, None], FLIP @ R_k, R_k)
        # refit: maximise sum_f w_f trace(R_ref' S R') = trace(R' N), N = sum w S' R_ref
        N = np.einsum("f,fki,fkj->ij", w, S, R_ref).T
        R_new = procrustes_so3(N)
        if np.array_equal(new_flips, flips) and np.allclose(R_new, R, atol=1e-12):
            flips, R = new_flips, R_new
            break
        flips, R = new_flips, R_new
    S = np.where(flips[:, None, None], FLIP @ R_k, R_k)
    cost = float(np.sum(w * np.sum((R_ref - S @ R.T) ** 2, axis=(1, 2))))
    return R, flips, cost


def register_rotations(R_ref, R_k, weights=None, handedness="both"):
    """Register one triplet's rotations onto the reference (Eq. 3, flip-aware).

    Minimises ``sum_f w_f || R_ref,f - s_f H(R_k,f) R_reg' ||_F^2`` over R_reg in SO(3),
    per-frame ``s_f`` in {I, diag(-1, -1, 1)} and, with ``handedness="both"``, the
    handedness ``H`` (identity, or ``R -> diag(1, 1, -1) R diag(1, 1, -1)``, the lift of
    the mirrored 2 x 3 blocks). Closed-form SO(3) Procrustes started from the third rows,
    then alternation between the flips and R_reg (converges in a few steps).

    Parameters
    ----------
    R_ref, R_k : (F, 3, 3) ndarray
    weights : (F,) ndarray, optional
        0 leaves a frame out of the fit (its flip is still chosen).
    handedness : {"both", "same"}

    Returns
    -------
    registered : (F, 3, 3) ndarray
        ``s_f H(R_k,f) R_reg'``.
    R_reg : (3, 3) ndarray
        In the sense of Eq. 3 (for the mirrored handedness, applied after the mirror).
    flips : (F,) bool
    mirrored : bool
    cost : float
    """
    R_ref = np.asarray(R_ref, float)
    R_k = np.asarray(R_k, float)
    w = np.ones(len(R_k)) if weights is None else np.asarray(weights, float)
    best = None
    options = [False, True] if handedness == "both" else [False]
    for mirrored in options:
        Rk = MIRROR @ R_k @ MIRROR if mirrored else R_k
        R, flips, cost = _register_one(R_ref, Rk, w)
        if best is None or cost < best[3] - 1e-12:
            best = (R, flips, mirrored, cost, Rk)
    R, flips, mirrored, cost, Rk = best
    S = np.where(flips[:, None, None], FLIP @ Rk, Rk)
    return S @ R.T, R, flips, mirrored, cost


# --------------------------------------------------------------------------- filtering
def filter_rotations(registered, reference, delta=0.05, metric="angle", valid=None):
    """Keep the samples within ``delta`` of the reference (paper: delta = 0.05).

    Parameters
    ----------
    registered : (m, F, 3, 3) ndarray
    reference : (F, 3, 3) ndarray
    delta : float
    metric : {"angle", "chordal"}
        ``angle``: geodesic angle in radians, the metric the L1 average minimises (0.05 rad
        = 2.9 degrees). ``chordal``: ``||R - R_ref||_F`` (= 2 sqrt(2) sin(angle / 2),
        so 0.05 is 2.0 degrees).
    valid : (m, F) bool, optional
        Samples already known to be unusable.

    Returns
    -------
    kept : (m, F) bool
    distance : (m, F) ndarray
    """
    if metric == "angle":
        dist = rotation_angle(registered, reference[None])
    elif metric == "chordal":
        dist = np.linalg.norm(registered - reference[None], axis=(-2, -1))
    else:
        raise ValueError(f"unknown metric {metric!r}")
    kept = dist <= delta
    if valid is not None:
        kept &= valid
    return kept, dist


# --------------------------------------------------------------------------- depth sign
def resolve_depth_signs(R):
    """Per-frame depth sign by motion smoothness (Dai's rule).

    Frame f is replaced by ``diag(-1, -1, 1) R_f`` when that is closer to the (resolved)
    frame f - 1, i.e. when the two cameras' rows disagree by more than 90 degrees on
    average (``r1.r1' + r2.r2' < 0``).

    Returns
    -------
    R : (F, 3, 3) ndarray
    flipped : (F,) bool, frames changed
    """
    R = np.array(R, float, copy=True)
    F = len(R)
    flipped = np.zeros(F, bool)
    # d_f = agreement of frame f with frame f-1 (unresolved); resolving sequentially only
    # needs the parity of the flips so far.
    d = np.einsum("fij,fij->f", R[1:, :2], R[:-1, :2])
    parity = np.cumsum(np.concatenate([[0], (d < 0).astype(int)])) % 2
    flipped = parity.astype(bool)
    R[flipped] = FLIP @ R[flipped]
    return R, flipped


# --------------------------------------------------------------------------- windows
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
        G, inf = refine_triplet(G0, M_hat, weights=w, method=method)
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


def sample_weights(coef, valid, settings):
    """Step 4a: the usable samples (validly lifted) and their weights in the average (1)."""
    usable = valid.copy()
    return usable, np.where(usable, 1.0, 0.0)


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
                               weigh=sample_weights, average=average_samples, refit=None,
                               combine=None, metric="angle"):
    """Steps 2-7 for given triplets G (m, 3K, 3): lift, register, filter, average,
    (refit, combine), depth signs. ``weigh``, ``average``, ``refit``, ``combine`` and
    ``metric`` are the replaceable steps (:mod:`nrsfm.ablation` passes its variants)."""
    clock = _Clock(timings)
    info["triplet_costs"] = np.array([triplet_cost(g, M) for g in G])
    per_triplet, coef, valid = rotations_from_triplets(M, G)
    clock.lap("lift")
    registered, registration, reg_info = register_triplets(per_triplet, valid)
    info.update(reg_info)
    clock.lap("registration")
    usable, weights = weigh(coef, valid, settings)
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
    settings : nrsfm.settings.RotationSettings, optional
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
        Research settings (run them with :func:`nrsfm.ablation.estimate_rotations_ablation`),
        or M_hat not (2F, 3K).
    """
    settings = RotationSettings() if settings is None else settings
    if isinstance(settings, RotationAblationSettings) or \
            not isinstance(settings, RotationSettings):
        raise ValueError("estimate_rotations runs RotationSettings (organic, bmm); research "
                         "settings run through nrsfm.ablation.estimate_rotations_ablation")
    return run_rotation_stage(M_hat, K, settings, seed, progress, production_triplets)


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
