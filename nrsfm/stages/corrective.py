"""Corrective triplets G^k (3K x 3) from the rank-3K motion factor (Dai et al., CVPR 2012).

Every valid triplet G satisfies, for each frame f with 2 x 3K block ``M_f`` (rows m_1, m_2),
``m_1 Q m_1' = m_2 Q m_2'`` and ``m_1 Q m_2' = 0`` with ``Q = G G'`` of rank 3
(``M_f G = c_f R_f[:2]``, an orthographic camera times a scalar).

Stages, each a function named by what it maps:

* :func:`constraint_matrix`: M_hat (2F, 3K) -> A (2F, n(n+1)/2) acting on vech(Q), n = 3K.
* :func:`penalized_gram`: M_hat -> Q, a PSD relaxation (trace plus a penalty on Dai's
  constraint residual, mean squared camera scale fixed to 1).
* :func:`triplets_from_gram`: Q -> G from the top-3 eigenpairs (or the K column blocks).
* :func:`refine_triplet`: G -> G minimising Dai's cost
  ``sum_f (1 - |r2|^2/|r1|^2)^2 + 4 sum_f ((r1.r2)/|r1|^2)^2`` (r1, r2 the rows of M_f G)
  by Levenberg-Marquardt on the 2F residuals with the analytic Jacobian.
* :func:`search_triplet`: multistart over the relaxations and seeded random starts,
  stopped once the lowest cost has been reached by two starts.
* :func:`corrective_triplets`: the search, as the rotation stage runs it.

Dai's own relaxation (minimum nuclear norm over the solution space) and the other starts
are research variants in :mod:`nrsfm.research.rotations`. Measurements behind these choices (which
starts reach the best minimum, with and without track noise, and at what cost):
``docs/rotation_stage.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, minimize

__all__ = ["constraint_matrix", "triplets_from_gram", "penalized_gram",
           "triplet_residuals", "triplet_cost", "refine_triplet", "CorrectiveResult",
           "corrective_triplets", "search_triplet", "SEARCH_LAMBDAS", "gram_from_vech",
           "vech_index"]


# ----------------------------------------------------------------------------- constraints
def vech_index(n):
    """Row and column indices (i <= j) of the upper triangle of an n x n matrix."""
    return np.triu_indices(n)


def gram_from_vech(q, n):
    """Symmetric n x n matrix from its upper triangle (vech order of :func:`vech_index`).

    ``q`` may be (n(n+1)/2,) or (n(n+1)/2, m): the result is then (m, n, n).
    """
    q = np.asarray(q, float)
    iu = vech_index(n)
    if q.ndim == 1:
        Q = np.zeros((n, n))
        Q[iu] = q
        return Q + np.triu(Q, 1).T
    Q = np.zeros((q.shape[1], n, n))
    Q[:, iu[0], iu[1]] = q.T
    return Q + np.transpose(np.triu(Q, 1), (0, 2, 1))


def constraint_matrix(M_hat):
    """Dai's 2F linear equations on vech(Q) (vectorised over frames).

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray

    Returns
    -------
    A : (2F, n(n+1)/2) ndarray, n = 3K
        Row 2f: ``m_1 Q m_1' - m_2 Q m_2'``; row 2f+1: ``m_1 Q m_2'`` as linear functions of
        the upper triangle of Q (off-diagonal entries counted twice where Q is symmetric).
    """
    M = np.asarray(M_hat, float)
    F, n = M.shape[0] // 2, M.shape[1]
    m1, m2 = M[0::2], M[1::2]
    i, j = vech_index(n)
    off = (i != j).astype(float)
    a = m1[:, i] * m1[:, j] - m2[:, i] * m2[:, j]
    a = a * (1.0 + off)
    b = m1[:, i] * m2[:, j] + off * m1[:, j] * m2[:, i]
    A = np.empty((2 * F, a.shape[1]))
    A[0::2], A[1::2] = a, b
    return A


def _constraint_eig(At, cache):
    """Eigendecomposition of ``At' At`` (independent of the penalty: cached across them)."""
    if cache is not None and "eig" in cache:
        return cache["eig"]
    e, V = np.linalg.eigh(At.T @ At)
    if cache is not None:
        cache["eig"] = (e, V)
    return e, V


