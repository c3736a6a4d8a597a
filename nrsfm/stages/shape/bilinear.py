"""Shape stage by a bilinear (factored) weighted-nuclear-norm objective, and the closed form.

Given cameras ``R`` and centred measurements ``W``, the shape ``X`` (F, 3, P) with
``X# = Phi(X) = B C'`` (B: F x r, C: 3P x r) minimises

    E(B, C) = 1/2 sum_f ||W_f - R_f X_f||_F^2 + mu/2 sum_i a_i (|B_i|^2 + |C_i|^2)     (*)

For non-decreasing weights ``a_1 <= a_2 <= ...`` the minimum of the regulariser over all
factorisations of a given ``X#`` is the weighted nuclear norm ``mu sum_i a_i sigma_i(X#)``
(Iglesias, Olsson, Oernhag, "Accurate optimization of weighted nuclear norm for non-rigid
structure from motion", ECCV 2020, Sec. 3), so (*) is the paper's Eq. (8)/(10) restricted to
rank r, in a smooth form whose stationary points can be verified by their gradient.

* Weights ``a`` (dimensionless): ``organic`` ``a_1 = 0`` (the partial sum, N = 1, paper
  Eq. 10) and ``a_i = sigma_1 / sigma_i`` of ``X_init#`` (Eq. 9 up to the common factor,
  which goes into ``mu``); ``weighted`` the same ratios with ``a_1 = 1`` (Eq. 8); ``nuclear``
  ``a_i = 1`` (Eq. 7).
* Balance from W alone: ``mu = max(mu_factor * noise * (sqrt(F) + sqrt(3P)),
  mu_noise * noise^2 * (F + 2P) / sigma_1)``, ``noise`` the RMS of W beyond rank 3K
  (:func:`nrsfm.noise.noise_level`), ``sigma_1`` that of X_init#: under noise the penalty
  of the i-th singular value is ``mu_noise noise^2 (F + 2P) / sigma_i``, the form of the
  optimal shrinkage of singular values (Gavish and Donoho, IEEE Trans. Inf. Theory 2017).
  ``mu_factor = 0.01``, ``mu_noise = 5`` (``docs/studies/shape.md``). Noise-free,
  exactly rank-3K W gives ``mu`` = 0 (to rounding) and (*) is the exact rank-K fit.
* Rank r from W and the prior (``rank=None``): K where W is itself of rank at most 3K (its
  numerical rank is below 3K, or ``s_3K+1 / s_3K < GAP_MAX``: a rank-K shape model plus
  noise), the rank-K model; otherwise the prior chooses the rank: r starts at 3K, the
  columns the prior does not want die and are dropped (``PRUNE_RTOL``), and the rank
  certificate (:func:`.factors.rank_certificate`: would a column more, at the next weight,
  lower E?) decides whether the answer's rank is the prior's; where it is not, the wanted
  column is added (r doubled when every column is used, up to ``min(F, 3P)``) and the fit
  goes on from there. If the rank-K fit is not unique (closed-form nullspace gap at rounding
  level) a RuntimeWarning is issued (``W-shape-not-unique``, ``docs/warnings.md``) and
  ``mu`` raised to ``min_mu ||W||_F``.
* Scale-free: W is divided by ``||W||_F`` inside and ``mu`` is proportional to the scale
  of W, so the minimiser for ``c W`` is ``c`` times that for ``W``.
* Solver: variable projection (:mod:`.factors`). C is eliminated in closed form (one 3r x 3r
  normal system shared by all points); ``f(B) = min_C E(B, C)`` is minimised by L-BFGS
  with its exact gradient and the per-frame Hessians as its initial inverse Hessian, from
  the closed-form rank-K start (r = K) or, for r > K, the leading singular vectors of the
  closed-form fit with a share of its residual, re-aligned every few iterations to the
  SVD-aligned factors of the same X# (L-BFGS's memory carried through that change of
  basis). Every weight carries a ridge of ``RIDGE`` (1e-12 in normalised units), so that
  along directions W leaves open the answer is the one of least norm. Each iteration
  is O(F P r) with no SVD and no (F x F) or (2F x 3F) block matrix; the set-up takes one
  thin SVD of W and the singular values of X_init# (from its smaller Gram matrix). Stops
  when the relative gradient norm is below ``gtol``.

Why these settings: ``docs/studies/shape.md``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import ClassVar, Optional

import numpy as np

from ...noise import noise_from_singular_values
from ...validation import check_integer, check_positive
from ...warnings_catalog import text
from ..measurement import left_singular
from ..rotations.subspace import DETERMINED_RTOL
from .closed_form import NULLSPACE_GAP_MIN, nullspace_coefficients
from .common import ShapeResult, check_prior, check_shape_inputs
from .factors import (c_step, minimise, objective, project, rank_certificate,
                      reduced_objective, relative_gradient, viewing_directions)

__all__ = ["BilinearSettings", "GAP_MAX", "bilinear_weights", "prior_rank",
           "solve_bilinear"]

#: W counts as of rank at most 3K (the rank-K model) when s_3K+1 / s_3K is below this
#: (measured: 0.06 - 0.27 for rank-K shapes under 2 - 10 % noise, 0.72 - 0.92 for the real
#: shapes)
GAP_MAX = 0.5
#: at most this many fits, each at a rank from the one before (a column added where the
#: rank certificate wants one, the rank doubled when every column is used)
MAX_RANK_STEPS = 8
#: columns whose singular value falls to this fraction of the largest are dropped while the
#: prior chooses the rank (measured on pickup: the columns the answer does not use fall
#: below 1e-9 within 20 - 50 iterations and reach 1e-16; those it uses stay above 1e-4)
PRUNE_RTOL = 1e-9
#: the prior's rank is reached when the rank certificate (the gain of a column more per
#: unit of its weight) is at most 1 + this
CERTIFICATE_SLACK = 1e-3


# --------------------------------------------------------------------------------------
# settings
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BilinearSettings:
    """The factored weighted nuclear norm (*) (``shape_solver="bilinear"``, the default).

    Attributes
    ----------
    rank : int or None
        Factor rank r; None: from W and the prior (module docstring): K where W is of rank
        at most 3K, else as large as the prior's answer needs (from 3K; columns added while
        the rank certificate wants one).
    mu_factor : float
        The clean-data term ``mu_factor * noise_level(W, K) * (sqrt(F) + sqrt(3P))`` of mu
        (measured: 0.01).
    mu_noise : float
        The noise term ``mu_noise * noise^2 * (F + 2P) / sigma_1(X_init#)`` (measured: 5);
        mu is the larger of the two terms.
    mu : float or None
        Override ``mu``, in the units of the W the solver is given (through
        :func:`nrsfm.reconstruct`: ``W / scale``, ``scale = ||W||_F / 170``).
    min_mu : float
        Used only when the rank-K fit is not unique (the closed form's (K+1)-th eigenvalue
        at rounding level): ``mu`` is raised to ``min_mu ||W||_F`` and a RuntimeWarning is
        issued. Measured on shark only.
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


# --------------------------------------------------------------------------------------
# noise level and weights
# --------------------------------------------------------------------------------------

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


# --------------------------------------------------------------------------------------
# steps
# --------------------------------------------------------------------------------------

def _singular_values(A):
    """Singular values of A (m, n) from the Gram matrix of its shorter side (m^2 n flops;
    the small ones lose relative accuracy, which the weights of (*) do not need)."""
    G = A @ A.T if A.shape[0] <= A.shape[1] else A.T @ A
    ev = np.linalg.eigvalsh(G)[::-1]
    return np.sqrt(np.maximum(ev, 0.0))


# --------------------------------------------------------------------------------------
# solver
# --------------------------------------------------------------------------------------

class _Objective:
    """E(B, C) of (*) on normalised W (``||W||_F = 1``), with its iteration record ``hist``
    (shared by the fits of one solve: each fit's start and iterations in turn)."""

    def __init__(self, Rf, Wn, Xi, reg, hist):
        self.Rf, self.Wn, self.Xi, self.reg = Rf, Wn, Xi, reg
        self.Pi = Rf.transpose(0, 2, 1) @ Rf
        self.n = viewing_directions(Rf)
        self.hist = hist

    def reduced(self, B):
        """(C, (E, data, dE/dB, 0.0)) at ``C = argmin_C E(B, C)``
        (:func:`.factors.reduced_objective`)."""
        return reduced_objective(B, self.n, self.Pi, self.Xi, 1.0, self.reg[:B.shape[1]])

    def values(self, B, C):                                          # ||Wn||_F^2 = 1
        return objective(B, C, self.Pi, self.Xi, 1.0, self.reg[:B.shape[1]])

    def measure(self, B, C):
        """(E, data term, relative gradient norm)."""
        E, data, gB, gC = self.values(B, C)
        return E, data, relative_gradient(B, C, gB, gC)

    def record(self, B, C, values):
        E, data, gB, gC = values
        self.hist["cost"].append(E)
        self.hist["data_term"].append(data)
        self.hist["grad_norm"].append(relative_gradient(B, C, gB, gC))


def _balance_mu(sw, Wn_shape, F, P, K, r, Uw, Rf, st, scale, sigma_1):
    """mu (normalised units), the noise level, the closed-form start B0 and the nullspace
    gap; a RuntimeWarning (and ``mu >= min_mu``) when the rank-K fit is not unique."""
    noise = noise_from_singular_values(sw, Wn_shape, K)
    if st.mu is None:
        mu_n = max(st.mu_factor * noise * (math.sqrt(F) + math.sqrt(3 * P)),   # clean W
                   st.mu_noise * noise ** 2 * (F + 2 * P) / max(sigma_1, 1e-300))
    else:
        mu_n = float(st.mu) / scale
    gap, B0 = float("nan"), None
    if r == K:
        B0, ev = nullspace_coefficients(Uw, sw, Rf, K)
        gap = float(ev[K]) if ev.size > K else float("nan")
        if not gap > NULLSPACE_GAP_MIN:
            message = (text("W-shape-not-unique", gap=gap, K=K, min_mu=st.min_mu)
                       if st.mu is None else
                       text("W-shape-not-unique-mu-given", gap=gap, K=K, mu=st.mu))
            warnings.warn(message, RuntimeWarning, stacklevel=5)
            if st.mu is None:
                mu_n = max(mu_n, st.min_mu)
    return mu_n, noise, B0, gap


def prior_rank(sw, K, F, P):
    """(first rank r, why) of the ``rank=None`` rule from W's singular values ``sw``.

    ``"W of rank <= 3K"``: r = K, W's numerical rank (above ``DETERMINED_RTOL s_1``) is
    below 3K or ``s_3K+1 / s_3K < GAP_MAX`` (the rank-K model); else ``"prior"``:
    r = min(3K, F, 3P), from which the solver drops the columns the prior does not use and
    adds those the rank certificate wants.
    """
    sw = np.asarray(sw, float)
    numerical_rank = int(np.sum(sw > DETERMINED_RTOL * sw[0]))
    gap = sw[3 * K] / sw[3 * K - 1] if sw.size > 3 * K and sw[3 * K - 1] > 0 else 0.0
    if numerical_rank < 3 * K or gap < GAP_MAX:
        return K, "W of rank <= 3K"
    return min(3 * K, F, 3 * P), "prior"


def solve_bilinear(W, R, K, prior="organic", settings=None, progress=None):
    """Minimise (*) (module docstring) to a stationary point by variable projection: the
    set-up, the rank rule, L-BFGS (:func:`.factors.minimise`) at each rank.

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
    """
    st = BilinearSettings() if settings is None else settings
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    check_prior(prior)
    scale = float(np.linalg.norm(W))
    if not scale > 0:
        raise ValueError("W is zero: nothing to reconstruct")
    Wn = W / scale
    Uw, sw, _ = left_singular(Wn)           # one thin SVD of W (its Gram matrix if wide)
    r_max = min(F, 3 * P)
    if st.rank is None:
        r, why = prior_rank(sw, K, F, P)
    else:
        r, why = st.rank, "given"
        if not 1 <= r <= r_max:
            raise ValueError(f"rank must be in [1, min(F, 3P)] = [1, {r_max}]; got {r!r}")
    say = progress if callable(progress) else (lambda msg: None)
    Xi3 = Rf.transpose(0, 2, 1) @ Wn.reshape(F, 2, P)
    sigma = _singular_values(Xi3.reshape(F, 3 * P))
    cache, prune = {"hist": {"cost": [], "data_term": [], "grad_norm": []}}, why == "prior"
    ranks, n_total = [], 0
    for _ in range(MAX_RANK_STEPS):
        fit = _fit_at_rank(Wn, Rf, Xi3, sigma, Uw, sw, K, r, prior, st, scale, cache, prune)
        ranks.append(r)
        n_total += fit["n_iter"]
        grow = prune and fit["certificate"] > 1.0 + CERTIFICATE_SLACK     # nan: full rank
        say(f"shape (bilinear, {prior}, r={r}) stopped after {fit['n_iter']} iterations: "
            f"relative gradient {fit['rel']:.2e}, rank {fit['live']}"
            + (f"; {fit['wanted'].shape[1]} column(s) more wanted (rank certificate "
               f"{fit['certificate']:.4g})" if grow else ""))
        if not grow:
            break
        B_next = np.column_stack([fit["B"], fit["wanted"]])   # the wanted columns added
        if B_next.shape[1] > r:             # the cap is too low: doubled (or more)
            r = min(max(2 * r, B_next.shape[1]), r_max)
        cache["warm"] = B_next[:, :r]
    fit.update(ranks=ranks, rank_rule=why, n_total=n_total)
    return _result(fit, Xi3, sigma, F, P, K, prior, st, scale)


def _fit_at_rank(Wn, Rf, Xi3, sigma, Uw, sw, K, r, prior, st, scale, cache, prune):
    """(*) at rank r from its start: the fitted factors and their measures (a dict).

    With ``prune``, columns that die are dropped (:func:`.factors.minimise`) and the result
    carries the rank certificate of the first dropped weight (:func:`rank_certificate`).
    ``cache`` holds the start's SVD across calls, the next rank's start (used once) and the
    iteration record."""
    F, P = Xi3.shape[0], Xi3.shape[2]
    Xi = Xi3.reshape(F, 3 * P)
    a = bilinear_weights(sigma, r, prior)
    mu_n, noise, B0, gap = _balance_mu(sw, Wn.shape, F, P, K, r, Uw, Rf, st, scale, sigma[0])
    obj = _Objective(Rf, Wn, Xi, mu_n * a + RIDGE, cache["hist"])
    warm = cache.pop("warm", None)
    if warm is not None:
        B0 = warm
    else:
        if B0 is None:
            B0 = _start(Xi, r, cache, Wn, Rf, Uw, sw, K)
        B0 = B0 / np.linalg.norm(B0, axis=0) * math.sqrt(max(sigma[0], 1e-300) / r)
    B, C, rel, n_iter = minimise(B0, obj.reduced, obj.Pi, obj.reg, st.gtol,
                                 st.max_iter, on_iterate=obj.record,
                                 prune_rtol=PRUNE_RTOL if prune else None)
    live = B.shape[1]
    E, data, rel = obj.measure(B, C)
    res = Wn.reshape(F, 2, P) - np.einsum("fac,fcp->fap", Rf, (B @ C.T).reshape(F, 3, P))
    data_exact = 0.5 * float(np.sum(res ** 2))
    s_x = np.linalg.svd(np.linalg.qr(B, mode="r") @ np.linalg.qr(C, mode="r").T,
                        compute_uv=False)                      # sigma(B C'), live x live
    cert, wanted = float("nan"), None
    r_max = min(F, 3 * P)
    if prune and live < r_max:              # the weights of the columns not used
        reg_next = mu_n * bilinear_weights(sigma, min(2 * live, r_max), prior)[live:]
        cert, s_g, U = rank_certificate(B, C, obj.Pi, Xi, reg_next)
        gain = s_g - reg_next[:s_g.size] * (1.0 + CERTIFICATE_SLACK)
        n = int(np.argmin(gain > 0)) if not np.all(gain > 0) else gain.size
        wanted = U[:, :n] * np.sqrt(np.maximum(gain[:n], 0.0))   # at first-order size
    return dict(B=B, C=C, n_iter=n_iter, obj=obj, a=a, mu_n=mu_n, noise=noise, gap=gap,
                E=E + data_exact - data, data_exact=data_exact, rel=rel, s_x=s_x, r=r,
                live=live, certificate=cert, wanted=wanted)


#: ridge added to every weight of (*) (normalised units, ||W||_F = 1; a nuclear norm of
#: 1e-12): where W has fewer independent directions than the fit has unknowns (shark's
#: noise-free W of rank 5 at r = 3), the data leave X# free along some directions that the
#: organic prior's first weight (0) does not bound; with the ridge the answer is the one of
#: least norm there, the same at every scale of W. It moves exact answers by about 1e-12
RIDGE = 1e-12

#: the start's share of the in-plane residual of the rank-K fit (:func:`_start`): it only
#: orients the columns beyond K (1e-4, 1e-3, 1e-2 reach the same minima in the same
#: iterations to within 10 %)
START_RESIDUAL = 1e-3


def _start(Xi, r, cache, Wn, Rf, Uw, sw, K):
    """B0 (F, r) for r > K: the leading left singular vectors of the closed-form rank-K fit
    X_K plus ``START_RESIDUAL`` of its in-plane residual (``X_K + e (X_init - Pi X_K)``:
    the exact rank-K answer, with the directions the fit leaves for the columns beyond K).
    Its SVD is cached across ranks."""
    if "U" not in cache:
        B, _ = nullspace_coefficients(Uw, sw, Rf, K)
        X_K = B @ c_step(B, Rf, Wn, np.zeros(K)).T
        X0 = X_K + START_RESIDUAL * (Xi - project(Rf.transpose(0, 2, 1) @ Rf, X_K))
        cache["U"], cache["s"] = np.linalg.svd(X0, full_matrices=False)[:2]
    return cache["U"][:, :r] * np.sqrt(cache["s"][:r])


def _result(fit, Xi3, sigma, F, P, K, prior, st, scale):
    """The ShapeResult of the last fit, in W's units."""
    B, C, obj, rel = fit["B"], fit["C"], fit["obj"], fit["rel"]
    converged = rel <= st.gtol
    noise_rel = fit["noise"] * math.sqrt(2 * F * P)
    params = dict(prior=prior, K=K, rank=fit["r"], ranks=fit["ranks"],
                  rank_rule=fit["rank_rule"], mu_factor=st.mu_factor, mu_noise=st.mu_noise,
                  noise_rel=noise_rel, min_mu=st.min_mu, gtol=st.gtol,
                  max_iter=int(st.max_iter), normalisation=scale,
                  nullspace_gap=fit["gap"], live_rank=fit["live"],
                  rank_certificate=fit["certificate"])
    wnn = fit["data_exact"] + float(obj.reg[:fit["live"]] @ fit["s_x"])
    return ShapeResult(
        shapes=(B @ C.T).reshape(F, 3, P) * scale, X_init=Xi3 * scale,
        X_init_singular_values=sigma * scale, theta=obj.reg * scale, weights=fit["a"],
        mu=fit["mu_n"] * scale, noise=fit["noise"] * scale, N=1 if prior == "organic" else 0,
        prior=prior, solver="bilinear", B=B * math.sqrt(scale), C=C * math.sqrt(scale),
        objective=fit["E"] * scale ** 2, wnn_objective=wnn * scale ** 2, optimality=rel,
        optimality_kind="gradient", history={k: np.asarray(v) for k, v in obj.hist.items()},
        n_iter=fit["n_total"], converged=converged, params=params)
