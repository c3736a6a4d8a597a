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
  ``mu_factor = 0.01``, ``mu_noise = 5``: measured, ``docs/shape_stage.md``. Noise-free,
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

Settings and measurements: ``docs/shape_stage.md``.

:class:`ClosedFormSettings` (``shape_solver="closed_form"``) is this solver with ``mu = 0``
and no iterations from the closed-form start of :mod:`.closed_form`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from typing import ClassVar, Optional

import numpy as np

from ...noise import noise_from_singular_values
from ..measurement import left_singular
from ...validation import check_choice, check_integer, check_positive
from ...warnings_catalog import text
from .base import SolverSettings, check_prior
from ..rotations.subspace import DETERMINED_RTOL
from .admm import AdmmSettings, solve_admm
from .closed_form import NULLSPACE_GAP_MIN, nullspace_coefficients
from .factors import (c_step, minimise, objective, project, rank_certificate,
                      reduced_objective, relative_gradient, viewing_directions)
from .common import ShapeResult, check_shape_inputs

__all__ = ["BilinearSettings", "ClosedFormSettings", "GAP_MAX", "bilinear_weights",
           "prior_rank", "solve_bilinear", "solve_closed_form"]

#: W counts as of rank at most 3K (the rank-K model) when s_3K+1 / s_3K is below this
#: (measured: 0.06 - 0.27 for rank-K shapes under 2 - 10 % noise, 0.72 - 0.92 for the real
#: shapes, docs/shape_stage.md)
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
class BilinearSettings(SolverSettings):
    """The factored weighted nuclear norm (*) (``shape_solver="bilinear"``, the default).

    Attributes
    ----------
    rank : int or None
        Factor rank r; None: from W and the prior (module docstring): K where W is of rank
        at most 3K, else as large as the prior's answer needs (from 3K; columns added while
        the rank certificate wants one).
    mu_factor : float
        The clean-data term ``mu_factor * noise_level(W, K) * (sqrt(F) + sqrt(3P))`` of mu
        (measured: 0.01, ``docs/shape_stage.md``).
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
    init : {"closed_form", "rank_k", "admm", "best"}
        The start: ``closed_form``, the exact rank-K fit (:func:`_start`); ``rank_k``,
        the leading singular vectors of X_init# (zero depth); ``admm``, those of the
        paper's ADMM's answer (:func:`.admm.solve_admm`, its default settings, the same
        prior); ``best``, solved from ``closed_form`` and from ``admm``, the lower
        objective kept (ties: ``closed_form``). On 33 rows with ground-truth rotations
        ``best`` reaches a lower E on 3 (stretch: e3d .0152 -> .0126; ``back`` on a smooth
        180-degree path: E 8 % lower, e3d .0445 -> .0221), at 2.5 - 4 x the time
        (``docs/shape_stage.md``). The rank-K fit's uniqueness is tested (and warned
        about) whatever the start. With ``start`` given (:func:`solve_bilinear`) the fit
        starts from it, whatever ``init``.
    gtol : float
        Stop when the relative gradient norm is at most gtol.
    max_iter : int
        Cap on L-BFGS iterations (0: the start only).
    """

    name: ClassVar[str] = "bilinear"
    warm_start: ClassVar[bool] = True
    INITS: ClassVar[tuple] = ("closed_form", "rank_k", "admm", "best")
    rank: Optional[int] = None
    mu_factor: float = 0.01
    mu_noise: float = 5.0
    mu: Optional[float] = None
    min_mu: float = 1e-5
    init: str = "closed_form"
    gtol: float = 1e-8
    max_iter: int = 3000

    def __post_init__(self):
        if self.rank is not None:
            check_integer(self.rank, "rank", minimum=1)
        for name in ("mu_factor", "mu_noise", "min_mu", "gtol"):
            check_positive(name, getattr(self, name), strict=False)
        if self.mu is not None:
            check_positive("mu", self.mu, strict=False)
        check_choice("init", self.init, self.INITS)
        check_integer(self.max_iter, "max_iter", minimum=0)

    def solve(self, W, R, K, prior, progress=None, observed=None, start=None):
        self.check_observed(observed, W)
        return solve_bilinear(W, R, K, prior, self, progress, start)


@dataclass(frozen=True)
class ClosedFormSettings(SolverSettings):
    """The exact rank-K solution, no prior (``shape_solver="closed_form"``), reported with
    the bilinear solver's measures.

    Attributes
    ----------
    gtol : float
        Tolerance for ``converged`` (relative gradient norm of the plain rank-K fit).
    """

    name: ClassVar[str] = "closed_form"
    uses_prior: ClassVar[bool] = False
    gtol: float = 1e-6

    def __post_init__(self):
        check_positive("gtol", self.gtol, strict=False)

    def solve(self, W, R, K, prior=None, progress=None, observed=None):
        self.check_observed(observed, W)
        return solve_closed_form(W, R, K, self, progress)


def solve_closed_form(W, R, K, settings=ClosedFormSettings(), progress=None):
    """The closed-form rank-K shape as a shape-stage result: the bilinear solver with
    ``mu = 0`` and no iterations (B from :func:`closed_form_coefficients`, C by least
    squares); the result reports the data term and the relative gradient norm of the plain
    rank-K fit at that point. No prior."""
    res = _bilinear(W, R, K, "nuclear", BilinearSettings(rank=K, mu=0.0, max_iter=0,
                                                       gtol=settings.gtol),
                    progress)
    res.prior, res.solver = "none", "closed_form"
    res.params["prior"] = "none"
    return res


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

