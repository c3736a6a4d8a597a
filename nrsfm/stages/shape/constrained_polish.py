"""Local solver that certifies a KKT point of the organic fit problem (C) (issue 17).

(C) of :mod:`nrsfm.stages.shape.constrained`: ``minimise ||X#||_a  s.t.
||W - R X||_F <= eps``. At a KKT point with the constraint active there is a multiplier
``lambda = 1 / mu > 0`` such that X is a stationary point of the penalised form

    E_mu(X) = 1/2 ||W - R X||_F^2 + mu ||X#||_a,      and  ||W - R X||_F = eps.       (K)

For a fixed factor rank r, ``X# = B C'`` (B: F x r, C: 3P x r) and the weighted nuclear
norm is replaced by its smooth variational form ``1/2 sum_i a_i (|B_i|^2 + |C_i|^2)`` (exact
at balanced stationary points for non-decreasing a: Iglesias, Olsson, Oernhag, ECCV 2020,
Sec. 3). This module solves (K) on that factorisation:

* inner: for a fixed mu, variable projection (C in closed form from one 3r x 3r system
  shared by every point) and L-BFGS on B in per-frame preconditioned variables (the C-step,
  the preconditioner and the balancing of the bilinear solver,
  :mod:`nrsfm.stages.shape.bilinear`, whose objective is (K) with fixed mu), to a
  relative gradient norm ``gtol`` (a first-order certificate, scale-free);
* outer: mu is the root of ``log ||W - R X(mu)|| = log eps``, found by secant steps in
  ``log mu`` from the multiplier estimate at the start (warm-started inner solves).

The start is the ADMM's end point of
:func:`nrsfm.stages.shape.constrained.organic_fit` (its rank r, at least 3K).
"""

from __future__ import annotations

import math

import numpy as np

from . import factors
from .factors import c_step, minimise

__all__ = ["factor_start", "multiplier_estimate", "rank_certificate", "solve_penalised",
           "solve_kkt"]




def _energy(B, C, Pi, Xi, Wf, Rf, reg):
    """Factored E_mu (K) at (B, C), its data residual ||W - R X|| and dE/dB (F, r)."""
    F = B.shape[0]
    X = (B @ C.T).reshape(F, 3, -1)
    res = np.einsum("fac,fcp->fap", Rf, X) - Wf
    G = np.einsum("fac,fap->fcp", Rf, res).reshape(F, -1)      # dE_data / dX#
    r2 = float(np.sum(res ** 2))
    E = 0.5 * r2 + 0.5 * float(reg @ (np.sum(B ** 2, axis=0) + np.sum(C ** 2, axis=0)))
    return E, math.sqrt(r2), G @ C + B * reg, G.T @ B + C * reg



def factor_start(X, r):
    """Balanced rank-r factors (B (F, r), C (3P, r)) of X# for X (F, 3, P): ``X# ~ B C'``."""
    F = X.shape[0]
    U, s, Vt = np.linalg.svd(X.reshape(F, -1), full_matrices=False)
    q = np.sqrt(s[:r])
    return U[:, :r] * q, Vt[:r].T * q


def multiplier_estimate(X, Wf, Rf, a):
    """mu of (K) by least squares at X (F, 3, P): ``G + mu U diag(a) V' ~ 0`` with G the data
    gradient and U, V the singular vectors of X# (the leading ones, as many as a has)."""
    F = X.shape[0]
    res = np.einsum("fac,fcp->fap", Rf, X) - Wf
    G = np.einsum("fac,fap->fcp", Rf, res).reshape(F, -1)
    U, s, Vt = np.linalg.svd(X.reshape(F, -1), full_matrices=False)
    r = min(a.size, s.size)
    D = (U[:, :r] * a[:r]) @ Vt[:r]
    mu = -float(np.vdot(G, D)) / max(float(np.vdot(D, D)), 1e-300)
    if not mu > 0:                              # X far from stationary: match the norms
        mu = float(np.linalg.norm(G)) / max(float(np.linalg.norm(D)), 1e-300)
    return mu


def solve_penalised(B, C, Pi, Xi, Wf, Rf, reg, gtol, max_iter):
    """Minimise the factored E_mu (reg = mu a) from (B, C) to relative gradient ``gtol``
    (:func:`nrsfm.stages.shape.factors.minimise`: variable projection, C eliminated, and
    L-BFGS on per-frame preconditioned B). Returns B, C, the relative gradient norm, the
    residual ||W - R X|| and the iteration count."""
    F = B.shape[0]
    W2 = Wf.reshape(2 * F, -1)

    def reduced(B):
        C = c_step(B, Rf, W2, reg)
        return C, _energy(B, C, Pi, Xi, Wf, Rf, reg)

    B, C, rel, n_iter = minimise(B, reduced, Pi, reg, gtol, max_iter)
    res = _energy(B, C, Pi, Xi, Wf, Rf, reg)[1]
    return B, C, rel, res, max(n_iter, 1)


def solve_kkt(X0, Wf, Rf, a, eps, r, *, gtol=1e-8, rtol=1e-5, max_outer=30, max_iter=20000):
    """A KKT point of (C) restricted to rank(X#) <= r, from X0 (F, 3, P): (K) solved by
    secant steps on log mu (module docstring), each inner solve warm-started.

    Returns X (F, 3, P), mu, the final relative gradient norm, the residual, and the
    history (mu, residual, relative gradient, inner iterations) per outer step.
    """
    F = X0.shape[0]
    Pi = Rf.transpose(0, 2, 1) @ Rf
    Xi = np.einsum("fac,fap->fcp", Rf, Wf).reshape(F, -1)
    ar = np.asarray(a[:r], dtype=float)
    B, C = factor_start(X0, r)
    mu = multiplier_estimate(X0, Wf, Rf, ar)
    hist = []
    used = 0
    for _ in range(max_outer):
        B, C, rel, res, it = solve_penalised(B, C, Pi, Xi, Wf, Rf, mu * ar, gtol,
                                             max_iter - used)
        used += it
        hist.append((mu, res, rel, it))
        err = math.log(max(res, 1e-300) / eps)
        if abs(err) <= rtol or used >= max_iter:
            break
        slope = 1.0
        if len(hist) > 1:
            dm = math.log(hist[-1][0] / hist[-2][0])
            dr = math.log(hist[-1][1] / hist[-2][1])
            if dm != 0 and dr / dm > 0:
                slope = min(max(dr / dm, 0.1), 10.0)
        mu *= math.exp(-err / slope)
    return (B @ C.T).reshape(F, 3, -1), mu, rel, res, np.asarray(hist)


def rank_certificate(X, Wf, Rf, a, mu, r):
    """``sigma_1(P_U' G P_V') / (mu a_{r+1})`` at X (F, 3, P) of rank r: at most 1 when a
    rank-r stationary point of (K) is also stationary without the rank cap (adding a
    rank-one term along the residual's largest singular pair outside X#'s row and column
    spaces does not lower E_mu to first order). G is the data gradient ``R'(R X - W)``;
    U, V the r leading singular vectors of X#. inf when r is already the full rank."""
    F = X.shape[0]
    if r >= min(F, X[0].size) or r >= len(a):
        return float("inf")
    Pi = Rf.transpose(0, 2, 1) @ Rf
    Xi = np.einsum("fac,fap->fcp", Rf, Wf).reshape(F, -1)
    B, C = factor_start(X, r)
    return factors.rank_certificate(B, C, Pi, Xi, np.array([mu * float(a[r])]))[0]
