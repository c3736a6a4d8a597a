"""The rotation stage as one run: its settings, the K triplets (the best one of the search
and K - 1 refined on temporal windows), the steps on them, and its result.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ...geometry import average_rotations
from ...validation import check_fraction, check_integer, check_positive
from ..corrective import TripletSearch, refine_triplet, search_triplet, triplet_cost
from .lifting import filter_rotations, register_rotations, resolve_depth_signs
from .lifting import rotations_from_triplets
from .subspace import determined_subspace, effective_K, lift_triplets

__all__ = ["RotationResult", "RotationSettings", "estimate_rotations", "window_weights"]

#: at least this many frames in a window triplet
MIN_WINDOW_FRAMES = 8
#: the window refinements start from the best triplet, next to their own minimum: initial
#: damping 1e-6 of max diag(J'J), J'J kept after steps below 1e-3 |G|, relative decrease
#: tolerance 1e-11 (each window's rotations within 4e-7 of its exact minimum)
WINDOW_LM = dict(lam0=1e-6, reuse=1e-3, tol=1e-11)


@dataclass(frozen=True)
class RotationSettings:
    """Rotation stage settings (paper Sec. 3.1); a value out of range is a ValueError.

    Attributes
    ----------
    window : float
        Length of the K - 1 window triplets' temporal windows, a fraction of F.
    delta : float
        Filter threshold (rad, geodesic angle from the samples' L1 average; paper: 0.05).
    max_iter, eps : int, float
        Weiszfeld iterations and step tolerance of the L1 average (Alg. 1).
    hits, max_starts : int
        The triplet search stops once its lowest cost has been reached by ``hits`` starts,
        or after ``max_starts`` (:func:`nrsfm.stages.corrective.search_triplet`).
    """

    window: float = 0.9
    delta: float = 0.05
    max_iter: int = 50
    eps: float = 1e-3
    hits: int = 2
    max_starts: int = 40

    def __post_init__(self):
        check_fraction("window", self.window)
        check_positive("delta", self.delta)
        check_integer(self.max_iter, "max_iter", minimum=1)
        check_positive("eps", self.eps, strict=False)
        check_integer(self.hits, "hits", minimum=1)
        check_integer(self.max_starts, "max_starts", minimum=1)


@dataclass
class RotationResult:
    """Output of :func:`estimate_rotations`: every intermediate of the rotation stage.

    ``m`` is the number of triplets: K for the averaged rotations, 1 for ``single=True``
    (BMM), :attr:`effective_K` where W has numerical rank below 3K.

    Attributes
    ----------
    rotations : (F, 3, 3) ndarray
        Final per-frame rotations in SO(3) (depth sign resolved by smoothness).
    G, triplet_costs : (m, 3K, 3), (m,) ndarray
        The triplets G^k (the best of the search, then the window triplets) and Dai's cost
        of each on all frames.
    search : TripletSearch
        The search that found ``G[0]``.
    window_spans : (m - 1, 2) int ndarray
        First and past-the-last frame of each window triplet's window.
    per_triplet, registered : (m, F, 3, 3) ndarray
        The rotations R^k lifted from each triplet, and after registration (Eq. 3).
    coefficients : (m, F) ndarray
        ``|c_fk|``, the RMS norm of the rows of ``M_f G^k``.
    registration, flips, mirrored : (m, 3, 3), (m, F) bool, (m,) bool ndarray
        R_reg^k (identity for k = 0), the frames depth-reversed by the registration, the
        triplets of the opposite handedness.
    filter_distance, kept : (m, F) ndarray, (m, F) bool ndarray
        Geodesic angle of each sample from the samples' L1 average; the samples within
        ``delta`` of it (at least the first triplet's).
    averaged, averaging_iterations : (F, 3, 3), (F,) int ndarray
        The per-frame L1 average of the kept samples (Alg. 1) and its Weiszfeld iterations.
    sign_from_smoothness : (F,) bool ndarray
        Frames whose depth sign the motion-smoothness rule changed.
    determined_rank, effective_K : int
        The numerical rank r of the motion factor; the triplets its determined subspace
        holds, ``min(K, max(1, r // 3))``.
    timings : dict
        Seconds per step.
    """

    rotations: np.ndarray
    G: np.ndarray
    triplet_costs: np.ndarray
    search: TripletSearch
    window_spans: np.ndarray
    per_triplet: np.ndarray
    coefficients: np.ndarray
    registration: np.ndarray
    flips: np.ndarray
    mirrored: np.ndarray
    registered: np.ndarray
    filter_distance: np.ndarray
    kept: np.ndarray
    averaged: np.ndarray
    averaging_iterations: np.ndarray
    sign_from_smoothness: np.ndarray
    determined_rank: int
    effective_K: int
    timings: dict = field(default_factory=dict)

    @property
    def n_triplets(self):
        return self.G.shape[0]


def window_weights(F, n_windows, window):
    """(weights, spans): the (F,) 0/1 weights and (start, stop) of ``n_windows`` temporal
    windows of ``window * F`` frames (at least :data:`MIN_WINDOW_FRAMES`), spread evenly."""
    L = int(min(F, max(MIN_WINDOW_FRAMES, round(window * F))))
    starts = np.round(np.linspace(0, F - L, n_windows)).astype(int) if n_windows > 1 else [0]
    spans = [(s, s + L) for s in starts[:n_windows]]
    return [(np.arange(F) >= s) & (np.arange(F) < e) for s, e in spans], spans


def register_triplets(per_triplet, valid):
    """Every triplet's rotations registered onto the first one's (Eq. 3): registered
    (m, F, 3, 3), registration (m, 3, 3), flips (m, F), mirrored (m,)."""
    m, F = per_triplet.shape[:2]
    registered, registration = per_triplet.copy(), np.tile(np.eye(3), (m, 1, 1))
    flips, mirrored = np.zeros((m, F), bool), np.zeros(m, bool)
    for k in range(1, m):
        w = valid[0] * valid[k].astype(float)
        out = register_rotations(per_triplet[0], per_triplet[k], weights=w)
        registered[k], registration[k], flips[k], mirrored[k] = out[:4]
    return registered, registration, flips, mirrored


def _fill_empty(R, empty):
    """Give frames without any sample the rotation of the nearest frame that has one."""
    R = R.copy()
    good = np.flatnonzero(~empty)
    if len(good) == 0:
        return np.tile(np.eye(3), (len(R), 1, 1))
    for f in np.flatnonzero(empty):
        R[f] = R[good[np.argmin(np.abs(good - f))]]
    return R


def estimate_rotations(M_hat, K, settings=None, *, single=False, seed=0, progress=None):
    """Camera rotations from the rank-3K motion factor (paper Sec. 3.1).

    1. The best corrective triplet of the search and K - 1 more refined from it on temporal
       windows (``single``: the best one only, Dai et al.'s BMM); 2. each lifted to one
       rotation per frame, ``M_f G^k = c_fk R_f^k[:2]``; 3. registered onto the first's
       (Eq. 3); 4. the samples within ``delta`` of their L1 average kept; 5. their
       per-frame L1 average (Alg. 1); 6. each frame's depth sign by motion smoothness.
       W of numerical rank r < 3K: in the determined subspace (:mod:`.subspace`).

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
        The motion factor of the measurement stage (:mod:`nrsfm.stages.measurement`).
    K : int
    settings : RotationSettings, optional
    single : bool
        One triplet, no averaging (the ``bmm`` method).
    seed : int
        Seed of the search's random starts (deterministic per seed).
    progress : callable(str) or None

    Returns
    -------
    RotationResult

    Raises
    ------
    ValueError
        Settings that are not a RotationSettings, M_hat not (2F, 3K), or W of numerical rank
        below 3 (no camera is determined; the message says what to try).
    """
    st = RotationSettings() if settings is None else settings
    if not isinstance(st, RotationSettings):
        raise ValueError(f"settings must be a RotationSettings; got {st!r}")
    M = np.asarray(M_hat, float)
    if M.ndim != 2 or M.shape[1] != 3 * K or M.shape[0] % 2:
        raise ValueError(f"M_hat must have shape (2F, 3K) = (2F, {3 * K}); got {M.shape}")
    say = progress if callable(progress) else (lambda msg: None)
    timings, t0 = {}, time.perf_counter()

    def lap(name):
        nonlocal t0
        t = time.perf_counter()
        timings[name], t0 = t - t0, t

    sub = determined_subspace(M)  # rank r < 3K: its r dimensions
    if sub.rank < 3:  # a camera takes three directions of M_hat (Eq. 1)
        raise ValueError(
            f"W has numerical rank {sub.rank} < 3: its cameras are not determined (a rigid "
            f"planar object or a single moving point under an orthographic camera); give the "
            f"rotations (reconstruct(W, K, rotations=R)) or track points off one plane"
        )
    k = effective_K(sub.rank, K) if sub.deficient else K
    if sub.deficient:
        M = sub.M
        say(
            f"W has numerical rank {sub.rank} < 3K = {3 * K}: rotations from the "
            f"determined {sub.rank}-dimensional subspace, {k} triplet(s)"
        )
    search = search_triplet(M, k, seed=seed, hits=st.hits, max_starts=st.max_starts)
    say(f"best corrective triplet: Dai cost {search.costs[0]:.4g} (start {search.starts[0]})")
    G, spans = search.G[:1], np.zeros((0, 2), int)
    if not single and k > 1:  # step 1: K - 1 window triplets
        weights, spans = window_weights(M.shape[0] // 2, k - 1, st.window)
        refined = [refine_triplet(G[0], M, weights=w, **WINDOW_LM)[0] for w in weights]
        G = np.concatenate([G, np.stack(refined)])
        spans = np.array(spans)
    lap("triplets")
    costs = np.array([triplet_cost(g, M) for g in G])
    per_triplet, coef, valid = rotations_from_triplets(M, G)  # step 2
    lap("lift")
    registered, registration, flips, mirrored = register_triplets(per_triplet, valid)
    lap("registration")
    pre = average_rotations(registered, valid, None, st.max_iter, st.eps)  # step 4
    kept, dist = filter_rotations(registered, pre, st.delta, valid=valid)
    kept[0] |= ~kept.any(axis=0) & valid[0]
    lap("filtering")
    averaged, avg = average_rotations(
        registered, kept, None, st.max_iter, st.eps, return_info=True
    )  # step 5
    if np.any(avg["empty"]):  # frames with no usable sample
        averaged = _fill_empty(averaged, avg["empty"])
    lap("averaging")
    rotations, flipped = resolve_depth_signs(averaged)  # step 6
    say(
        f"rotations: {len(G)} triplet(s), {kept.sum()} of {kept.size} samples kept, "
        f"{int(flipped.sum())} frames' depth sign from smoothness"
    )
    if sub.deficient:
        G = lift_triplets(G, sub)
    return RotationResult(
        rotations=rotations,
        G=G,
        triplet_costs=costs,
        search=search,
        window_spans=spans,
        per_triplet=per_triplet,
        coefficients=coef,
        registration=registration,
        flips=flips,
        mirrored=mirrored,
        registered=registered,
        filter_distance=dist,
        kept=kept,
        averaged=averaged,
        averaging_iterations=avg["iterations"],
        sign_from_smoothness=flipped,
        determined_rank=sub.rank,
        effective_K=k,
        timings=timings,
    )
