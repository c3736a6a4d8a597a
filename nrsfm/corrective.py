"""Corrective triplets G^k (3K x 3) from the rank-3K motion factor (Dai et al., CVPR 2012).

Every valid triplet G satisfies, for each frame f with 2 x 3K block ``M_f`` (rows m_1, m_2),
``m_1 Q m_1' = m_2 Q m_2'`` and ``m_1 Q m_2' = 0`` with ``Q = G G'`` of rank 3
(``M_f G = c_f R_f[:2]``, an orthographic camera times a scalar).

Stages, each a function named by what it maps:

* :func:`constraint_matrix`: M_hat (2F, 3K) -> A (2F, n(n+1)/2) acting on vech(Q), n = 3K.
* :func:`solution_space`: A -> basis (n(n+1)/2, 2K^2 - K), the right singular vectors of
  the smallest singular values.
* :func:`relaxed_gram`: basis -> Q, the minimum-trace (= nuclear norm on the PSD cone)
  point of the solution space with coefficients summing to 1 (an SDP; solved by a small
  ADMM written here, see the docstring for why not cvxpy).
* :func:`triplets_from_gram`: Q -> G from the top-3 eigenpairs (or column blocks of Q).
* :func:`refine_triplet`: G -> G minimising Dai's cost
  ``sum_f (1 - |r2|^2/|r1|^2)^2 + 4 sum_f ((r1.r2)/|r1|^2)^2`` (r1, r2 the rows of M_f G).
* :func:`corrective_triplets`: all of the above.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, minimize

__all__ = ["constraint_matrix", "solution_space", "relaxed_gram", "triplets_from_gram",
           "triplet_residuals", "triplet_cost", "refine_triplet", "CorrectiveResult",
           "corrective_triplets", "gram_from_vech", "vech_index"]


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
    # enough for a subspace separated by a large gap.  Rows of A are normalised first so
    # that every frame counts equally (the constraints are homogeneous in M_f).
    H = A.T @ A
    w, V = np.linalg.eigh(H)
    sv = np.sqrt(np.clip(w[::-1], 0, None))
    if A.shape[0] < m:          # A'A is rank deficient: the extra null vectors are valid too
        sv[A.shape[0]:] = 0.0
    return V[:, :d], sv


# ------------------------------------------------------------------------- relaxed SDP
def _basis_matrices(basis, n):
    """(d, n, n) symmetric matrices N_i with vech(N_i) = basis[:, i]."""
    return gram_from_vech(basis, n)


def relaxed_gram(basis, K, solver="admm", max_iter=3000, tol=1e-7, rho=None, return_info=False):
    """Minimum-trace PSD point of the solution space (Dai's convex relaxation).

    ``minimise trace(Q)  s.t.  Q = sum_i x_i N_i,  sum_i x_i = 1,  Q PSD``
    (on the PSD cone the nuclear norm is the trace).

    Parameters
    ----------
    basis : (n(n+1)/2, d) ndarray
        From :func:`solution_space`.
    K : int
    solver : {"admm", "cvxpy"}
        ``admm``: the ADMM below (eigendecomposition of one 3K x 3K matrix per iteration,
        no compilation; about 0.05-0.3 s at K = 12). ``cvxpy``: cvxpy + SCS (3 s at K = 12,
        mostly problem compilation), kept for cross-checking.

    Returns
    -------
    Q : (3K, 3K) ndarray, symmetric PSD
    info : dict (only if ``return_info``)
    """
    n = 3 * K
    N = _basis_matrices(basis, n)                 # (d, n, n)
    d = N.shape[0]
    if solver == "cvxpy":
        import cvxpy as cp

        x = cp.Variable(d)
        Q = cp.Variable((n, n), symmetric=True)
        cons = [Q == sum(x[i] * N[i] for i in range(d)), cp.sum(x) == 1, Q >> 0]
        prob = cp.Problem(cp.Minimize(cp.trace(Q)), cons)
        t0 = time.perf_counter()
        prob.solve(solver=cp.SCS, eps=1e-6, max_iters=20000)
        Qv = np.asarray(Q.value)
        Qv = 0.5 * (Qv + Qv.T)
        info = dict(solver="cvxpy-scs", status=prob.status, seconds=time.perf_counter() - t0)
        return (Qv, info) if return_info else Qv
    if solver != "admm":
        raise ValueError(f"unknown solver {solver!r}")

    # ADMM on: minimise t'x  s.t.  A x = vec(Z), 1'x = 1, Z PSD (A x = vec(sum x_i N_i)).
    A = N.reshape(d, n * n).T                     # (n^2, d)
    t = np.trace(N, axis1=1, axis2=2)             # trace(N_i)
    H = A.T @ A
    Hinv = np.linalg.inv(H + 1e-12 * np.eye(d))
    one = np.ones(d)
    Hinv1 = Hinv @ one
    s1 = one @ Hinv1
    # Scale: start from the least-squares point of the constraint set (no PSD).
    if rho is None:
        rho = 1.0
    Z = np.zeros((n, n))
    U = np.zeros((n, n))
    x = Hinv1 / s1
    history = []
    status = "max_iter"
    for it in range(max_iter):
        rhs = A.T @ (Z - U).ravel() - t / rho
        y = Hinv @ rhs
        nu = (one @ y - 1.0) / s1
        x = y - nu * Hinv1
        Qx = (A @ x).reshape(n, n)
        V = Qx + U
        w, E = np.linalg.eigh(V)
        wp = np.clip(w, 0, None)
        Z_old = Z
        Z = (E * wp) @ E.T
        r = Qx - Z
        U = U + r
        rn = np.linalg.norm(r)
        sn = rho * np.linalg.norm(Z - Z_old)
        scale = max(np.linalg.norm(Z), 1e-12)
        if it % 10 == 0:
            history.append((it, rn / scale, sn / scale))
        if rn < tol * scale and sn < tol * scale * rho and it > 10:
            status = "converged"
            break
        # residual balancing (Boyd et al. 3.4.1)
        if it % 20 == 19:
            if rn > 10 * sn:
                rho *= 2.0
                U /= 2.0
            elif sn > 10 * rn:
                rho /= 2.0
                U *= 2.0
    Q = 0.5 * (Z + Z.T)
    info = dict(solver="admm", status=status, iterations=it + 1, rho=rho,
                primal_residual=float(rn), x=x)
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
_EPS = 1e-300


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
    na = np.einsum("fi,fi->f", a, a) + _EPS
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


def refine_triplet(G0, M_hat, weights=None, method="lm", max_iter=None, tol=1e-12):
    """Minimise Dai's cost over G (3K x 3), started from ``G0``.

    Parameters
    ----------
    G0 : (3K, 3) ndarray
    M_hat : (2F, 3K) ndarray
    weights : (F,) ndarray, optional
    method : {"lm", "lbfgs"}
        ``lm``: Levenberg-Marquardt (MINPACK via scipy.optimize.least_squares) on the 2F
        residuals with the analytic Jacobian: converges in tens of iterations.
        ``lbfgs``: scipy L-BFGS-B on the cost with the analytic gradient (J' r): the same
        minimum, but thousands of iterations on the benchmark (ill-conditioned valley).

    Returns
    -------
    G : (3K, 3) ndarray, normalised so that the rows of M_f G have RMS norm 1
    info : dict (cost, iterations, seconds, method)
    """
    M = np.asarray(M_hat, float)
    G0 = _normalise_triplet(np.asarray(G0, float), M)
    shape = G0.shape
    t0 = time.perf_counter()
    if method == "lm":
        def fun(g):
            return triplet_residuals(g.reshape(shape), M, weights)

        def jac(g):
            return triplet_residuals(g.reshape(shape), M, weights, jac=True)[1]

        res = least_squares(fun, G0.ravel(), jac=jac, method="lm", xtol=tol, ftol=tol,
                            gtol=tol, max_nfev=max_iter or 100 * G0.size)
        G = res.x.reshape(shape)
        nit = int(res.nfev)
    elif method == "lbfgs":
        def fg(g):
            r, J = triplet_residuals(g.reshape(shape), M, weights, jac=True)
            return float(r @ r), 2.0 * (J.T @ r)

        res = minimize(fg, G0.ravel(), jac=True, method="L-BFGS-B",
                       options=dict(maxiter=max_iter or 20000, ftol=1e-15, gtol=1e-10,
                                    maxcor=30))
        G = res.x.reshape(shape)
        nit = int(res.nit)
    else:
        raise ValueError(f"unknown method {method!r}")
    G = _normalise_triplet(G, M)
    cost = triplet_cost(G, M, weights)
    return G, dict(cost=cost, iterations=nit, seconds=time.perf_counter() - t0,
                   method=method, cost0=triplet_cost(G0, M, weights))


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


def corrective_triplets(M_hat, K, mode="eig", sdp_solver="admm", refine="lm"):
    """Dai et al.'s corrective triplet(s) from the motion factor.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    K : int
    mode : {"eig", "columns"}
        See :func:`triplets_from_gram`.
    sdp_solver : {"admm", "cvxpy"}
    refine : {"lm", "lbfgs", None}

    Returns
    -------
    CorrectiveResult
    """
    M = np.asarray(M_hat, float)
    timings = {}
    t0 = time.perf_counter()
    A = constraint_matrix(M)
    basis, sv = solution_space(A, K)
    timings["solution_space"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Q, sdp_info = relaxed_gram(basis, K, solver=sdp_solver, return_info=True)
    timings["sdp"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    G_init = triplets_from_gram(Q, mode)
    Gs, costs, infos = [], [], []
    for G0 in G_init:
        if refine:
            G, inf = refine_triplet(G0, M, method=refine)
        else:
            G = _normalise_triplet(G0, M)
            inf = dict(cost=triplet_cost(G, M))
        Gs.append(G)
        costs.append(inf["cost"])
        infos.append(inf)
    timings["refine"] = time.perf_counter() - t0
    sdp_info = {k: v for k, v in sdp_info.items() if k != "x"}
    return CorrectiveResult(G=np.stack(Gs), G_init=G_init, Q=Q, costs=np.array(costs),
                            info=dict(sdp=sdp_info, refine=infos, singular_values=sv),
                            timings=timings)