def solve_bilinear(W, R, K, prior, settings=BilinearSettings(), progress=None, start=None):
    """Minimise (*) (module docstring) to a stationary point by variable projection.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements, any units.
    R : (F, 3, 3) or (F, 2, 3) ndarray
    K : int
        Number of shape bases.
    prior : {"organic", "weighted", "nuclear"}
        Weights ``a``, see :func:`bilinear_weights`.
    settings : BilinearSettings
    progress : callable(str) or None
    start : ShapeResult, optional
        This solver's result on the same W (same rank rule and first rank) with nearby
        cameras: the fit starts from its factors at its final rank (ValueError for any
        other start).

    Returns
    -------
    ShapeResult
    """
    if settings.init != "best" or start is not None:
        return _bilinear(W, R, K, prior, settings, progress, start)
    first = _bilinear(W, R, K, prior, replace(settings, init="closed_form"), progress)
    with warnings.catch_warnings():          # the first solve has said it
        warnings.filterwarnings("ignore", message="W-shape-not-unique")
        second = _bilinear(W, R, K, prior, replace(settings, init="admm"), progress)
    best = second if second.objective < first.objective else first
    best.params.update(init="best", init_kept=best.params["init"],
                       objectives_of_starts=dict(closed_form=first.objective,
                                                 admm=second.objective))
    return best


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
    return mu_n, noise, (B0 if st.init == "closed_form" else None), gap


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


def _bilinear(W, R, K, prior, st, progress, start=None):
    """Set-up, the rank rule, L-BFGS (:func:`.factors.minimise`) at each rank, and the result in
    W's units."""
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
    if start is None and st.init in ("rank_k", "admm"):       # the start's singular vectors
        X0 = (Xi3.reshape(F, 3 * P) if st.init == "rank_k" else
              solve_admm(W, R, K, prior, AdmmSettings()).shapes.reshape(F, 3 * P) / scale)
        cache["U"], cache["s"] = np.linalg.svd(X0, full_matrices=False)[:2]
    if start is not None:                   # its factors, at its final rank
        cache["warm"], r = _warm_factors(start, Wn, r, why)
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
    ``cache`` holds the SVD of X_init# across calls, a warm start (used once) and the
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


def _warm_factors(start, Wn, r, why):
    """(B of ``start`` in normalised units, its final rank); ValueError unless it is a
    bilinear result on a W of the same size with the same rank rule and first rank."""
    p = getattr(start, "params", None) or {}
    B = getattr(start, "B", None)
    if getattr(start, "solver", None) != "bilinear" or B is None or \
            B.shape[0] != Wn.shape[0] // 2 or p.get("rank_rule") != why or \
            list(p.get("ranks", ()))[:1] != [r]:
        raise ValueError("start must be a bilinear shape result on the same W (same rank "
                         f"rule {why!r} and first rank {r}); got {type(start).__name__}")
    return np.asarray(B, float) / math.sqrt(float(p["normalisation"])), int(p["rank"])


#: ridge added to every weight of (*) (normalised units, ||W||_F = 1; a nuclear norm of
#: 1e-12): where W has fewer independent directions than the fit has unknowns (shark's
#: noise-free W of rank 5 at r = 3), the data leave X# free along some directions, and
#: the organic prior's first weight (0) does not bound them. Without it the C step was
#: singular to rounding, E jittered by 1e-11 between evaluations, and the first column grew
#: along those directions wherever the solver happened to go (shark through the pipeline:
#: 1827 iterations; W x 3 gave another answer, e3d .0105 against .0162); with it the answer
#: is the one of least norm there (59 iterations at every scale). It moves exact answers by
#: about 1e-12 (docs/shape_stage.md)
RIDGE = 1e-12

#: the start's share of the in-plane residual of the rank-K fit (:func:`_start`): it only
#: orients the columns beyond K (1e-4, 1e-3, 1e-2 reach the same minima in the same
#: iterations to within 10 %, docs/shape_stage.md)
START_RESIDUAL = 1e-3


def _start(Xi, r, cache, Wn, Rf, Uw, sw, K):
    """B0 (F, r) for r > K: the leading left singular vectors of the closed-form rank-K fit
    X_K plus ``START_RESIDUAL`` of its in-plane residual (``X_K + e (X_init - Pi X_K)``:
    the exact rank-K answer, with the directions the fit leaves for the columns beyond K).
    Against ``X_init + (I - Pi) X_K`` (the image-plane part of W with the rank-K depth, the
    start before) on the 8 MoCap sequences and the noisy rows of the shape table: the same
    minima except stretch at sigma .05 (seed 0), where it reaches a lower one, and 1408 ->
    1395 iterations in all with the pipeline's rotations (pickup 161 -> 122, drink 390 ->
    454; ``docs/shape_stage.md``). Its SVD is cached across ranks; with ``init`` ``rank_k``
    or ``admm`` the cache holds that start's instead (:func:`_bilinear`)."""
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
                  noise_rel=noise_rel, min_mu=st.min_mu, init=st.init, gtol=st.gtol,
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
