"""Triplet starts other than the production search, and rotation-fit helpers, for the
research strategies (:mod:`.rotations`) and the notebooks:

* Dai's relaxation as specified (:func:`solution_space`, :func:`relaxed_gram`), its
  column blocks and a screened multistart (:func:`corrective_triplets_from`);
* :func:`chordal_mean`, :func:`triplet_from_rotations`, :func:`row_space_residual`.
"""

from __future__ import annotations

import time

import numpy as np

from ..geometry import project_to_so3
from ..stages.corrective import CorrectiveResult, corrective_triplets, refine_triplet
from ..stages.relaxation import (constraint_matrix, gram_from_vech, penalized_gram,
                                 triplets_from_gram)
from ..validation import check_choice

__all__ = ["STARTS", "chordal_mean", "corrective_triplets_from", "relaxed_gram",
           "row_space_residual", "solution_space", "triplet_from_rotations"]

#: where the triplet refinement starts (:func:`corrective_triplets_from`)
STARTS = ("search", "relaxed", "dai", "columns", "multistart")


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
    check_choice("starts", starts, STARTS)
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
        G, inf = refine_triplet(G0, M, method=refine)
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
