"""The default shape solver: the weighted nuclear norm in factored (bilinear) form.

With ``X# = Phi(X) = B C'`` (B: F x r, C: 3P x r) the shape minimises

    E(B, C) = 1/2 sum_f ||W_f - R_f X_f||_F^2 + mu/2 sum_i a_i (|B_i|^2 + |C_i|^2)     (*)

For non-decreasing weights a the regulariser's minimum over the factorisations of X# is the
weighted nuclear norm ``mu sum_i a_i sigma_i(X#)`` (Iglesias, Olsson, Oernhag, ECCV 2020,
Sec. 3): (*) is Eq. (8)/(10) at rank r, smooth, and its stationary points are certified by
the gradient.

* Weights (:func:`bilinear_weights`): ``a_i = sigma_1 / sigma_i`` of X_init# (Eq. 9 up to a
  factor that goes into mu), ``a_1 = 0`` for ``organic`` (Eq. 10, N = 1); ones for
  ``nuclear`` (Eq. 7).
* Balance from W alone: ``mu = max(mu_factor noise (sqrt(F) + sqrt(3P)), mu_noise noise^2
  (F + 2P) / sigma_1)``, noise the RMS of W beyond rank 3K; the second term has the form of
  optimal singular value shrinkage (Gavish and Donoho 2017). Noise-free rank-3K W: mu = 0.
* Rank (:func:`prior_rank`): K where W is of rank at most 3K (the rank-K model);
  otherwise from 3K, the columns the prior does not want dropped and columns added while
  the rank certificate (:func:`.factors.rank_certificate`) wants one. A rank-K fit that is
  not unique warns (``W-shape-not-unique``) and raises mu to ``min_mu``.
* Scale-free: W is divided by ``||W||_F`` inside and mu scales with W.
* Solver: variable projection (C in closed form) and L-BFGS on B from the closed-form rank-K
  start (:mod:`.closed_form`), every weight with a ridge ``RIDGE`` (the least-norm answer
  along directions W leaves open); stops at a relative gradient ``gtol``.

Why these settings: ``docs/studies/shape.md``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import ClassVar, Optional

import numpy as np

from ...noise import noise_from_singular_values
from ...validation import check_integer, check_positive, check_shape_inputs
from ...warnings_catalog import text
from ..measurement import left_singular
from ..rotations.subspace import DETERMINED_RTOL
from .closed_form import NULLSPACE_GAP_MIN, nullspace_coefficients
from .common import ShapeResult, check_prior
from .factors import c_step, minimise, objective, project, rank_certificate
from .factors import reduced_objective, relative_gradient, viewing_directions

__all__ = ["BilinearSettings", "bilinear_weights", "prior_rank", "solve_bilinear"]

#: W counts as of rank at most 3K when s_3K+1 / s_3K is below this (rank-K shapes under
#: 2 - 10 % noise: 0.06 - 0.27; the MoCap shapes: 0.72 - 0.92)
GAP_MAX = 0.5
#: at most this many fits, each at a rank from the one before
MAX_RANK_STEPS = 8
#: columns whose singular value falls to this fraction of the largest are dropped while the
#: prior chooses the rank
PRUNE_RTOL = 1e-9
#: the prior's rank is reached when the rank certificate is at most 1 + this
CERTIFICATE_SLACK = 1e-3


@dataclass(frozen=True)
class BilinearSettings:
    """The factored weighted nuclear norm (*) (``shape_solver="bilinear"``, the default).

    Attributes
    ----------
    rank : int or None
        Factor rank r; None: from W and the prior (:func:`prior_rank`).
    mu_factor, mu_noise : float
        The clean-data and the noise term of mu (module docstring); mu is the larger.
    mu : float or None
        Override ``mu``, in the units of the W the solver is given (through
        :func:`nrsfm.reconstruct`: ``W / scale``, ``scale = ||W||_F / 170``).
    min_mu : float
        Where the rank-K fit is not unique, mu is raised to ``min_mu ||W||_F`` (a warning).
    gtol : float
        Stop when the relative gradient norm is at most gtol.
    max_iter : int
        Cap on L-BFGS iterations (0: the start only).

    Raises
    ------
    ValueError
        A value out of range (named in the message).
    """

    name: ClassVar[str] = "bilinear"
    rank: Optional[int] = None
    mu_factor: float = 0.01
    mu_noise: float = 5.0
    mu: Optional[float] = None
    min_mu: float = 1e-5
    gtol: float = 1e-8
    max_iter: int = 3000

    def __post_init__(self):
        if self.rank is not None:
            check_integer(self.rank, "rank", minimum=1)
        for name in ("mu_factor", "mu_noise", "min_mu", "gtol"):
            check_positive(name, getattr(self, name), strict=False)
        if self.mu is not None:
            check_positive("mu", self.mu, strict=False)
        check_integer(self.max_iter, "max_iter", minimum=0)

    def solve(self, W, R, K, prior, progress=None):
        return solve_bilinear(W, R, K, prior, self, progress)


def bilinear_weights(sigma, r, prior):
    """Dimensionless weights ``a`` (r,) of (*) from the singular values of ``X_init#``.

    ``organic``: 0, sigma_1/sigma_2, ..., sigma_1/sigma_r; ``weighted``: sigma_1/sigma_i;
    ``nuclear``: ones. Non-decreasing in every case.
    """
    sigma = np.asarray(sigma, dtype=float)[:r]
    if prior == "nuclear":
        return np.ones(r)
    a = sigma[0] / np.maximum(sigma, sigma[0] * 1e-12)
    if prior == "organic":
        a[0] = 0.0
    elif prior != "weighted":
        raise ValueError(f"unknown shape prior {prior!r}")
    return a


def _singular_values(A):
    """Singular values of A (m, n) from the Gram matrix of its shorter side (the small ones
    lose relative accuracy, which the weights of (*) do not need)."""
    G = A @ A.T if A.shape[0] <= A.shape[1] else A.T @ A
    ev = np.linalg.eigvalsh(G)[::-1]
    return np.sqrt(np.maximum(ev, 0.0))


def prior_rank(sw, K, F, P):
    """(first rank r, why) from W's singular values ``sw``: ``"W of rank <= 3K"``, r = K,
    where W's numerical rank is below 3K or ``s_3K+1 / s_3K < GAP_MAX``; else ``"prior"``,
    r = min(3K, F, 3P), from which the prior drops and the rank certificate adds columns."""
    sw = np.asarray(sw, float)
    numerical_rank = int(np.sum(sw > DETERMINED_RTOL * sw[0]))
    gap = sw[3 * K] / sw[3 * K - 1] if sw.size > 3 * K and sw[3 * K - 1] > 0 else 0.0
    if numerical_rank < 3 * K or gap < GAP_MAX:
        return K, "W of rank <= 3K"
    return min(3 * K, F, 3 * P), "prior"


#: ridge added to every weight of (*) (normalised units, ||W||_F = 1): where the data leave
#: X# free along some directions that the organic prior's first weight (0) does not bound
#: (shark's noise-free W of rank 5 at r = 3), the answer is the one of least norm there, the
#: same at every scale of W; it moves exact answers by about 1e-12
RIDGE = 1e-12
#: the start's share of the in-plane residual of the rank-K fit (:meth:`_Problem.start`):
#: it only orients the columns beyond K
START_RESIDUAL = 1e-3


def solve_bilinear(W, R, K, prior="organic", settings=None, progress=None):
    """Minimise (*) (module docstring) to a stationary point: the rank rule, then L-BFGS
    (:func:`.factors.minimise`) at each rank.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements, any units.
    R : (F, 3, 3) or (F, 2, 3) ndarray
    K : int
        Number of shape bases.
    prior : {"organic", "weighted", "nuclear"}
        Weights ``a``, see :func:`bilinear_weights`.
    settings : BilinearSettings, optional
    progress : callable(str) or None

    Returns
    -------
    ShapeResult
        In W's units.

    Raises
    ------
    ValueError
        Bad shapes, a zero W, an unknown prior, a given rank above ``min(F, 3P)``.
    """
    st = BilinearSettings() if settings is None else settings
    pb = _Problem(W, R, K, check_prior(prior), st)
    if st.rank is None:
        r, why = prior_rank(pb.sw, K, pb.F, pb.P)
    else:
        r, why = st.rank, "given"
        if not 1 <= r <= pb.r_max:
            raise ValueError(f"rank must be in [1, min(F, 3P)] = [1, {pb.r_max}]; got {r!r}")
    say = progress if callable(progress) else (lambda msg: None)
    ranks, n_total, warm, prune = [], 0, None, why == "prior"
    for _ in range(MAX_RANK_STEPS):
        fit = pb.fit(r, warm, prune)
        ranks.append(r)
        n_total += fit["n_iter"]
        grow = prune and fit["cert"] > 1.0 + CERTIFICATE_SLACK  # nan: full rank
        say(
            f"shape (bilinear, {prior}, r={r}): {fit['n_iter']} iterations, relative "
            f"gradient {fit['rel']:.2e}, rank {fit['live']}, certificate {fit['cert']:.4g}"
        )
        if not grow:
            break
        B_next = np.column_stack([fit["B"], fit["wanted"]])  # the wanted columns added
        if B_next.shape[1] > r:  # the cap is too low: doubled (or more)
            r = min(max(2 * r, B_next.shape[1]), pb.r_max)
        warm = B_next[:, :r]
    return pb.result(fit, ranks, why, n_total)


class _Problem:
    """(*) on the normalised W (``||W||_F = 1``) of one solve: its data, the start's SVD
    (shared by the ranks), the balance mu and the iteration record."""

    def __init__(self, W, R, K, prior, st):
        W, self.Rf, self.F, self.P, self.K = check_shape_inputs(W, R, K)
        F, P = self.F, self.P
        self.prior, self.st, self.scale = prior, st, float(np.linalg.norm(W))
        if not self.scale > 0:
            raise ValueError("W is zero: nothing to reconstruct")
        self.Wn = W / self.scale
        self.Uw, self.sw, _ = left_singular(self.Wn)  # one thin SVD (Gram matrix if wide)
        self.Xi3 = self.Rf.transpose(0, 2, 1) @ self.Wn.reshape(F, 2, P)
        self.Xi = self.Xi3.reshape(F, 3 * P)
        self.sigma = _singular_values(self.Xi)
        self.Pi = self.Rf.transpose(0, 2, 1) @ self.Rf
        self.n = viewing_directions(self.Rf)
        self.r_max, self.gtol, self.max_iter = min(F, 3 * P), st.gtol, st.max_iter
        self.hist = {"cost": [], "data_term": [], "grad_norm": []}
        self.noise = noise_from_singular_values(self.sw, self.Wn.shape, K)
        self.svd = None

    def _balance(self):
        """mu in normalised units, from the noise level (module docstring) or as given."""
        st, F, P = self.st, self.F, self.P
        if st.mu is not None:
            return float(st.mu) / self.scale
        return max(
            st.mu_factor * self.noise * (math.sqrt(F) + math.sqrt(3 * P)),
            st.mu_noise * self.noise**2 * (F + 2 * P) / max(self.sigma[0], 1e-300),
        )

    def closed_form(self):
        """The rank-K start B0 (:mod:`.closed_form`) and its nullspace gap; where the gap is
        at rounding level, a RuntimeWarning and ``mu >= min_mu``."""
        K, st = self.K, self.st
        B0, ev = nullspace_coefficients(self.Uw, self.sw, self.Rf, K)
        self.gap = float(ev[K]) if ev.size > K else float("nan")
        if not self.gap > NULLSPACE_GAP_MIN:
            message = (
                text("W-shape-not-unique", gap=self.gap, K=K, min_mu=st.min_mu)
                if st.mu is None
                else text("W-shape-not-unique-mu-given", gap=self.gap, K=K, mu=st.mu)
            )
            warnings.warn(message, RuntimeWarning, stacklevel=4)
            if st.mu is None:
                self.mu = max(self.mu, st.min_mu)
        return B0

    def start(self, r):
        """B0 (F, r) for r > K: the leading left singular vectors of the closed-form rank-K
        fit X_K plus ``START_RESIDUAL`` of its in-plane residual, ``X_K + e (X_init - Pi
        X_K)`` (the directions the fit leaves for the columns beyond K)."""
        if self.svd is None:
            B, _ = nullspace_coefficients(self.Uw, self.sw, self.Rf, self.K)
            X_K = B @ c_step(B, self.Rf, self.Wn, np.zeros(self.K)).T
            X0 = X_K + START_RESIDUAL * (self.Xi - project(self.Pi, X_K))
            self.svd = np.linalg.svd(X0, full_matrices=False)[:2]
        U, s = self.svd
        return U[:, :r] * np.sqrt(s[:r])

    def reduced(self, B):
        return reduced_objective(B, self.n, self.Pi, self.Xi, 1.0, self.reg[: B.shape[1]])

    def record(self, B, C, values):
        E, data, gB, gC = values
        self.hist["cost"].append(E)
        self.hist["data_term"].append(data)
        self.hist["grad_norm"].append(relative_gradient(B, C, gB, gC))

    def fit(self, r, warm, prune):
        """(*) at rank r from ``warm`` or its start: the factors and their measures (a dict).
        With ``prune``, the columns that die are dropped and the rank certificate of the
        next weights (:func:`.factors.rank_certificate`) says which columns are wanted."""
        Xi = self.Xi
        a = bilinear_weights(self.sigma, r, self.prior)
        self.mu, self.gap = self._balance(), float("nan")
        B0 = self.closed_form() if r == self.K else None
        self.reg = self.mu * a + RIDGE
        if warm is not None:
            B0 = warm
        else:
            B0 = self.start(r) if B0 is None else B0
            B0 = B0 / np.linalg.norm(B0, axis=0) * math.sqrt(max(self.sigma[0], 1e-300) / r)
        B, C, _, n_iter = minimise(B0, self, PRUNE_RTOL if prune else None)
        live = B.shape[1]
        rel = relative_gradient(B, C, *objective(B, C, self.Pi, Xi, 1.0, self.reg[:live])[2:])
        cert, wanted = float("nan"), None
        if prune and live < self.r_max:  # the weights of the columns not used
            reg_next = (
                self.mu * bilinear_weights(self.sigma, min(2 * live, self.r_max), self.prior)[live:]
            )
            cert, s_g, U = rank_certificate(B, C, self.Pi, Xi, reg_next)
            gain = s_g - reg_next[: s_g.size] * (1.0 + CERTIFICATE_SLACK)
            n = int(np.argmin(gain > 0)) if not np.all(gain > 0) else gain.size
            wanted = U[:, :n] * np.sqrt(np.maximum(gain[:n], 0.0))  # at first-order size
        return dict(B=B, C=C, n_iter=n_iter, rel=rel, r=r, live=live, cert=cert, wanted=wanted)

    def result(self, fit, ranks, rank_rule, n_iter):
        """The ShapeResult of the last fit, in W's units."""
        B, C, F, P, scale = fit["B"], fit["C"], self.F, self.P, self.scale
        E, data, _, _ = objective(B, C, self.Pi, self.Xi, 1.0, self.reg[: fit["live"]])
        res = self.Wn.reshape(F, 2, P) - np.einsum(
            "fac,fcp->fap", self.Rf, (B @ C.T).reshape(F, 3, P)
        )
        data_exact = 0.5 * float(np.sum(res**2))
        R_b, R_c = np.linalg.qr(B, mode="r"), np.linalg.qr(C, mode="r")
        wnn = data_exact + float(self.reg[: fit["live"]] @ np.linalg.svd(R_b @ R_c.T, False, 0))
        params = dict(
            ranks=ranks,
            rank_rule=rank_rule,
            live_rank=fit["live"],
            rank_certificate=fit["cert"],
            nullspace_gap=self.gap,
        )
        return ShapeResult(
            shapes=(B @ C.T).reshape(F, 3, P) * scale,
            X_init=self.Xi3 * scale,
            X_init_singular_values=self.sigma * scale,
            theta=self.reg * scale,
            N=1 if self.prior == "organic" else 0,
            prior=self.prior,
            solver="bilinear",
            history={k: np.asarray(v) for k, v in self.hist.items()},
            n_iter=n_iter,
            converged=fit["rel"] <= self.gtol,
            objective=(E + data_exact - data) * scale**2,
            optimality=fit["rel"],
            params=params,
            mu=self.mu * scale,
            noise=self.noise * scale,
            wnn_objective=wnn * scale**2,
        )
