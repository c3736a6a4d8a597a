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
* triplet starts other than the search: Dai's relaxation as specified
  (:func:`solution_space`, :func:`relaxed_gram`), its column blocks and a screened
  multistart (:func:`corrective_triplets_from`);
* :func:`chordal_mean`, :func:`triplet_from_rotations`, :func:`row_space_residual`.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..geometry import project_to_so3
from ..stages.corrective import (CorrectiveResult, _normalise_triplet, constraint_matrix,
                                corrective_triplets, gram_from_vech, penalized_gram,
                                refine_triplet, triplet_cost, triplets_from_gram)
from ..stages.rotations import (RotationSettings, rotations_from_triplets,
                                run_rotation_stage, triplets_on_subsets, window_weights)
from ..stages.rotations.stage import MIN_WINDOW_FRAMES, average_samples, record_search
from .family import combine_family, combine_triplets, triplet_family
from .settings import RotationAblationSettings

__all__ = ["STRATEGIES", "chordal_mean", "combine_family", "corrective_triplets_from",
           "estimate_rotations_ablation", "relaxed_gram", "row_space_residual",
           "solution_space", "subset_weights", "triplet_family", "triplet_from_rotations"]

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


def chordal_mean(samples, mask=None):
    """Chordal L2 mean per frame: projection of the arithmetic mean onto SO(3)."""
    samples = np.asarray(samples, float)
    mask = np.ones(samples.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    S = np.einsum("mf,mfij->fij", mask.astype(float), samples)
    S = np.where(mask.any(axis=0)[:, None, None], S, np.eye(3))
    return project_to_so3(S)


def triplet_from_rotations(M_hat, R, G0, n_iter=30):
    """The triplet whose cameras best match given rotations: ``M_f G ~ s_f R_f[:2]``.

    Alternating least squares over G (3K x 3) and the per-frame scales s_f (normalised to
    ``sum_f s_f^2 = F``), started from ``G0``. Used to project averaged rotations back onto
    the factorisation model (one G for all frames, as the shape stage assumes).

    Returns
    -------
    G : (3K, 3) ndarray
    scales : (F,) ndarray
    """
    M = np.asarray(M_hat, float)
    F = M.shape[0] // 2
    A = np.asarray(R, float)[:, :2]
    pinvM = np.linalg.pinv(M)
    G = np.asarray(G0, float).copy()
    s = np.ones(F)
    for _ in range(n_iter):
        B = (M @ G).reshape(F, 2, 3)
        s = np.einsum("fij,fij->f", B, A) / 2.0
        n = np.sqrt(np.sum(s ** 2))
        if not n > 0:
            break
        s *= np.sqrt(F) / n
        G_new = pinvM @ (s[:, None, None] * A).reshape(2 * F, 3)
        if np.allclose(G_new, G, rtol=1e-10, atol=1e-14):
            G = G_new
            break
        G = G_new
    return G, s



# --------------------------------------------------------------------------- triplets
def row_space_residual(M_hat, R, G0):
    """How far rotations are from cameras one triplet can give: ``min ||M_hat G - s R||``.

    The factorisation model (Eq. 1) has one G for all frames, ``M_f G = c_f R_f[:2]``;
    rotations averaged per frame need not be of that form. Fits G and the per-frame scales
    by alternating least squares (:func:`triplet_from_rotations`, started from ``G0``).

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    R : (F, 3, 3) ndarray
    G0 : (3K, 3) ndarray

    Returns
    -------
    float
        ``||M_hat G - s R[:2]||_F / ||s R[:2]||_F`` at the fit (0: exactly consistent).
    """
    M = np.asarray(M_hat, float)
    F = M.shape[0] // 2
    G, s = triplet_from_rotations(M, R, G0)
    target = (s[:, None, None] * np.asarray(R, float)[:, :2]).reshape(2 * F, 3)
    return float(np.linalg.norm(M @ G - target) / max(np.linalg.norm(target), 1e-300))


def solution_space(A, K):
    """Basis of the (approximate) null space of A: the last 2K^2 - K right singular vectors.

    Returns
    -------
    basis : (n(n+1)/2, 2K^2 - K) ndarray, orthonormal columns
    singular_values : ndarray, all singular values of A (for inspection)
    """
    d = 2 * K * K - K
    m = A.shape[1]
    # The right singular vectors of A are the eigenvectors of A'A (m x m, m <= 2F here is
    # not guaranteed): eigh of the Gram matrix is 3-5x faster than the SVD of A and accurate
    # enough for a subspace separated by a large gap. The rows of A are used as they are
    # (not normalised): frames with larger camera scale |c_f| weigh more.
    H = A.T @ A
    w, V = np.linalg.eigh(H)
    sv = np.sqrt(np.clip(w[::-1], 0, None))
    if A.shape[0] < m:          # A'A is rank deficient: the extra null vectors are valid too
        sv[A.shape[0]:] = 0.0
    return V[:, :d], sv


# ------------------------------------------------------------------------- relaxed SDP
def relaxed_gram(basis, K, solver="admm", psd=False, max_iter=5000, tol=1e-6, rho=None,
                 return_info=False):
    """Dai's convex relaxation: the minimum nuclear-norm point of the solution space.

    ``minimise ||Q||_*  s.t.  Q = sum_i x_i N_i,  sum_i x_i = 1``  (``vech(N_i)`` the basis
    vectors). With ``psd=True`` the constraint ``Q PSD`` is added (the nuclear norm is then
    the trace); on the benchmark that problem is infeasible (noise takes the PSD triplets
    out of the approximate null space), so the default leaves Q indefinite.

    Parameters
    ----------
    basis : (n(n+1)/2, d) ndarray
        From :func:`solution_space`.
    K : int
    solver : {"admm", "cvxpy"}
        ``admm``: the ADMM below (one symmetric 3K x 3K eigendecomposition per iteration,
        no compilation). ``cvxpy``: cvxpy + SCS, kept for cross-checking (its problem
        compilation alone takes seconds at K = 12).

    Returns
    -------
    Q : (3K, 3K) ndarray, symmetric, signed so that its largest eigenvalues are positive
    info : dict (only if ``return_info``)
    """
    n = 3 * K
    N = gram_from_vech(basis, n)                   # (d, n, n)
    d = N.shape[0]
    t0 = time.perf_counter()
    if solver == "cvxpy":
        import cvxpy as cp

        x = cp.Variable(d)
        Qe = sum(x[i] * N[i] for i in range(d))
        if psd:
            Qv = cp.Variable((n, n), PSD=True)
            prob = cp.Problem(cp.Minimize(cp.trace(Qv)), [Qv == Qe, cp.sum(x) == 1])
        else:
            prob = cp.Problem(cp.Minimize(cp.normNuc(Qe)), [cp.sum(x) == 1])
        prob.solve(solver=cp.SCS, eps=1e-7, max_iters=50000)
        if x.value is None:
            raise RuntimeError(f"cvxpy/SCS: {prob.status}")
        xv = np.asarray(x.value)
        Q = np.tensordot(xv, N, axes=1)
        info = dict(solver="cvxpy-scs", status=prob.status, x=xv)
    elif solver == "admm":
        Q, info = _admm_nuclear(N, psd, max_iter, tol, rho)
    else:
        raise ValueError(f"unknown solver {solver!r}")
    Q = 0.5 * (Q + Q.T)
    w = np.linalg.eigvalsh(Q)
    if w[-3:].sum() < -w[:3].sum():                # dominant part negative: use -Q
        Q = -Q
    info["seconds"] = time.perf_counter() - t0
    return (Q, info) if return_info else Q


def _admm_nuclear(N, psd, max_iter, tol, rho):
    """ADMM for ``min ||Z||_*  s.t. Z = sum x_i N_i, 1'x = 1 [, Z PSD]``.

    x-step: least squares with one linear equality (precomputed inverse); Z-step:
    eigenvalue soft-thresholding of a symmetric matrix (clipped at 0 when ``psd``).
    """
    d, n, _ = N.shape
    A = N.reshape(d, n * n).T                     # (n^2, d): vec(Q) = A x
    H = A.T @ A
    Hinv = np.linalg.inv(H + 1e-12 * np.trace(H) / d * np.eye(d))
    one = np.ones(d)
    Hinv1 = Hinv @ one
    s1 = one @ Hinv1
    x = Hinv1 / s1                                # least-norm point with 1'x = 1
    Qx = (A @ x).reshape(n, n)
    # rho in units of the problem's scale (the nuclear norm is 1-homogeneous)
    rho = 1.0 / max(np.abs(np.linalg.eigvalsh(Qx)).max(), 1e-12) if rho is None else rho
    Z = Qx.copy()
    U = np.zeros((n, n))
    status = "max_iter"
    it = 0
    rn = np.inf
    for it in range(max_iter):
        y = Hinv @ (A.T @ (Z - U).ravel())
        x = y - ((one @ y - 1.0) / s1) * Hinv1
        Qx = (A @ x).reshape(n, n)
        V = Qx + U
        w, E = np.linalg.eigh(0.5 * (V + V.T))
        thr = 1.0 / rho
        wp = np.clip(w - thr, 0, None) if psd else np.sign(w) * np.clip(np.abs(w) - thr, 0, None)
        Z_old = Z
        Z = (E * wp) @ E.T
        r = Qx - Z
        U = U + r
        rn = np.linalg.norm(r)
        scale = max(np.linalg.norm(Z), 1e-12)
        if rn < tol * scale and np.linalg.norm(Z - Z_old) < tol * scale and it > 10:
            status = "converged"
            break
        if it % 10 == 9:                          # residual balancing (Boyd et al. 3.4.1)
            dual = np.linalg.norm(Z - Z_old) * rho
            if rn * rho > 10 * dual / rho * rho and rn > 10 * np.linalg.norm(Z - Z_old):
                rho *= 2.0
                U /= 2.0
            elif np.linalg.norm(Z - Z_old) > 10 * rn:
                rho /= 2.0
                U *= 2.0
    return Qx, dict(solver="admm", status=status, iterations=it + 1, rho=float(rho),
                    primal_residual=float(rn), x=x)




def corrective_triplets_from(M_hat, K, starts="search", seed=0, n_random=32, n_full=4,
                        screen_frames=80, screen_iter=30, sdp_solver="admm", refine="lm",
                        lam=1e2, gram="penalized", hits=2, max_starts=40):
    """Corrective triplet(s) from the motion factor, best (lowest Dai cost) first.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    K : int
    starts : {"search", "relaxed", "dai", "columns", "multistart"}
        Where the refinement starts.

        * ``search`` (default): :func:`search_triplet` (``hits``, ``max_starts``): the
          relaxation at the penalties :data:`SEARCH_LAMBDAS`, then seeded random starts,
          until the lowest cost has been reached by ``hits`` starts.
        * ``relaxed``: the top-3 eigenpairs of :func:`penalized_gram` (PSD, trace +
          penalised constraint residual, mean camera scale 1): one refinement.
        * ``dai``: the top-3 eigenpairs of Dai's relaxation as specified
          (:func:`relaxed_gram`).
        * ``columns``: the K column blocks of the relaxed Gram matrix (``gram`` selects
          which relaxation), each refined on all frames: the paper's "K column triplets"
          read literally.
        * ``multistart``: the ``relaxed`` and ``dai`` starts, the K column blocks of the
          nuclear-norm relaxation and ``n_random`` seeded Gaussian starts, each refined for
          ``screen_iter`` LM iterations on about ``screen_frames`` evenly spaced frames;
          the ``n_full`` lowest screened costs are refined on all frames.
    seed : int
        Seed of the random starts.
    hits, max_starts : int
        Stopping rule of ``starts="search"``.
    lam : float
        Penalty of :func:`penalized_gram`.
    gram : {"penalized", "nuclear"}
        Relaxation whose column blocks ``starts="columns"`` uses.

    Returns
    -------
    CorrectiveResult
        As :func:`nrsfm.stages.corrective.corrective_triplets`, ``G`` sorted by cost.
    """
    M = np.asarray(M_hat, float)
    if starts not in ("search", "relaxed", "dai", "columns", "multistart"):
        raise ValueError(f"unknown starts {starts!r}")
    if starts == "search":
        return corrective_triplets(M, K, seed=seed, hits=hits, max_starts=max_starts,
                                   sdp_solver=sdp_solver, refine=refine)
    timings = {}
    t0 = time.perf_counter()
    grams, info = _relaxations(M, K, starts, gram, lam, sdp_solver)
    timings["sdp"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    cands = _starting_triplets(grams, starts, gram, 3 * K, seed, n_random)
    screened = None
    if starts == "multistart" and len(cands) > n_full:
        cands, screened = _screen(cands, M, n_full, screen_frames, screen_iter, refine)
    timings["screen"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Gs, costs, infos, G_init = [], [], [], []
    for name, G0 in cands:
        if refine:
            G, inf = refine_triplet(G0, M, method=refine)
        else:
            G = _normalise_triplet(G0, M)
            inf = dict(cost=triplet_cost(G, M))
        inf["start"] = name
        Gs.append(G)
        G_init.append(G0)
        costs.append(inf["cost"] if np.isfinite(inf["cost"]) else np.inf)
        infos.append(inf)
    order = np.argsort(costs, kind="stable")
    timings["refine"] = time.perf_counter() - t0
    info.update(refine=[infos[i] for i in order], starts=[infos[i]["start"] for i in order],
                screen=screened)
    Q = grams["penalized"] if "penalized" in grams else grams["nuclear"]
    return CorrectiveResult(G=np.stack([Gs[i] for i in order]),
                            G_init=np.stack([G_init[i] for i in order]), Q=Q,
                            costs=np.array(costs)[order], info=info, timings=timings)


def _relaxations(M, K, starts, gram, lam, sdp_solver):
    """The Gram matrices the starts need: ``penalized`` and/or Dai's ``nuclear``."""
    grams, info = {}, {}
    if starts in ("relaxed", "multistart") or (starts == "columns" and gram == "penalized"):
        grams["penalized"], info["penalized"] = penalized_gram(
            M, K, lam=lam, solver=sdp_solver, return_info=True)
    if starts in ("dai", "multistart") or (starts == "columns" and gram == "nuclear"):
        basis, sv = solution_space(constraint_matrix(M), K)
        grams["nuclear"], nuc_info = relaxed_gram(basis, K, solver=sdp_solver,
                                                  return_info=True)
        info["nuclear"] = {k: v for k, v in nuc_info.items() if k != "x"}
        info["singular_values"] = sv
    return grams, info


def _starting_triplets(grams, starts, gram, n, seed, n_random):
    """Named starting triplets [(name, G0)] of a start mode."""
    cands = []
    if starts in ("relaxed", "multistart"):
        cands.append(("relaxed", triplets_from_gram(grams["penalized"], "eig")[0]))
    if starts in ("dai", "multistart"):
        cands.append(("dai", triplets_from_gram(grams["nuclear"], "eig")[0]))
    if starts == "columns":
        Qc = grams[gram]
        cands += [(f"column{k}", G) for k, G in enumerate(triplets_from_gram(Qc, "columns"))]
    if starts == "multistart":
        cands += [(f"column{k}", G)
                  for k, G in enumerate(triplets_from_gram(grams["nuclear"], "columns"))]
        rng = np.random.default_rng(seed)
        cands += [(f"random{i}", rng.standard_normal((n, 3))) for i in range(n_random)]
    return cands


def _screen(cands, M, n_full, screen_frames, screen_iter, refine):
    """The n_full starts with the lowest cost after ``screen_iter`` refinement
    iterations on about ``screen_frames`` evenly spaced frames."""
    F = M.shape[0] // 2
    step = max(1, F // max(screen_frames, 1))
    sub = np.zeros(F)
    sub[::step] = 1.0
    scores = []
    for name, G0 in cands:
        G, inf = refine_triplet(G0, M, weights=sub, method=refine, max_iter=screen_iter)
        scores.append(inf["cost"] if np.isfinite(inf["cost"]) else np.inf)
    order = np.argsort(scores, kind="stable")[:n_full]
    screened = dict(names=[c[0] for c in cands], costs=np.array(scores))
    return [cands[i] for i in order], screened
