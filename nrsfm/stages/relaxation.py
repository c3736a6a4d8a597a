"""The convex relaxation that gives the triplet search its first starts (Dai et al.'s
constraints on Q = G G', penalised instead of imposed), and the triplets a Gram matrix
gives. Used by :mod:`nrsfm.stages.corrective`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import blas, lapack

__all__ = ["constraint_matrix", "penalized_gram", "triplets_from_gram", "vech_index"]


def vech_index(n):
    """Row and column indices (i <= j) of the upper triangle of an n x n matrix."""
    return np.triu_indices(n)


def constraint_matrix(M_hat):
    """Dai's 2F linear equations on vech(Q): A (2F, n(n+1)/2) for M_hat (2F, n = 3K), rows
    ``m_1 Q m_1' - m_2 Q m_2'`` and ``m_1 Q m_2'`` of each frame as functions of the upper
    triangle of Q (off-diagonal entries counted twice)."""
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


def _cached(cache, key, make):
    """``cache[key]``, made by ``make()`` on first use."""
    if key not in cache:
        cache[key] = make()
    return cache[key]


def _system_factor(AtA, scale, rho):
    """Lower Cholesky factor of ``scale At'At + rho I`` (rho > 0: positive definite); a
    tenth of the time of the eigendecomposition of At'At at 3K = 36."""
    H = scale * AtA
    H[np.diag_indices_from(H)] += rho
    L, info = lapack.dpotrf(H, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"the relaxation's system is not positive definite ({info})")
    return np.asfortranarray(L)


def _solve(L, v):
    """``(L L')^-1 v`` by two triangular solves."""
    return blas.dtrsv(L, blas.dtrsv(L, v, lower=1), lower=1, trans=1)


def _frobenius(A):
    """``||A||_F`` (as ``numpy.linalg.norm``, without its dispatch)."""
    a = A.ravel()
    return math.sqrt(a @ a)


#: over-relaxation of the ADMM's z-update (Boyd et al. 2011, sec. 3.4.3)
OVER_RELAXATION = 1.5
#: the ADMM's first step size, times the trace weight ``a``
RHO_START = 1.0 / 3.0


def penalized_gram(M_hat, K, lam=1e2, max_iter=3000, tol=1e-7, _cache=None):
    """A convex relaxation that lands near the best triplet on the benchmark.

    ``minimise  a trace(Q) + (lam / F) ||A vech(Q)||^2   s.t.  Q PSD,  <M'M, Q> = 2F``

    with ``a = trace(M'M) / (2F 3K)`` (both terms dimensionless). Dai's constraint residual
    is penalised instead of imposed (their exact intersection with the PSD cone is empty on
    real data), the mean squared camera scale is fixed to 1, and the trace pushes Q to low
    rank. Solved by ADMM: the Cholesky factor of the x-update's system whenever the step
    size changes (residual balancing from ``RHO_START a``), two triangular solves and a
    3K x 3K eigendecomposition of the over-relaxed x per iteration. ``_cache`` (a dict)
    carries the constraints and the last state from one penalty to the next (the same M).

    Returns
    -------
    Q : (3K, 3K) ndarray, symmetric PSD
    """
    cache = {} if _cache is None else _cache
    M = np.asarray(M_hat, float)
    F, n = M.shape[0] // 2, M.shape[1]  # 3K, or the determined rank r
    A = _cached(cache, "A", lambda: constraint_matrix(M))  # the same M for every lam
    C = M.T @ M
    a = np.trace(C) / (2.0 * F * n)
    iu = vech_index(n)
    dw = np.where(iu[0] == iu[1], 1.0, np.sqrt(2.0))  # vec_w(Q) = dw * vech(Q)
    At = _cached(cache, "At", lambda: A / dw)  # A vech(Q) = At vec_w(Q)
    t = (iu[0] == iu[1]).astype(float)  # trace(Q) = t . vec_w(Q)
    c = C[iu] * dw  # <C, Q> = c . vec_w(Q)
    AtA = _cached(cache, "gram", lambda: At.T @ At)  # independent of the penalty
    if "warm" in cache:  # the previous penalty's state: fewer iterations
        Z, U, rho = np.array(cache["warm"][0]), np.array(cache["warm"][1]), cache["warm"][2]
    else:  # a feasible, PSD start; a: the dual's scale
        Z, U, rho = np.eye(n) * (2.0 * F / np.trace(C)), np.zeros((n, n)), a * RHO_START
    upper = iu[0] * n + iu[1]  # vech entries in Q.ravel()
    sym = np.empty(n * n, dtype=np.intp)  # Q.ravel() = vech(Q)[sym]
    sym[upper] = sym[iu[1] * n + iu[0]] = np.arange(upper.size)
    Hc = None
    for it in range(1, max_iter + 1):
        if Hc is None:
            L = _system_factor(AtA, 2.0 * lam / F, rho)
            Hc = _solve(L, c)  # H^-1 c
            cHc = c @ Hc
        rhs = rho * (np.take(Z - U, upper) * dw) - a * t
        y = _solve(L, rhs)
        mu = (c @ y - 2.0 * F) / cHc
        v = (y - mu * Hc) / dw
        Qm = v[sym].reshape(n, n)  # the symmetric matrix of vech v
        Qh = OVER_RELAXATION * Qm + (1.0 - OVER_RELAXATION) * Z  # over-relaxed x
        w, E = np.linalg.eigh(Qh + U)
        Z_old = Z
        Z = (E * np.clip(w, 0, None)) @ E.T
        r = Qm - Z
        U += Qh - Z
        rn, sn, scale = _frobenius(r), _frobenius(Z - Z_old), max(_frobenius(Z), 1e-300)
        if rn < tol * scale and sn < tol * scale:
            break
        if it % 10 == 0:  # residual balancing
            if rn > 10 * sn:
                rho *= 2.0
                U /= 2.0
                Hc = None
            elif sn > 10 * rn:
                rho /= 2.0
                U *= 2.0
                Hc = None
    cache["warm"] = (Z, U, rho)
    return 0.5 * (Z + Z.T)


def triplets_from_gram(Q):
    """The triplet ``V_3 sqrt(L_3)`` (3K, 3) of a (relaxed) Gram matrix Q (3K, 3K): its
    top-3 eigenpairs (Dai et al.)."""
    Q = 0.5 * (np.asarray(Q, float) + np.asarray(Q, float).T)
    w, V = np.linalg.eigh(Q)
    w, V = w[::-1][:3], V[:, ::-1][:, :3]
    return V * np.sqrt(np.clip(w, 0, None))