def _warm_start(cache, Z, U, rho):
    """The previous penalty's ADMM state when cached (the problem is convex: the same
    optimum, fewer iterations; pickup 195 -> 60), else the given start."""
    if cache is None or "warm" not in cache:
        return Z, U, rho
    Zw, Uw, rw = cache["warm"]
    return np.array(Zw, copy=True), np.array(Uw, copy=True), float(rw)


def penalized_gram(M_hat, K, lam=1e2, solver="admm", max_iter=3000, tol=1e-7,
                   return_info=False, _cache=None):
    """A convex relaxation that does land near the best triplet on the benchmark.

    ``minimise  a trace(Q) + (lam / F) ||A vech(Q)||^2
      s.t.  Q PSD,  <M'M, Q> = 2F``

    with ``a = trace(M'M) / (2F 3K)`` (so that both terms are dimensionless). The
    constraint residual of Dai's equations is penalised instead of imposed (the exact
    intersection of the approximate null space with the PSD cone is empty on real data,
    see :func:`nrsfm.research.rotations.relaxed_gram`), the normalisation fixes the mean squared camera scale
    ``mean_f |c_f|^2`` to 1 instead of an arbitrary sum of basis coefficients, and the
    trace (nuclear norm on the PSD cone) pushes the solution to low rank. Which ``lam``
    reaches the best minimum with and without noise: ``docs/rotation_stage.md``.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    K : int
    lam : float
    solver : {"admm", "cvxpy"}
        ``admm``: the ADMM below (one eigendecomposition of the 3K(3K+1)/2 square Gram
        matrix of the constraints up front, then a 3K x 3K eigendecomposition per
        iteration). ``cvxpy``: cvxpy + SCS for cross-checking.

    Returns
    -------
    Q : (3K, 3K) ndarray, symmetric PSD
    info : dict (if ``return_info``)
    """
    M = np.asarray(M_hat, float)
    F, n = M.shape[0] // 2, M.shape[1]          # 3K, or the determined rank r
    A = constraint_matrix(M)
    C = M.T @ M
    a = np.trace(C) / (2.0 * F * n)
    iu = vech_index(n)
    dw = np.where(iu[0] == iu[1], 1.0, np.sqrt(2.0))      # vec_w(Q) = dw * vech(Q)
    At = A / dw                                            # A vech(Q) = At vec_w(Q)
    t = (iu[0] == iu[1]).astype(float)                     # trace(Q) = t . vec_w(Q)
    c = C[iu] * dw                                         # <C, Q> = c . vec_w(Q)
    t0 = time.perf_counter()
    if solver == "cvxpy":
        import cvxpy as cp

        Qv = cp.Variable((n, n), PSD=True)
        q = cp.hstack([Qv[i, j] for i, j in zip(*iu)])
        prob = cp.Problem(cp.Minimize(a * cp.trace(Qv) + lam / F * cp.sum_squares(A @ q)),
                          [cp.trace(C @ Qv) == 2 * F])
        prob.solve(solver=cp.SCS, eps=1e-7, max_iters=50000)
        Q = 0.5 * (Qv.value + Qv.value.T)
        info = dict(solver="cvxpy-scs", status=prob.status)
    elif solver == "admm":
        e, V = _constraint_eig(At, _cache)
        e = np.clip(e, 0, None) * (2.0 * lam / F)
        Vt_t, Vt_c = V.T @ t, V.T @ c

        def solve(rhs_v, rho):                             # (2 lam/F At'At + rho I)^-1
            return V @ (rhs_v / (e + rho))

        rho = 1.0
        Z = np.eye(n) * (2.0 * F / np.trace(C))            # feasible, PSD start
        U = np.zeros((n, n))
        Z, U, rho = _warm_start(_cache, Z, U, rho)
        status, it = "max_iter", 0
        Hc = None
        for it in range(1, max_iter + 1):
            if Hc is None:
                Hc = solve(Vt_c, rho)                      # H^-1 c
                cHc = c @ Hc
            rhs = rho * ((Z - U)[iu] * dw) - a * t
            y = solve(V.T @ rhs, rho)
            mu = (c @ y - 2.0 * F) / cHc
            v = y - mu * Hc
            Qm = np.zeros((n, n))
            Qm[iu] = v / dw
            Qm = Qm + np.triu(Qm, 1).T
            w, E = np.linalg.eigh(Qm + U)
            Z_old = Z
            Z = (E * np.clip(w, 0, None)) @ E.T
            r = Qm - Z
            U += r
            rn, sn = np.linalg.norm(r), np.linalg.norm(Z - Z_old)
            scale = max(np.linalg.norm(Z), 1e-300)
            if rn < tol * scale and sn < tol * scale:
                status = "converged"
                break
            if it % 10 == 0:                               # residual balancing
                if rn > 10 * sn:
                    rho *= 2.0
                    U /= 2.0
                    Hc = None
                elif sn > 10 * rn:
                    rho /= 2.0
                    U *= 2.0
                    Hc = None
        Q = 0.5 * (Z + Z.T)
        if _cache is not None:
            _cache["warm"] = (Z, U, rho)
        info = dict(solver="admm", status=status, iterations=it, rho=rho,
                    primal_residual=float(rn))
    else:
        raise ValueError(f"unknown solver {solver!r}")
    info["seconds"] = time.perf_counter() - t0
    info["constraint_residual"] = float(np.linalg.norm(A @ Q[iu]) / np.sqrt(F))
    return (Q, info) if return_info else Q


