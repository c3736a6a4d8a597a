"""Shape solver ``constrained``: the organic weighted nuclear norm with W fitted to within
its noise (issue 17). Optional (``reconstruct(shape_solver="constrained")``), not the default.

Problem (the small-mu limit of the paper's Eq. 10, written as a constraint):

    minimise_X  ||X#||_a = sum_i a_i sigma_i(X#)   s.t.   ||W - R X||_F <= eps        (C)

with X# = Phi(X) (F, 3P), organic weights ``a_1 = 0``, ``a_i = sigma_1 / sigma_i`` of
``X_init# = Phi(pinv(R) W)`` (paper Eq. 9 up to a common factor, partial sum N = 1, Eq. 10),
and eps the noise norm of W estimated from W alone (:func:`residual_bound`: the residual
of the best rank-3K approximation, scaled to all 2FP degrees of freedom).
The weights are dimensionless and eps is homogeneous in W, so (C) is scale-free.

With orthonormal camera rows R_f (2 x 3) and third row n_f, the exact-fit set (eps = 0) is
``X_f = R_f' W_f + n_f z_f'`` with only the depths z_f (P) free (:func:`exact_fit_shapes`);
for eps > 0 the in-plane part may move inside a ball (:func:`project_to_fit`, exact and
cheap). The weights increase with i, so ``||.||_a`` is not convex.

Solver (:func:`organic_fit`): ADMM with the paper's continuation of the penalty
(rho grows by ``lam`` per iteration; Eq. 11-14 with the data term replaced by the
constraint); one Gram eigenproblem of the shorter side of X# per iteration (F x 3P:
3P x 3P). As for the paper's ADMM, the answer is where the continuation freezes, a point of
(C) with zero constraint gap, not a certified minimiser: fixed-rho ADMM and an iteratively
reweighted least-squares solver did not converge on (C) (``docs/shape_constrained.md``).
The answer is the feasible point with the lower objective among the ADMM's end point and
the closed-form rank-K shape projected onto (C), the latter only when the rank-K fit is
unique (:func:`rank_k_closed_form`): exact on exactly rank-K data, and a unique answer on
rank-deficient data. When eps > 0 the ADMM's end point is then polished into a certified
KKT point of (C) with rank(X#) <= r (:mod:`.constrained_polish`): the answer no longer
depends on where the continuation froze. The closed form is the bilinear solver's
(:func:`nrsfm.stages.shape.closed_form.closed_form_fit`).

:func:`solve_constrained` is the shape stage's entry (settings :class:`ConstrainedSettings`,
result :class:`ShapeResult`); :func:`organic_fit` the same solver with its own result type.
The exact-fit set and its projection: :mod:`.fit_set`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar, Optional

import numpy as np

from ...noise import noise_from_singular_values
from ...validation import check_flag, check_integer, check_K, check_measurements, check_positive
from .base import PRIORS, SolverSettings, check_prior
from .bilinear import bilinear_weights
from ..rotations.subspace import DETERMINED_RTOL
from .closed_form import NULLSPACE_GAP_MIN, closed_form_fit
from .common import ShapeResult, check_shape_inputs
from .constrained_polish import rank_certificate, solve_kkt
from .fit_set import apply_frames, project_to_fit, weighted_svt

__all__ = ["ConstrainedSettings", "OrganicFitResult", "organic_fit", "organic_objective",
           "organic_weights", "rank_k_closed_form", "residual_bound", "solve_constrained"]



@dataclass(frozen=True)
class ConstrainedSettings(SolverSettings):
    """Organic norm, W fitted to within its noise (``shape_solver="constrained"``).

    Attributes
    ----------
    eps : float or None
        Residual bound ``||W - R X||_F <= eps`` in W's units (default: the noise norm of W,
        :func:`residual_bound`).
    rho0, lam, rho_max : float
        Initial ADMM penalty (times ``1 / sigma_1(X_init#)``), its growth per iteration
        (> 1), its cap.
    tol : float
        Stop the ADMM when ``||Y - X#||_F < tol sigma_1(X_init#)``.
    max_iter : int
        Cap on ADMM iterations.
    polish : bool
        Polish the ADMM's end point into a KKT point of (C) (skipped when eps = 0 to
        rounding, where the candidate step is exact).
    gtol, rtol : float
        The polish's tolerances: relative gradient norm of the factored (K) and
        ``|log(residual / eps)|`` (:func:`.constrained_polish.solve_kkt`).
    polish_max_iter : int
        Cap on the polish's L-BFGS iterations.
    rank : int or None
        Factor rank of the polish (default: the larger of 3K and the ADMM point's rank).
    """

    name: ClassVar[str] = "constrained"
    eps: Optional[float] = None
    rho0: float = 1.0
    lam: float = 1.1
    rho_max: float = 1e10
    tol: float = 1e-8
    max_iter: int = 1000
    polish: bool = True
    gtol: float = 1e-8
    rtol: float = 1e-5
    polish_max_iter: int = 20000
    rank: Optional[int] = None

    def __post_init__(self):
        if self.eps is not None:
            check_positive("eps", self.eps, strict=False)
        for name in ("rho0", "rho_max", "tol", "gtol", "rtol"):
            check_positive(name, getattr(self, name))
        if not self.lam > 1:
            raise ValueError(f"lam must be > 1 (rho grows each iteration); got {self.lam!r}")
        check_integer(self.max_iter, "max_iter", minimum=1)
        check_integer(self.polish_max_iter, "polish_max_iter", minimum=1)
        check_flag("polish", self.polish)
        if self.rank is not None:
            check_integer(self.rank, "rank", minimum=1)

    def solve(self, W, R, K, prior, progress=None, observed=None):
        self.check_observed(observed, W)
        return solve_constrained(W, R, K, prior, self, progress)


def organic_weights(sigma):
    """Organic weights a (r,) from the singular values sigma (r,) of X_init#.

    ``a_1 = 0`` (first singular value free, N = 1, paper Eq. 10), ``a_i = sigma_1 / sigma_i``
    (Eq. 9 divided by its common factor); singular values below ``1e-12 sigma_1`` (the
    rounding-level null space of a centred X_init#) count as ``1e-12 sigma_1``.
    Non-decreasing.
    """
    sigma = np.asarray(sigma, dtype=float)
    if sigma.ndim != 1 or sigma.size == 0 or not sigma[0] > 0:
        raise ValueError(f"sigma must be a non-empty 1-D array with sigma_1 > 0; got shape "
                         f"{sigma.shape}")
    return bilinear_weights(sigma, sigma.size, "organic")


def residual_bound(W, K):
    """eps: the norm of the noise in W (2F, P), estimated from W alone.

    ``eps = ||W - W_3K||_F sqrt(2FP / ((2F - 3K)(P - 3K)))``: W_3K is the best rank-3K
    approximation; for W = rank-3K signal + i.i.d. noise, the residual keeps about
    ``(2F - 3K)(P - 3K)`` of the noise's 2FP degrees of freedom, so eps estimates the noise
    norm (the discrepancy principle: fit W to within its noise). Zero (to rounding) for
    exactly rank-3K W. In W's units.
    """
    W = check_measurements(W)
    K = check_K(K, W.shape[0] // 2, W.shape[1])
    return _noise_norm(np.linalg.svd(W, compute_uv=False), W.shape, K)


def _noise_norm(s, shape, K):
    """:func:`residual_bound` from the singular values s of W (shape (2F, P)): the noise
    level (:func:`nrsfm.noise.noise_from_singular_values`) times ``sqrt(2FP)``."""
    return noise_from_singular_values(s, shape, K) * math.sqrt(shape[0] * shape[1])


def organic_objective(X, a):
    """``sum_i a_i sigma_i(X#)`` for X (F, 3, P) and weights a (>= min(F, 3P) entries)."""
    X = np.asarray(X, dtype=float)
    s = np.linalg.svd(X.reshape(X.shape[0], -1), compute_uv=False)
    return float(np.asarray(a)[:s.size] @ s)


def rank_k_closed_form(W, R, K):
    """Closed-form rank-K shape X (F, 3, P) fitting W (2F, P) in least squares, and its gap.

    Coefficients B (F, K) by the nullspace method of Valmadre, Sridharan, Denman, Fookes,
    Lucey ("Closed-form solutions for low-rank non-rigid reconstruction", DICTA 2015): with
    ``W ~ M_hat B_hat`` (rank 3K), an exact rank-K shape means ``M_hat_f G_k = b_fk R_f``;
    eliminating ``b_fk = <R_f, M_hat_f G_k> / 2`` leaves a (9K x 9K) quadratic form whose K
    smallest eigenvectors give B. Bases by linear least squares (one (3K x 3K) normal
    matrix shared by every point). Exact on exactly rank-K data with exact cameras when the
    rank-K fit is unique; otherwise one least-squares candidate.

    Returns
    -------
    X : (F, 3, P) ndarray
    gap : float
        The (K+1)-th smallest eigenvalue of the quadratic form over its largest: at rounding
        level when the rank-K fit is not unique (then X is an arbitrary member).
    """
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    return closed_form_fit(W, Rf, K)


@dataclass
class OrganicFitResult:
    """Result of :func:`organic_fit`.

    Attributes
    ----------
    shapes : (F, 3, P) ndarray
        X in W's units; ``||W - R X||_F <= eps`` holds by construction.
    X_init : (F, 3, P) ndarray
        Pseudo-inverse shape ``pinv(R_f) W_f`` (W's units).
    X_init_singular_values : (min(F, 3P),) ndarray
        Singular values of ``X_init#`` (W's units).
    weights : (min(F, 3P),) ndarray
        Organic weights a (dimensionless, ``a_1 = 0``).
    eps : float
        Residual bound (W's units), :func:`residual_bound` unless given.
    objective : float
        ``sum_i a_i sigma_i(X#)`` at the end (W's units).
    residual : float
        ``||W - R X||_F`` at the end (W's units), at most eps.
    optimality : float
        ``||Y - X#||_F / sigma_1(X_init#)`` at the end: the gap between the low-rank
        variable Y and the fitted X# (the ADMM's stopping quantity, the paper's criterion
        made relative).
    history : dict of (n_iter,) ndarrays
        ``objective`` (of X#, W's units), ``residual`` (``||W - R X||_F``, W's units),
        ``gap`` (the optimality measure), ``rho`` (relative to ``1 / sigma_1``).
    n_iter : int
    converged : bool
        True when the gap fell below ``tol``.
    chosen : {"kkt", "admm", "closed_form"}
        Which feasible candidate had the lower objective (see :func:`organic_fit`):
        the KKT point polished from the ADMM's end point, the end point itself (when not
        polished), or the closed-form rank-K shape.
    candidate_objectives : dict
        Objective of each candidate (W's units).
    params : dict
    certified : bool
        True when the answer is a KKT point of (C) with rank(X#) <= r to the tolerances:
        relative gradient of the factored (K) at most ``gtol`` and
        ``|log(residual / eps)|`` at most ``rtol`` (:mod:`.constrained_polish`).
    kkt : dict
        ``mu`` (1 / multiplier of the constraint, W's units), ``grad_norm`` (relative
        gradient norm of (K)), ``residual_gap`` (``|log(residual / eps)|``), ``rank`` (r),
        ``n_iter`` (L-BFGS iterations), ``n_outer`` (secant steps on mu),
        ``rank_certificate`` (:func:`.constrained_polish.rank_certificate`: at most 1 when the
        point is also stationary without the rank cap r); empty when not
        polished (eps = 0, or ``polish=False``).
    """

    shapes: np.ndarray
    X_init: np.ndarray
    X_init_singular_values: np.ndarray
    weights: np.ndarray
    eps: float
    objective: float
    residual: float
    optimality: float
    history: dict = field(default_factory=dict)
    n_iter: int = 0
    converged: bool = False
    chosen: str = "admm"
    candidate_objectives: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    certified: bool = False
    kkt: dict = field(default_factory=dict)


def organic_fit(W, R, K, settings=None, prior="organic"):
    """Organic weighted nuclear norm with W fitted to within eps (module docstring, (C)).

    ADMM on ``minimise ||Y||_a  s.t.  Y = X#, ||W - R X|| <= eps`` with the paper's
    continuation of the penalty (Eq. 11-14 with the data term replaced by the
    constraint):

    * Y step: ``Y = weighted_svt(X# - U, a sigma_1 / rho)`` (PSVT, first value kept);
    * X step: ``X = project_to_fit(Y + U)`` (exact projection onto the constraint);
    * ``U += Y - X#``; ``rho *= lam`` (U rescaled with it, U = multiplier / rho).

    Stops when ``||Y - X#||_F < tol sigma_1(X_init#)`` or rho reaches rho_max. The
    iterates stay in R^3 (x) rowspace(W), so for P > 2F the solver runs, exactly, on
    coordinates in that row space (2F x 2F) and maps back: per iteration one Gram
    eigenproblem of size ``min(F, 3 min(P, 2F))``. The answer is
    the feasible point with the lower objective of (C) among the ADMM's end point and the
    closed-form rank-K shape (:func:`rank_k_closed_form`) projected onto the constraint
    (on exactly rank-K data the latter is the exact shape and the relaxation's path can end
    higher; on MoCap the ADMM's objective is about ten times lower). Everything is relative
    to ``||W||_F`` and ``sigma_1(X_init#)``: ``c W`` gives ``c X``.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements, any units.
    R : (F, 2, 3) or (F, 3, 3) ndarray
        Cameras; the first two rows of each must be orthonormal.
    K : int
        Number of shape bases: sets eps (:func:`residual_bound`).
    settings : ConstrainedSettings
    prior : {"organic", "weighted", "nuclear"}
        Weights a of (C) (:func:`nrsfm.stages.shape.bilinear.bilinear_weights`).

    Returns
    -------
    OrganicFitResult

    Raises
    ------
    ValueError
        Bad shapes or values, non-orthonormal camera rows, W zero.
    """
    st = ConstrainedSettings() if settings is None else settings
    return _organic_fit(W, R, K, st, check_prior(prior))


def solve_constrained(W, R, K, prior, settings, progress=None):
    """The shape stage's ``constrained`` solver (:func:`organic_fit` as a
    :class:`ShapeResult`).

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements (the result is in W's units).
    R : (F, 3, 3) or (F, 2, 3) ndarray
        Cameras with orthonormal rows.
    K : int
        Number of shape bases (sets eps).
    prior : {"organic", "weighted", "nuclear"}
        Weights a of (C) (:func:`nrsfm.stages.shape.bilinear.bilinear_weights`; the
        measurements in ``docs/shape_constrained.md`` are of ``organic``).
    settings : ConstrainedSettings
    progress : callable(str) or None

    Returns
    -------
    ShapeResult
        ``objective`` and ``wnn_objective`` the weighted norm of (C) at the end (the data
        term is the constraint, the same for all cameras R: the pipeline's choice between
        rotations compares this), ``optimality`` the ADMM's relative gap; ``params``
        holds every constant and ``eps``, ``residual``, ``chosen``,
        ``candidate_objectives``, ``certified`` and ``kkt`` (:class:`OrganicFitResult`).
    """
    res = _organic_fit(W, R, K, settings, check_prior(prior))
    F, P = res.shapes.shape[0], res.shapes.shape[2]
    if callable(progress):
        progress(f"shape (constrained, organic) stopped after {res.n_iter} ADMM iterations: "
                 f"{res.chosen} chosen, {'certified' if res.certified else 'not certified'}")
    params = dict(res.params, prior=prior, eps=res.eps, residual=res.residual,
                  chosen=res.chosen, candidate_objectives=res.candidate_objectives,
                  certified=res.certified, kkt=res.kkt)
    history = dict(res.history, cost=res.history["objective"])
    return ShapeResult(
        shapes=res.shapes, X_init=res.X_init, X_init_singular_values=res.X_init_singular_values,
        theta=res.weights, N=PRIORS[prior], prior=prior, solver="constrained", history=history,
        n_iter=res.n_iter, converged=res.converged, objective=res.objective,
        optimality=res.optimality, optimality_kind="admm gap", params=params, weights=res.weights,
        wnn_objective=res.objective,
        mu=res.kkt.get("mu"), noise=res.eps / math.sqrt(2 * F * P))


def _organic_fit(W, R, K, st, prior):
    """The body of :func:`organic_fit`."""
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    eps, rho0, lam, rho_max, tol, max_iter = (st.eps, st.rho0, st.lam, st.rho_max, st.tol,
                                              st.max_iter)
    polish, gtol, rtol, polish_max_iter, rank = (st.polish, st.gtol, st.rtol,
                                                 st.polish_max_iter, st.rank)
    scale = float(np.linalg.norm(W))
    if not scale > 0:
        raise ValueError("W is zero: nothing to reconstruct")
    Wn = W / scale
    Wr, Vt = _row_space_coordinates(Wn)
    sw = np.linalg.svd(Wr, compute_uv=False)
    eps_n = _noise_norm(sw, Wn.shape, K) if eps is None else float(eps) / scale
    if not (np.isfinite(eps_n) and eps_n >= 0):
        raise ValueError(f"eps must be finite and non-negative; got {eps!r}")
    Xr, a, sA, hist, it, converged = _continuation_admm(Wr, Rf, eps_n, prior, rho0, lam,
                                                        rho_max, tol, max_iter)
    kkt, admm_objective = {}, organic_objective(Xr, a)
    if polish and eps_n > 1e-10:
        Xr, kkt = _polish(Xr, Wr, Rf, K, a, eps_n, gtol, rtol, polish_max_iter, rank)
    Xr, chosen, cand = _select_candidate(Xr, Wr, Rf, K, eps_n, a, "kkt" if kkt else "admm")
    certified = bool(kkt) and chosen == "kkt" and kkt["grad_norm"] <= gtol \
        and kkt["residual_gap"] <= rtol
    if kkt:
        kkt["mu"] *= scale
        cand["admm"] = admm_objective
    X3 = Xr if Vt is None else (Xr.reshape(-1, Vt.shape[0]) @ Vt).reshape(F, 3, P)
    Xi = apply_frames(Rf.transpose(0, 2, 1), Wn.reshape(F, 2, P))
    params = dict(prior=prior, K=K, eps_rule="residual_bound" if eps is None else "given",
                  rho0=rho0, lam=lam, rho_max=rho_max, tol=tol, max_iter=int(max_iter),
                  normalisation=scale, polish=polish, gtol=gtol, rtol=rtol,
                  polish_max_iter=int(polish_max_iter))
    hist = {k: np.asarray(v) * (scale if k in ("objective", "residual") else 1.0)
            for k, v in hist.items()}
    return OrganicFitResult(
        shapes=X3 * scale, X_init=Xi * scale, X_init_singular_values=sA * scale, weights=a,
        eps=eps_n * scale, objective=organic_objective(Xr, a) * scale,
        residual=float(np.linalg.norm(apply_frames(Rf, X3) - Wn.reshape(F, 2, P))) * scale,
        optimality=float(hist["gap"][-1]), history=hist, n_iter=it, converged=converged,
        chosen=chosen, candidate_objectives={k: v * scale for k, v in cand.items()},
        params=params, certified=certified, kkt=kkt)


def _polish(X, Wn, Rf, K, a, eps_n, gtol, rtol, max_iter, rank=None):
    """KKT point of (C) from the ADMM's end point X (F, 3, r'): factor rank r = the larger of
    3K and X#'s numerical rank (singular values above 1e-6 of the largest), projected onto
    (C) at the end (a move of relative size rtol at most). Returns X and the kkt dict."""
    F = X.shape[0]
    s = np.linalg.svd(X.reshape(F, -1), compute_uv=False)
    r = min(max(3 * K, int(np.sum(s > 1e-6 * s[0]))) if rank is None else int(rank), s.size)
    Wf = Wn.reshape(F, 2, -1)
    Xk, mu, rel, res, hist = solve_kkt(X, Wf, Rf, a, eps_n, r, gtol=gtol, rtol=rtol,
                                       max_iter=max_iter)
    cert = rank_certificate(Xk, Wf, Rf, a, mu, r)
    Xk = project_to_fit(Xk, Wn, Rf, eps_n)
    return Xk, dict(mu=mu, grad_norm=rel, residual_gap=abs(float(np.log(res / eps_n))),
                    rank=r, n_iter=int(hist[:, 3].sum()), n_outer=len(hist),
                    rank_certificate=cert)


def _row_space_coordinates(W):
    """(W', V') with W = W' V' and V' (r, P) orthonormal rows, r = 2F, when P > 2F (QR of
    W'); (W, None) otherwise.

    Every ADMM iterate lies in R^3 (x) rowspace(W) (X_init does, and both steps keep it), so
    the solver runs exactly on W' and maps back with V': on dense data X# shrinks from
    F x 3P to F x 6F.
    """
    F2, P = W.shape
    if P <= F2:
        return W, None
    Q, Rq = np.linalg.qr(W.T)
    return Rq.T, Q.T


def _continuation_admm(W, Rf, eps, prior, rho0, lam, rho_max, tol, max_iter):
    """The ADMM of :func:`organic_fit` on (W (2F, r), R_f): returns X (F, 3, r), the
    weights, sigma(X_init#), the history, the iteration count and whether it converged."""
    F, r = W.shape[0] // 2, W.shape[1]
    Wf = W.reshape(F, 2, r)
    A = (Rf.transpose(0, 2, 1) @ Wf).reshape(F, -1)
    sA = np.linalg.svd(A, compute_uv=False)
    a = organic_weights(sA) if prior == "organic" else bilinear_weights(sA, sA.size, prior)
    X, U = A.copy(), np.zeros_like(A)
    rho = rho0
    hist = {k: [] for k in ("objective", "residual", "gap", "rho")}
    converged, it = False, 0
    for it in range(1, max_iter + 1):
        Y, s_y = weighted_svt(X - U, a * sA[0] / rho)                 # Y step (PSVT)
        X = project_to_fit((Y + U).reshape(F, 3, r), W, Rf, eps).reshape(F, -1)
        D = Y - X
        U += D
        gap = float(np.linalg.norm(D)) / sA[0]
        hist["objective"].append(float(a[:s_y.size] @ s_y))
        hist["residual"].append(float(np.linalg.norm(Rf @ X.reshape(F, 3, r) - Wf)))
        hist["gap"].append(gap)
        hist["rho"].append(rho)
        if gap < tol:
            converged = True
            break
        if rho >= rho_max:
            break
        U /= lam                                                       # U = multiplier / rho
        rho = min(rho * lam, rho_max)
    return X.reshape(F, 3, r), a, sA, hist, it, converged


def _select_candidate(X_admm, Wn, Rf, K, eps_n, a, label="admm"):
    """The feasible point of (C) with the lower objective: the ADMM's, or the closed-form
    rank-K shape projected onto the constraint. The latter is a candidate only when W has
    3K directions and the rank-K fit is unique (nullspace gap above ``NULLSPACE_GAP_MIN``):
    where W has fewer, the closed form works in W's smaller column space, where a planar
    basis has no exact triplet, and (C) can prefer its inexact fit (rigid plus planar,
    K = 2: e3d .044, the ADMM below 1e-6). It wins only if lower by more than a
    relative 1e-9."""
    X_cf, gap = closed_form_fit(Wn, Rf, K)        # (W' = U S: the same B, bases S V)
    cand = {label: organic_objective(X_admm, a)}
    s = np.linalg.svd(Wn, compute_uv=False)
    if not gap > NULLSPACE_GAP_MIN or np.sum(s > DETERMINED_RTOL * s[0]) < 3 * K:
        return X_admm, label, cand
    X_cf = project_to_fit(X_cf, Wn, Rf, eps_n)
    cand["closed_form"] = organic_objective(X_cf, a)
    if cand["closed_form"] < cand[label] * (1 - 1e-9):
        return X_cf, "closed_form", cand
    return X_admm, label, cand
