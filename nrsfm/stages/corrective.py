"""Corrective triplets G^k (3K x 3) from the rank-3K motion factor (Dai et al., CVPR 2012).

Every valid triplet G satisfies, for each frame f with 2 x 3K block ``M_f`` (rows m_1, m_2),
``m_1 Q m_1' = m_2 Q m_2'`` and ``m_1 Q m_2' = 0`` with ``Q = G G'`` of rank 3
(``M_f G = c_f R_f[:2]``, an orthographic camera times a scalar).

The search (:func:`search_triplet`) starts from a convex relaxation of those constraints
(:mod:`nrsfm.stages.relaxation`) and from seeded random triplets, refines each by
Levenberg-Marquardt on Dai's cost ``sum_f (1 - |r2|^2/|r1|^2)^2 + 4 sum_f ((r1.r2)/|r1|^2)^2``
(r1, r2 the rows of ``M_f G``; :func:`refine_triplet`), and stops once the lowest cost has
been reached by two starts.

Why these starts and this rule: ``docs/studies/rotations.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from .relaxation import penalized_gram, triplets_from_gram

__all__ = ["TripletSearch", "refine_triplet", "search_triplet", "triplet_cost"]


_EPS = 1e-150  # floor of |r1|^2 (keeps |r1|^4 representable)
LAM0 = 1e-3  # initial LM damping, times max diag(J'J)


class _Frames:
    """What every evaluation of Dai's cost on one ``M_hat`` shares: its x and y rows
    ``m1``, ``m2`` (F, 3K) as contiguous arrays, stacked per frame for the Jacobian, and
    the frame weights (``sqrt_w`` in the residuals, ``w`` in ``J'r``)."""

    def __init__(self, M_hat, weights=None):
        M = np.asarray(M_hat, float)
        self.m1, self.m2 = np.ascontiguousarray(M[0::2]), np.ascontiguousarray(M[1::2])
        self.U = np.stack([self.m1, self.m2], axis=2)[:, None]  # (F, 1, 3K, 2)
        self.w = None if weights is None else np.asarray(weights, float)
        self.sqrt_w = None if weights is None else np.sqrt(self.w)

    def products(self, G):
        """(a, b, |a|^2, |b|^2, a.b) per frame: ``a = m1 G``, ``b = m2 G``."""
        a, b = self.m1 @ G, self.m2 @ G
        na = np.maximum(np.einsum("fi,fi->f", a, a), _EPS)
        return a, b, na, np.einsum("fi,fi->f", b, b), np.einsum("fi,fi->f", a, b)

    def residuals(self, p):
        """The 2F residuals ``[1 - |b|^2/|a|^2, 2 a.b/|a|^2]`` (times sqrt(w))."""
        a, b, na, nb, ab = p
        r1, r2 = 1.0 - nb / na, 2.0 * ab / na
        if self.sqrt_w is not None:
            r1, r2 = r1 * self.sqrt_w, r2 * self.sqrt_w
        r = np.empty(2 * a.shape[0])
        r[0::2], r[1::2] = r1, r2
        return r

    def jacobian(self, p):
        """The Jacobian (2F, 9K) of the residuals with respect to ``G.ravel()``: frame f's
        rows ``m1 (c1 a)' + m2 (c2 b)'`` and ``m1 (c3 b + c4 a)' + m2 (c3 a)'`` with c1 =
        2|b|^2/|a|^4, c2 = -2/|a|^2, c3 = 2/|a|^2, c4 = -4 a.b/|a|^4."""
        a, b, na, nb, ab = p
        F = a.shape[0]
        inv = 1.0 / na
        c1, c2, c3, c4 = 2.0 * nb * inv * inv, -2.0 * inv, 2.0 * inv, -4.0 * ab * inv * inv
        if self.sqrt_w is not None:
            w = self.sqrt_w
            c1, c2, c3, c4 = c1 * w, c2 * w, c3 * w, c4 * w
        C = np.empty((F, 2, 2, 3))
        C[:, 0, 0], C[:, 0, 1] = c1[:, None] * a, c2[:, None] * b
        C[:, 1, 0], C[:, 1, 1] = c3[:, None] * b + c4[:, None] * a, c3[:, None] * a
        return np.matmul(self.U, C).reshape(2 * F, self.m1.shape[1] * a.shape[1])

    def gradient(self, p):
        """``J' r`` (3K, 3) without forming J (the coefficients of :meth:`jacobian`)."""
        a, b, na, nb, ab = p
        inv = 1.0 / na
        r1, r2 = 1.0 - nb * inv, 2.0 * ab * inv
        if self.w is not None:
            r1, r2 = r1 * self.w, r2 * self.w
        c1, c2, c3, c4 = 2.0 * nb * inv * inv, -2.0 * inv, 2.0 * inv, -4.0 * ab * inv * inv
        A = (r1 * c1 + r2 * c4)[:, None] * a + (r2 * c3)[:, None] * b
        B = (r1 * c2)[:, None] * b + (r2 * c3)[:, None] * a
        return self.m1.T @ A + self.m2.T @ B


def triplet_residuals(G, M_hat, weights=None, jac=False):
    """The residuals r (2F,) of Dai's cost, ``[1 - |r2|^2/|r1|^2, 2 r1.r2/|r1|^2]`` per
    frame, of G (3K, 3) on M_hat (2F, 3K) with per-frame ``weights`` (F,), and with ``jac``
    the Jacobian (2F, 9K) with respect to ``G.ravel()``."""
    frames = _Frames(M_hat, weights)
    p = frames.products(np.asarray(G, float))
    r = frames.residuals(p)
    return (r, frames.jacobian(p)) if jac else r


def triplet_cost(G, M_hat, weights=None):
    """Dai's cost ``sum_f (1 - |r2|^2/|r1|^2)^2 + 4 sum_f ((r1.r2)/|r1|^2)^2``."""
    r = triplet_residuals(G, M_hat, weights)
    return float(r @ r)


def _normalise_triplet(G, M_hat):
    """Fix the scale gauge: rows of M_f G have RMS norm 1 over frames."""
    a = np.asarray(M_hat) @ G
    s = np.sqrt(np.mean(np.einsum("ri,ri->r", a, a)))
    return G / s if s > 0 else G


def _damped_step(A, D, lam, grad):
    """``-(A + lam diag(D))^-1 grad`` by one Cholesky solve (LAPACK ``posv``; A = J'J is
    positive semi-definite and D > 0), or None where rounding leaves it indefinite."""
    H = A.copy()
    H.flat[:: H.shape[0] + 1] += lam * D
    _, step, info = lapack.dposv(H, -grad, lower=1, overwrite_a=1)
    return step if info == 0 else None


def _levenberg_marquardt(G0, M, weights, max_iter, tol, lam0=LAM0, reuse=None):
    """Levenberg-Marquardt on Dai's residuals (normal equations, Nielsen's damping rule):
    (G, cost, iterations). ``reuse``: after an accepted step shorter than ``reuse`` |G| that
    lowered the cost by less than ``reuse`` of it, J'J is kept and only the (exact) gradient
    recomputed: near a minimum J'J hardly changes, and the iterate reaches the same point.
    """
    shape = G0.shape
    frames = _Frames(M, weights)
    g = G0.ravel().copy()
    p = frames.products(G0)
    r, J = frames.residuals(p), frames.jacobian(p)
    cost = float(r @ r)
    A, grad = J.T @ J, J.T @ r
    lam = lam0 * float(np.max(np.diag(A))) if A.size else 1.0
    nu = 2.0
    it = 0
    for it in range(1, max_iter + 1):
        D = np.diag(A).copy()
        D = np.maximum(D, 1e-12 * max(D.max(), 1e-300))
        step = _damped_step(A, D, lam, grad)
        if step is None:
            lam *= nu
            nu *= 2.0
            if nu > 1e15 or lam > 1e100:
                break
            continue
        g_new = g + step
        p_new = frames.products(g_new.reshape(shape))
        r_new = frames.residuals(p_new)
        c_new = float(r_new @ r_new)
        if np.isfinite(c_new) and c_new < cost:
            pred = -(step @ grad) - 0.5 * step @ (A @ step)
            rho = (cost - c_new) / max(2.0 * pred, 1e-300)
            done = (cost - c_new) <= tol * cost or c_new < 1e-28
            keep = (
                reuse is not None
                and (cost - c_new) <= reuse * cost
                and np.linalg.norm(step) <= reuse * np.linalg.norm(g_new)
            )
            g, cost, r = g_new, c_new, r_new
            if keep:
                grad = frames.gradient(p_new).ravel()
            else:
                J = frames.jacobian(p_new)
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


def refine_triplet(G0, M_hat, weights=None, max_iter=500, tol=1e-10, lam0=LAM0, reuse=None):
    """Minimise Dai's cost over G (3K, 3) from ``G0`` on M_hat (2F, 3K) by
    Levenberg-Marquardt with the analytic Jacobian, until the relative decrease of the cost
    is below ``tol``. ``weights`` (F,): per-frame weights (0 drops a frame); ``lam0``: the
    initial damping times max diag(J'J); ``reuse``: see ``_levenberg_marquardt``.

    Returns
    -------
    G : (3K, 3) ndarray, normalised so that the rows of M_f G have RMS norm 1
    cost : float
    iterations : int
    """
    M = np.asarray(M_hat, float)
    if weights is not None:
        weights = np.asarray(weights, float)
        keep = weights > 0
        if not keep.all():  # drop zero-weight frames outright
            M = M[np.repeat(keep, 2)]
            weights = weights[keep]
    G0 = _normalise_triplet(np.asarray(G0, float), M)
    G, _, nit = _levenberg_marquardt(G0, M, weights, max_iter, tol, lam0, reuse)
    G = _normalise_triplet(G, M)
    return G, triplet_cost(G, M, weights), nit


@dataclass
class TripletSearch:
    """Output of :func:`search_triplet`: the distinct minima of Dai's cost it found.

    ``G`` (m, 3K, 3) and ``costs`` (m,): the refined triplets of the distinct minima, lowest
    cost first; ``starts``: the first start that reached each (``relaxed(lam=...)`` or
    ``randomN``) and ``counts`` how many did; ``history``: every start's (name, cost,
    iterations); ``n_random``: random starts refined; ``stopped``: ``"hits"`` or
    ``"max_starts"``; ``miss_bound``: ``3 / n_random``, with 95 % confidence the attraction
    probability of a better minimum never reached (rule of three; 1 with no random start);
    ``Q``: the last relaxed Gram matrix; ``seconds``.
    """

    G: np.ndarray
    costs: np.ndarray
    starts: list
    counts: list
    history: list
    n_random: int
    stopped: str
    miss_bound: float
    Q: np.ndarray
    seconds: float = 0.0

    @property
    def n_starts(self):
        return len(self.history)

    @property
    def hits(self):
        """Starts that reached the best minimum."""
        return self.counts[0]


#: penalties of :func:`penalized_gram` tried, in order, by the search
SEARCH_LAMBDAS = (1e1, 1e2)
#: the relaxation's tolerance in the search: its Gram matrix is only a start that the
#: refinement takes to the minimum
SEARCH_SDP_TOL = 1e-5


def search_triplet(
    M_hat, K, seed=0, hits=2, max_starts=40, lams=SEARCH_LAMBDAS, rtol=1e-5, max_iter=200
):
    """Multistart minimisation of Dai's cost with a stopping rule.

    Starts, in a fixed order: the relaxation (:func:`penalized_gram`) at each penalty in
    ``lams``, then Gaussian starts from ``numpy.random.default_rng(seed)``, each refined on
    all frames. Stops once the lowest cost so far has been reached by ``hits`` starts (equal
    to relative ``rtol``: the same minimum) or after ``max_starts``. A better basin never
    reached by n random starts has attraction probability below 3 / n with 95 % confidence
    (rule of three); two hits mean the best minimum was found again by a start that did not
    know it.

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
    TripletSearch
    """
    t0 = time.perf_counter()
    M = np.asarray(M_hat, float)
    n = M.shape[1]  # 3K, or the determined rank r
    rng = np.random.default_rng(seed)
    minima = []  # [cost, G, name, count]
    history = []
    Q = None

    def add(name, G0):
        G, c, nit = refine_triplet(G0, M, max_iter=max_iter, reuse=1e-3)
        c = c if np.isfinite(c) else np.inf
        history.append((name, float(c), int(nit)))
        for mn in minima:
            if abs(mn[0] - c) <= rtol * max(abs(mn[0]), 1e-12):
                mn[3] += 1  # same minimum: keep the first start's triplet (its
                return  # gauge), so round-off cannot switch between them
        minima.append([c, G, name, 1])

    def done():
        return bool(minima) and min(minima, key=lambda mn: mn[0])[3] >= hits

    stopped, n_random, cache = "max_starts", 0, {}
    for lam in lams:
        Q = penalized_gram(M, K, lam=lam, tol=SEARCH_SDP_TOL, _cache=cache)
        add(f"relaxed(lam={lam:g})", triplets_from_gram(Q))
        if done():
            stopped = "hits"
            break
    while stopped != "hits" and len(history) < max_starts:
        add(f"random{n_random}", rng.standard_normal((n, 3)))
        n_random += 1
        if done():
            stopped = "hits"
    minima.sort(key=lambda mn: mn[0])
    return TripletSearch(
        G=np.stack([mn[1] for mn in minima]),
        costs=np.array([mn[0] for mn in minima]),
        starts=[mn[2] for mn in minima],
        counts=[mn[3] for mn in minima],
        history=history,
        n_random=n_random,
        stopped=stopped,
        miss_bound=min(1.0, 3.0 / n_random) if n_random else 1.0,
        Q=Q,
        seconds=time.perf_counter() - t0,
    )
