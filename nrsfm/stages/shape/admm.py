"""The paper's continuation ADMM for the shape stage (paper Sec. 3.2, ``solver="admm"``).

The paper's problem (Eq. 8, 10) is

    minimise_{X, X#}  1/2 ||W - R X||_F^2 + mu ||X#||_{r=N, theta}   s.t.  X# = Phi(X)

with ``||A||_{r=N, theta} = sum_{i > N} theta_i sigma_i(A)``, solved by ADMM (Eq. 11-14)
with the partial singular value thresholding (PSVT) operator of Oh et al. for the X# step
(:func:`admm_iterations`). Three priors share the machinery:

``organic``  (the paper): N = 1, theta_i = xi / (sigma_i(X_init#) + gamma) (Eq. 9).
``weighted`` (R-BMM-style baseline): N = 0, the same weights on every singular value.
``nuclear``  (BMM's shape model): N = 0, one weight ``c = sum_i theta_i sigma_i /
             sum_i sigma_i`` for every singular value (X_init pays the same penalty).

The ADMM is a continuation (rho grows 10 % per iteration): its answer is where the path
freezes, not a minimiser of Eq. (10). Its thresholds are absolute (``xi = 5e-3
sqrt(sigma_1(X_init#))``, ``rho0 = 1e-4``, ``theta_i = xi / sigma_i``), so its result depends
on the units of W: :func:`solve_admm`, the stage's entry, runs it on ``W / s`` with
``s = ||W||_F / TARGET_FROBENIUS`` and multiplies the shapes by ``s``. The rule uses W alone
and is homogeneous of degree one, so the stage is exactly scale invariant; but 170 is a
setting of this solver, chosen on the eight MoCap sequences (other targets give different
answers, ``docs/studies/shape.md``). The bilinear solver is scale-free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Optional

import numpy as np

from ...validation import check_integer, check_positive
from ..measurement import weighted_svt
from .common import PRIORS, ShapeResult, check_prior, check_shape_inputs, phi, phi_inv, \
    truncate_rank

__all__ = ["AdmmSettings", "TARGET_FROBENIUS", "admm_iterations", "normalization_scale",
           "psvt", "shape_weights", "solve_admm"]

#: Frobenius norm of the W the ADMM's constants are tuned for (its setting).
TARGET_FROBENIUS = 170.0
#: ``xi = XI_FACTOR sqrt(sigma_1(X_init#))`` (paper Sec. 4, implementation details)
XI_FACTOR = 5e-3
#: a progress line every this many iterations
PROGRESS_EVERY = 100


@dataclass(frozen=True)
class AdmmSettings:
    """The paper's continuation ADMM (``shape_solver="admm"``).

    Attributes
    ----------
    N : int or None
        Leading singular values left unpenalised; default from the prior
        (:data:`nrsfm.stages.shape.PRIORS`). The paper's ablation varies it (Fig. 3d).
    mu : float
        Weight of the regulariser (paper: 1).
    rho0, lam, rho_max : float
        Initial penalty, its growth per iteration (> 1) and its cap (paper: 1e-4, 1.1, 1e10).
    eps : float
        Stop when ``max |X# - Phi(X)| < eps`` (paper: 1e-10).
    xi, gamma : float
        Eq. (9); ``xi`` defaults to ``5e-3 sqrt(sigma_1(X_init#))``.
    max_iter : int
        Safety cap on iterations (the rho schedule alone stops after
        ``ceil(log(rho_max / rho0) / log(lam))`` iterations, 339 with the defaults).

    Raises
    ------
    ValueError
        A value out of range (named in the message).
    """

    name: ClassVar[str] = "admm"
    N: Optional[int] = None
    mu: float = 1.0
    rho0: float = 1e-4
    lam: float = 1.1
    rho_max: float = 1e10
    eps: float = 1e-10
    xi: Optional[float] = None
    gamma: float = 1e-6
    max_iter: int = 1000

    def __post_init__(self):
        if self.N is not None:
            check_integer(self.N, "N", minimum=0)
        check_positive("mu", self.mu, strict=False)
        for name in ("rho0", "rho_max", "lam", "gamma"):
            check_positive(name, getattr(self, name))
        check_positive("eps", self.eps, strict=False)
        if self.lam <= 1:
            raise ValueError(f"lam must be > 1 (rho grows each iteration); got {self.lam}")
        if self.xi is not None:
            check_positive("xi", self.xi)
        check_integer(self.max_iter, "max_iter", minimum=1)

    def solve(self, W, R, K, prior, progress=None):
        return solve_admm(W, R, K, prior, self, progress)


def normalization_scale(W):
    """``s = ||W||_F / TARGET_FROBENIUS``: the ADMM runs on ``W / s``.

    Raises
    ------
    ValueError
        W not 2-D, non-finite, or zero.
    """
    W = np.asarray(W, dtype=float)
    if W.ndim != 2:
        raise ValueError(f"W must be a 2-D (2F, P) matrix; got shape {W.shape}")
    if not np.all(np.isfinite(W)):
        raise ValueError("W contains NaN or infinite entries")
    norm = float(np.linalg.norm(W))
    if not norm > 0:
        raise ValueError("W is constant (every row has zero spread, W is zero after centring): "
                         "nothing to reconstruct")
    return norm / TARGET_FROBENIUS


# --------------------------------------------------------------------------------------
# PSVT and weights
# --------------------------------------------------------------------------------------

def psvt(Q, N, tau, return_singular_values=False):
    """Partial singular value thresholding ``P_{N, tau}[Q]`` (Oh et al.; paper's theorem).

    Solves ``argmin_P  ||P||_{r=N, tau} + 1/2 ||P - Q||_F^2`` where
    ``||P||_{r=N, tau} = sum_{i > N} tau_i sigma_i(P)``: the leading N singular values of Q
    are kept, the others soft-thresholded, ``sigma_i -> max(sigma_i - tau_i, 0)``. For a
    scalar tau this is Oh et al.'s theorem; for per-value thresholds that do not decrease
    with i (as Eq. 9 gives: smaller sigma, larger theta) it is still the exact proximal
    operator of the weighted partial sum (the weighted-SVT result of Gu et al., CVPR 2014).

    Parameters
    ----------
    Q : (m, n) array_like
    N : int
        Number of leading singular values left untouched, ``0 <= N``.
    tau : float or (min(m, n),) array_like
        Threshold, a scalar or one per singular value (entries for i < N are ignored).
        Must be non-negative.
    return_singular_values : bool
        Also return the thresholded singular values.

    Returns
    -------
    P : (m, n) ndarray
    s : (min(m, n),) ndarray
        Only if ``return_singular_values``: the singular values of P (in Q's order).

    Raises
    ------
    ValueError
        Q not 2-D or not finite, N negative or not an integer, tau negative, non-finite or
        of the wrong length.
    """
    Q = np.asarray(Q, dtype=float)
    if Q.ndim != 2:
        raise ValueError(f"Q must be a 2-D matrix; got shape {Q.shape}")
    if not np.all(np.isfinite(Q)):
        raise ValueError("Q contains NaN or infinite entries")
    r = min(Q.shape)
    N = _check_N(N)
    tau = _check_tau(tau, r)
    U, s, Vt = np.linalg.svd(Q, full_matrices=False)
    s_new = _threshold(s, N, tau)
    P = (U * s_new) @ Vt
    return (P, s_new) if return_singular_values else P


def _threshold(s, N, tau):
    """Keep s[:N], soft-threshold s[N:] by tau (scalar or per value)."""
    out = np.maximum(s - tau, 0.0)
    out[:N] = s[:N]
    return out


def _check_N(N):
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)):
        raise ValueError(f"N must be a non-negative integer; got {N!r}")
    if N < 0:
        raise ValueError(f"N must be a non-negative integer; got {N}")
    return int(N)


def _check_tau(tau, r):
    tau = np.asarray(tau, dtype=float)
    if tau.ndim == 0:
        tau = np.full(r, float(tau))
    elif tau.shape != (r,):
        raise ValueError(f"tau must be a scalar or have {r} entries (one per singular value);"
                         f" got shape {tau.shape}")
    if not np.all(np.isfinite(tau)) or np.any(tau < 0):
        raise ValueError("tau must be finite and non-negative")
    return tau


def shape_weights(sigma, xi=None, gamma=1e-6):
    """Organic shape weights, paper Eq. (9): ``theta_i = xi / (sigma_i + gamma)``.

    Parameters
    ----------
    sigma : (r,) array_like
        Singular values of ``X_init# = Phi(X_init)``, in decreasing order.
    xi : float, optional
        Numerator; default ``5e-3 * sqrt(sigma_1)`` (paper Sec. 4, implementation details).
    gamma : float
        Small positive constant preventing division by zero (paper: 1e-6).

    Returns
    -------
    theta : (r,) ndarray
        Weights, increasing as the singular values decrease.

    Raises
    ------
    ValueError
        sigma empty, negative or non-finite; xi or gamma not positive.
    """
    sigma = np.asarray(sigma, dtype=float)
    if sigma.ndim != 1 or sigma.size == 0:
        raise ValueError(f"sigma must be a non-empty 1-D array; got shape {sigma.shape}")
    if not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
        raise ValueError("sigma must be finite and non-negative")
    if not (np.isfinite(gamma) and gamma > 0):
        raise ValueError(f"gamma must be positive; got {gamma!r}")
    if xi is None:
        xi = XI_FACTOR * math.sqrt(float(sigma.max()))
    if not (np.isfinite(xi) and xi > 0):
        raise ValueError(f"xi must be positive; got {xi!r} (is X_init zero?)")
    return xi / (sigma + gamma)


# --------------------------------------------------------------------------------------
# ADMM (Eq. 10-14)
# --------------------------------------------------------------------------------------

def admm_iterations(W, R, K, prior, settings, progress=None):
    """Low-rank shape by ADMM on Eq. (10) with the PSVT X# step (paper Sec. 3.2).

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements, in the units the constants assume
        (:func:`solve_admm` brings W to ``||W||_F = TARGET_FROBENIUS`` first).
    R : (F, 3, 3) or (F, 2, 3) ndarray
        Camera rotations; the first two rows of each must be orthonormal.
    K : int
        Number of shape bases (the start is the rank-K truncation of X_init).
    prior : {"organic", "weighted", "nuclear"}
        Thresholding rule, see the module docstring.
    settings : AdmmSettings
    progress : callable(str) or None
        Called with a line every 100 iterations and at the end.

    Returns
    -------
    ShapeResult

    Raises
    ------
    ValueError
        Bad shapes, non-finite entries, non-orthonormal rotations, K out of range, unknown
        prior.

    Notes
    -----
    One iteration t (Eq. 11-14), with ``Z = Phi^-1(X# + Y / rho)``:

    * X step, per frame in closed form (Eq. 13):
      ``X_f = (R_f'R_f + rho I)^-1 (R_f'W_f + rho Z_f)``. For orthonormal rows,
      ``R_f'R_f`` is the projector onto the image plane, and the inverse reduces to
      ``X_f = Z_f + R_f'(W_f - R_f Z_f) / (1 + rho)`` (vectorised over frames).
    * X# step (Eq. 14 and the PSVT operator, Eq. 16-17):
      ``X# = P_{N, mu theta / rho}[Phi(X) - Y / rho]``.
    * ``Y += rho (X# - Phi(X))``; ``rho = min(rho_max, lam rho)``.
    * Stop when ``max |X# - Phi(X)| < eps`` or ``rho >= rho_max``.

    ``X = X#`` start at the rank-K truncation of X_init, ``Y`` at zero. The iterate returned
    is X, the data-step variable.
    """
    check_prior(prior)
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    st = settings
    N = PRIORS[prior] if st.N is None else st.N
    say = progress if callable(progress) else (lambda msg: None)
    Wf = W.reshape(F, 2, P)
    X_init = Rf.transpose(0, 2, 1) @ Wf             # pinv(R_f) = R_f' for orthonormal rows
    sigma = np.linalg.svd(phi(X_init), compute_uv=False)
    theta, reg_w, xi = _admm_weights(sigma, prior, N, st)
    X, hist, n_iter, converged = _iterate(Wf, Rf, X_init, K, N, reg_w, st, prior, say)
    resid = hist["residual"][-1]
    say(f"shape ADMM ({prior}, N={N}) stopped after {n_iter} iterations: "
        f"{'converged' if converged else 'not converged'}, residual {resid:.3g}, "
        f"cost {hist['cost'][-1]:.6g}")
    params = dict(vars(st), prior=prior, N=N, K=K, xi=xi)
    return ShapeResult(shapes=X, X_init=X_init, X_init_singular_values=sigma,
                       theta=theta, N=N, prior=prior, solver="admm", history=hist,
                       n_iter=n_iter, converged=converged, objective=hist["cost"][-1],
                       optimality=resid, optimality_kind="residual", params=params)


def solve_admm(W, R, K, prior="organic", settings=None, progress=None):
    """The shape stage's ADMM: :func:`admm_iterations` on ``W / s``,
    ``s = normalization_scale(W)``, with ``shapes``, ``X_init`` and its singular values
    returned in W's units (``theta`` and ``history`` stay in the ADMM's units;
    ``params["admm_scale"]`` is s)."""
    s = normalization_scale(W)
    settings = AdmmSettings() if settings is None else settings
    res = admm_iterations(W / s, R, K, prior, settings, progress)
    res.shapes, res.X_init = res.shapes * s, res.X_init * s
    res.X_init_singular_values = res.X_init_singular_values * s
    res.params["admm_scale"] = s
    return res


def _admm_weights(sigma, prior, N, settings):
    """(theta, mu theta with the first N zeroed, xi) from the singular values of X_init#."""
    if not sigma[0] > 0:
        raise ValueError("the pseudo-inverse shape is zero (W is zero?)")
    xi = XI_FACTOR * math.sqrt(float(sigma[0])) if settings.xi is None else settings.xi
    theta = shape_weights(sigma, xi, settings.gamma)        # Eq. (9)
    if prior == "nuclear":
        # Equal weights (BMM's plain nuclear norm), set so that X_init pays the same
        # penalty as under the weighted norm: c sum_i sigma_i = sum_i theta_i sigma_i.
        theta = np.full_like(sigma, float(theta @ sigma) / float(sigma.sum()))
    reg_w = settings.mu * theta.copy()
    reg_w[:N] = 0.0                                 # partial sum: first N free (Eq. 10)
    return theta, reg_w, xi


def _iterate(Wf, Rf, X_init, K, N, reg_w, st, prior, say):
    """The ADMM iterations (Eq. 11-14, Notes of :func:`admm_iterations`).

    Returns (X, history of arrays, iterations, converged)."""
    F, _, P = Wf.shape
    Rt = Rf.transpose(0, 2, 1)                      # (F, 3, 2)
    X = truncate_rank(X_init, K)
    Xs = phi(X).copy()
    Y = np.zeros_like(Xs)
    rho = st.rho0
    hist = {k: [] for k in ("cost", "data_term", "residual", "rho")}
    converged = False
    n_iter = 0
    for n_iter in range(1, st.max_iter + 1):
        # X step (Eq. 13), closed form per frame, vectorised.
        Z = phi_inv(Xs + Y / rho, P)
        X = Z + Rt @ (Wf - Rf @ Z) / (1.0 + rho)
        # X# step (Eq. 14, 17): PSVT of Phi(X) - Y / rho with tau_i = mu theta_i / rho (the
        # first N zero, the rest non-decreasing: weighted SVT from the shorter side's Gram
        # matrix, 2.5 x faster than an SVD at pickup's size)
        Xs, s_new = weighted_svt(phi(X) - Y / rho, reg_w / rho)
        # Multiplier and penalty updates.
        D = Xs - phi(X)
        Y += rho * D
        resid = float(np.abs(D).max())
        data = 0.5 * float(np.sum((Wf - Rf @ X) ** 2))
        hist["cost"].append(data + float(reg_w @ s_new))
        hist["data_term"].append(data)
        hist["residual"].append(resid)
        hist["rho"].append(rho)
        rho = min(st.rho_max, st.lam * rho)
        if n_iter % PROGRESS_EVERY == 0:
            say(f"shape ADMM ({prior}) iter {n_iter}: cost {hist['cost'][-1]:.6g}, "
                f"residual {resid:.3g}, rho {rho:.3g}")
        if resid < st.eps:
            converged = True
            break
        if rho >= st.rho_max:
            break
    return X, {k: np.asarray(v) for k, v in hist.items()}, n_iter, converged