def triplets_from_gram(Q, mode="eig"):
    """Triplets from a (relaxed) Gram matrix.

    Parameters
    ----------
    Q : (3K, 3K) symmetric ndarray
    mode : {"eig", "columns"}
        ``eig``: one triplet ``V_3 sqrt(L_3)`` from the top-3 eigenpairs (Dai).
        ``columns``: the K column blocks ``Q[:, 3k:3k+3]`` (for Q = G G' of rank 3 each
        is G times a 3 x 3 matrix: a valid triplet up to an affine map that refinement
        removes) -- the paper's "K column triplets" read literally.

    Returns
    -------
    G : (m, 3K, 3) ndarray (m = 1 for ``eig``, K for ``columns``)
    """
    Q = 0.5 * (np.asarray(Q, float) + np.asarray(Q, float).T)
    n = Q.shape[0]
    if mode == "eig":
        w, V = np.linalg.eigh(Q)
        w, V = w[::-1][:3], V[:, ::-1][:, :3]
        return (V * np.sqrt(np.clip(w, 0, None)))[None]
    if mode == "columns":
        return np.stack([Q[:, 3 * k:3 * k + 3] for k in range(n // 3)])
    raise ValueError(f"unknown mode {mode!r}")


# ------------------------------------------------------------------------- refinement
_EPS = 1e-150   # floor of |r1|^2 (keeps |r1|^4 representable)


def triplet_residuals(G, M_hat, weights=None, jac=False):
    """Residuals of Dai's cost, ``[1 - |r2|^2/|r1|^2, 2 r1.r2/|r1|^2]`` per frame.

    Parameters
    ----------
    G : (3K, 3) ndarray
    M_hat : (2F, 3K) ndarray
    weights : (F,) ndarray, optional
        Per-frame weights (0 drops a frame; used for frame subsets).
    jac : bool
        Also return the Jacobian (2F, 9K) with respect to ``G.ravel()``.

    Returns
    -------
    r : (2F,) ndarray, and J if ``jac``
    """
    M = np.asarray(M_hat, float)
    m1, m2 = M[0::2], M[1::2]
    a, b = m1 @ G, m2 @ G
    na = np.maximum(np.einsum("fi,fi->f", a, a), _EPS)
    nb = np.einsum("fi,fi->f", b, b)
    ab = np.einsum("fi,fi->f", a, b)
    r1 = 1.0 - nb / na
    r2 = 2.0 * ab / na
    w = None if weights is None else np.sqrt(np.asarray(weights, float))
    if w is not None:
        r1, r2 = r1 * w, r2 * w
    r = np.empty(2 * M.shape[0] // 2)
    r[0::2], r[1::2] = r1, r2
    if not jac:
        return r
    # d|a|^2/dG = 2 m1 a' ; d|b|^2/dG = 2 m2 b' ; d(a.b)/dG = m1 b' + m2 a'
    dna = 2.0 * m1[:, :, None] * a[:, None, :]
    dnb = 2.0 * m2[:, :, None] * b[:, None, :]
    dab = m1[:, :, None] * b[:, None, :] + m2[:, :, None] * a[:, None, :]
    inv = (1.0 / na)[:, None, None]
    J1 = -dnb * inv + (nb / na ** 2)[:, None, None] * dna
    J2 = 2.0 * (dab * inv - (ab / na ** 2)[:, None, None] * dna)
    if w is not None:
        J1, J2 = J1 * w[:, None, None], J2 * w[:, None, None]
    F = M.shape[0] // 2
    J = np.empty((2 * F, G.size))
    J[0::2] = J1.reshape(F, -1)
    J[1::2] = J2.reshape(F, -1)
    return r, J


def triplet_cost(G, M_hat, weights=None):
    """Dai's cost ``sum_f (1 - |r2|^2/|r1|^2)^2 + 4 sum_f ((r1.r2)/|r1|^2)^2``."""
    r = triplet_residuals(G, M_hat, weights)
    return float(r @ r)


def _normalise_triplet(G, M_hat):
    """Fix the scale gauge: rows of M_f G have RMS norm 1 over frames."""
    a = np.asarray(M_hat) @ G
    s = np.sqrt(np.mean(np.einsum("ri,ri->r", a, a)))
    return G / s if s > 0 else G


def _levenberg_marquardt(G0, M, weights, max_iter, tol):
    """Levenberg-Marquardt on Dai's residuals (normal equations, Nielsen's damping rule).

    Returns (G, cost, iterations). About 0.3 ms per iteration at pickup's size, ten times
    faster than MINPACK through scipy (whose per-call overhead dominates at this size).
    """
    shape = G0.shape
    g = G0.ravel().copy()
    r, J = triplet_residuals(G0, M, weights, jac=True)
    cost = float(r @ r)
    A, grad = J.T @ J, J.T @ r
    lam = 1e-3 * float(np.max(np.diag(A))) if A.size else 1.0
    nu = 2.0
    it = 0
    for it in range(1, max_iter + 1):
        D = np.diag(A).copy()
        D = np.maximum(D, 1e-12 * max(D.max(), 1e-300))
        try:
            step = np.linalg.solve(A + lam * np.diag(D), -grad)
        except np.linalg.LinAlgError:
            lam *= nu
            nu *= 2.0
            if nu > 1e15 or lam > 1e100:
                break
            continue
        g_new = g + step
        r_new = triplet_residuals(g_new.reshape(shape), M, weights)
        c_new = float(r_new @ r_new)
        if np.isfinite(c_new) and c_new < cost:
            pred = -(step @ grad) - 0.5 * step @ (A @ step)
            rho = (cost - c_new) / max(2.0 * pred, 1e-300)
            done = (cost - c_new) <= tol * cost or c_new < 1e-28
            g, cost = g_new, c_new
            r, J = triplet_residuals(g.reshape(shape), M, weights, jac=True)
            A, grad = J.T @ J, J.T @ r
            lam *= max(1.0 / 3.0, 1.0 - (2.0 * min(rho, 1.0) - 1.0) ** 3)
            nu = 2.0
            if done:
                break
        else:
            lam *= nu
            nu *= 2.0
            if nu > 1e15 or lam > 1e100:
                break
    return g.reshape(shape), cost, it


def refine_triplet(G0, M_hat, weights=None, method="lm", max_iter=None, tol=1e-10):
    """Minimise Dai's cost over G (3K x 3), started from ``G0``.

    Parameters
    ----------
    G0 : (3K, 3) ndarray
    M_hat : (2F, 3K) ndarray
    weights : (F,) ndarray, optional
        Per-frame weights (0 drops a frame).
    method : {"lm", "minpack", "lbfgs"}
        ``lm`` (default): the Levenberg-Marquardt above on the 2F residuals with the
        analytic Jacobian, stopped when the relative decrease of the cost is below ``tol``:
        tens of iterations, 20-100 ms on pickup. ``minpack``: the same model through
        ``scipy.optimize.least_squares(method="lm")`` (same minima, about 10x slower).
        ``lbfgs``: scipy L-BFGS-B on the cost with the analytic gradient ``2 J'r``: the
        same minimum from the same start, but thousands of iterations (seconds).

    Returns
    -------
    G : (3K, 3) ndarray, normalised so that the rows of M_f G have RMS norm 1
    info : dict (cost, cost0, iterations, seconds, method)
    """
    M = np.asarray(M_hat, float)
    if weights is not None:
        weights = np.asarray(weights, float)
        keep = weights > 0
        if not keep.all():                      # drop zero-weight frames outright
            M = M[np.repeat(keep, 2)]
            weights = weights[keep]
    G0 = _normalise_triplet(np.asarray(G0, float), M)
    shape = G0.shape
    t0 = time.perf_counter()
    cost0 = triplet_cost(G0, M, weights)
    if method == "lm":
        G, _, nit = _levenberg_marquardt(G0, M, weights, max_iter or 500, tol)
    elif method == "minpack":
        def fun(g):
            return triplet_residuals(g.reshape(shape), M, weights)

        def jac(g):
            return triplet_residuals(g.reshape(shape), M, weights, jac=True)[1]

        res = least_squares(fun, G0.ravel(), jac=jac, method="lm", xtol=1e-12, ftol=1e-12,
                            gtol=1e-12, max_nfev=max_iter or 100 * G0.size)
        G, nit = res.x.reshape(shape), int(res.nfev)
    elif method == "lbfgs":
        def fg(g):
            r, J = triplet_residuals(g.reshape(shape), M, weights, jac=True)
            return float(r @ r), 2.0 * (J.T @ r)

        res = minimize(fg, G0.ravel(), jac=True, method="L-BFGS-B",
                       options=dict(maxiter=max_iter or 20000, ftol=1e-15, gtol=1e-10,
                                    maxcor=30))
        G, nit = res.x.reshape(shape), int(res.nit)
    else:
        raise ValueError(f"unknown method {method!r}")
    G = _normalise_triplet(G, M)
    return G, dict(cost=triplet_cost(G, M, weights), cost0=cost0, iterations=nit,
                   seconds=time.perf_counter() - t0, method=method)


# ------------------------------------------------------------------------- all together
@dataclass
class CorrectiveResult:
    """Output of :func:`corrective_triplets`.

    Attributes
    ----------
    G : (m, 3K, 3) ndarray
        Refined triplets (m = 1 for ``mode="eig"``).
    G_init : (m, 3K, 3) ndarray
        Starting points (from the relaxed Gram matrix).
    Q : (3K, 3K) ndarray
        Relaxed Gram matrix.
    costs : (m,) ndarray
        Dai's cost of each refined triplet.
    info : dict
    timings : dict
    """

    G: np.ndarray
    G_init: np.ndarray
    Q: np.ndarray
    costs: np.ndarray
    info: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)


#: penalties of :func:`penalized_gram` tried, in order, by ``starts="search"``
SEARCH_LAMBDAS = (1e1, 1e2)


def search_triplet(M_hat, K, seed=0, hits=2, max_starts=40, lams=SEARCH_LAMBDAS,
                   rtol=1e-5, max_iter=200, sdp_solver="admm", refine="lm"):
    """Multistart minimisation of Dai's cost with a stopping rule.

    Starts, in a fixed order: the top-3 eigenpairs of :func:`penalized_gram` for each
    penalty in ``lams``, then Gaussian starts drawn from ``numpy.random.default_rng(seed)``.
    Each start is refined on all frames (Levenberg-Marquardt, at most ``max_iter``
    iterations). The search stops as soon as the lowest cost found so far has been reached
    by ``hits`` starts (costs equal to relative ``rtol``: the same minimum), or after
    ``max_starts`` starts.

    Why this rule: a basin reached by ``h`` of ``n`` independent random starts has an
    estimated attraction probability ``h / n``; a better basin never reached in ``n``
    starts has, with 95% confidence, attraction probability below ``3 / n`` (rule of
    three). Requiring two hits of the best minimum means that minimum was found again by a
    start that did not know it, which rules out the failure the single relaxation showed
    under noise (one start, one unconfirmed local minimum). ``info["miss_bound"]`` reports
    ``3 / n_random`` when random starts were used (1.0 when none were).

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    K : int
    seed : int
        Seeds every random start (deterministic results for a given seed).
    hits : int
        Starts that must reach the best minimum before the search stops.
    max_starts : int
        Upper bound on the number of refined starts (relaxations included).
    lams : sequence of float
        Penalties of the relaxations used as the first starts.

    Returns
    -------
    G : (m, 3K, 3) ndarray
        The refined triplets of the distinct minima found, lowest cost first.
    costs : (m,) ndarray
    info : dict
        ``starts`` (name of each row's first start), ``n_starts``, ``hits`` (starts that
        reached the best minimum), ``history`` (name, cost, iterations per start),
        ``stopped`` ("hits" or "max_starts"), ``miss_bound``, relaxation infos.
    """
    M = np.asarray(M_hat, float)
    n = M.shape[1]                  # 3K, or the determined rank r
    rng = np.random.default_rng(seed)
    minima = []                     # [cost, G, name, count]
    history = []
    info = {"penalized": []}
    Q = None

    def add(name, G0):
        G, inf = refine_triplet(G0, M, method=refine, max_iter=max_iter)
        c = inf["cost"] if np.isfinite(inf["cost"]) else np.inf
        history.append((name, float(c), int(inf["iterations"])))
        for mn in minima:
            if abs(mn[0] - c) <= rtol * max(abs(mn[0]), 1e-12):
                mn[3] += 1            # same minimum: keep the first start's triplet (its
                return                # gauge), so round-off cannot switch between them
        minima.append([c, G, name, 1])

    def done():
        if not minima:
            return False
        best = min(minima, key=lambda mn: mn[0])
        return best[3] >= hits

    stopped = "max_starts"
    n_random = 0
    cache = {}
    for lam in lams:
        Q, pinfo = penalized_gram(M, K, lam=lam, solver=sdp_solver, return_info=True,
                                  _cache=cache)
        info["penalized"].append(pinfo)
        add(f"relaxed(lam={lam:g})", triplets_from_gram(Q, "eig")[0])
        if done():
            stopped = "hits"
            break
    while stopped != "hits" and len(history) < max_starts:
        add(f"random{n_random}", rng.standard_normal((n, 3)))
        n_random += 1
        if done():
            stopped = "hits"
    minima.sort(key=lambda mn: mn[0])
    info.update(starts=[mn[2] for mn in minima], n_starts=len(history), n_random=n_random,
                hits=int(minima[0][3]), counts=[mn[3] for mn in minima], history=history,
                stopped=stopped, miss_bound=min(1.0, 3.0 / n_random) if n_random else 1.0,
                Q=Q)
    return (np.stack([mn[1] for mn in minima]), np.array([mn[0] for mn in minima]), info)


def corrective_triplets(M_hat, K, seed=0, hits=2, max_starts=40, sdp_solver="admm",
                        refine="lm"):
    """Corrective triplet(s) from the motion factor, best (lowest Dai cost) first.

    :func:`search_triplet`: the relaxation at the penalties :data:`SEARCH_LAMBDAS`, then
    seeded random starts, until the lowest cost has been reached by ``hits`` starts (at
    most ``max_starts``). Other starts (Dai's relaxation, its column blocks, a screened
    multistart) are research variants: :func:`nrsfm.research.rotations.corrective_triplets_from`.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    K : int
    seed : int
        Seed of the random starts.
    hits, max_starts : int
        Stopping rule of the search.
    sdp_solver : {"admm", "cvxpy"}
    refine : {"lm", "minpack", "lbfgs"}

    Returns
    -------
    CorrectiveResult
        ``G`` sorted by cost (``G[0]`` is the best triplet); ``info["starts"]`` names each
        row's start, ``info["search"]`` the search's record.
    """
    M = np.asarray(M_hat, float)
    t0 = time.perf_counter()
    G, costs, sinfo = search_triplet(M, K, seed=seed, hits=hits, max_starts=max_starts,
                                     sdp_solver=sdp_solver, refine=refine)
    Q = sinfo.pop("Q")
    timings = {"search": time.perf_counter() - t0}
    sinfo["search"] = {k: sinfo[k] for k in ("n_starts", "n_random", "hits", "counts",
                                             "history", "stopped", "miss_bound")}
    return CorrectiveResult(G=G, G_init=G.copy(), Q=Q, costs=costs, info=sinfo,
                            timings=timings)
