"""The paper's continuation ADMM for the shape stage (paper Sec. 3.2, ``solver="admm"``).

    minimise_{X, X#}  1/2 ||W - R X||_F^2 + mu ||X#||_{r=N, theta}   s.t.  X# = Phi(X)

with ``||A||_{r=N, theta} = sum_{i > N} theta_i sigma_i(A)`` (Eq. 8, 10), by ADMM (Eq. 11-14)
with partial singular value thresholding (PSVT, Oh et al.) for the X# step. The priors:
``organic`` N = 1, ``theta_i = xi / (sigma_i(X_init#) + gamma)`` (Eq. 9); ``weighted`` N = 0,
the same weights; ``nuclear`` N = 0, one weight ``sum_i theta_i sigma_i / sum_i sigma_i``.

The ADMM is a continuation (rho grows 10 % per iteration): its answer is where the path
freezes. Its thresholds are absolute, so :func:`solve_admm` runs it on ``W / s``,
``s = ||W||_F / TARGET_FROBENIUS``, and scales the shapes back: scale invariant to rounding,
with 170 a setting of this solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Optional

import numpy as np

from ...linalg import weighted_svt
from ...validation import check_integer, check_positive, check_shape_inputs
from ..measurement import WORKING_FROBENIUS
from .common import PRIORS, ShapeResult, check_prior, phi, phi_inv, truncate_rank

__all__ = ["AdmmSettings", "admm_iterations", "psvt", "shape_weights", "solve_admm"]

#: Frobenius norm of the W the ADMM's constants are tuned for: the working norm
TARGET_FROBENIUS = WORKING_FROBENIUS
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
        (:data:`nrsfm.stages.shape.PRIORS`). The paper's ablation varies it (Fig. 4d).
    mu : float
        Weight of the regulariser (paper: 1).
    rho0, lam, rho_max : float
        Initial penalty, its growth per iteration (> 1) and its cap (paper: 1e-4, 1.1, 1e10).
    eps : float
        Stop when ``max |X# - Phi(X)| < eps`` (paper: 1e-10).
    xi, gamma : float
        Eq. (9); ``xi`` defaults to ``5e-3 sqrt(sigma_1(X_init#))``.
    max_iter : int
        Cap on iterations (the rho schedule stops after 339 with the defaults).

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
        W not 2-D, not finite, or zero (nothing to reconstruct).
    """
    W = np.asarray(W, dtype=float)
    norm = float(np.linalg.norm(W)) if W.ndim == 2 else float("nan")
    if not 0 < norm < np.inf:
        raise ValueError(
            f"W must be a finite, non-zero (2F, P) matrix; got shape {W.shape}, norm {norm:g}"
        )
    return norm / TARGET_FROBENIUS


def psvt(Q, N, tau, return_singular_values=False):
    """Partial singular value thresholding ``P_{N, tau}[Q]`` (Oh et al.; paper Eq. 16-17).

    ``argmin_P sum_{i > N} tau_i sigma_i(P) + 1/2 ||P - Q||_F^2``: the leading N singular
    values of Q are kept, the others ``sigma_i -> max(sigma_i - tau_i, 0)``. Exact also for
    per-value thresholds that do not decrease with i, as Eq. 9 gives (Gu et al., CVPR 2014).

    Parameters
    ----------
    Q : (m, n) array_like
    N : int
        Leading singular values left untouched, ``N >= 0``.
    tau : float or (min(m, n),) array_like
        Non-negative threshold(s); entries for i < N are ignored.
    return_singular_values : bool
        Also return the singular values of P.

    Returns
    -------
    P : (m, n) ndarray, and s : (min(m, n),) ndarray if ``return_singular_values``

    Raises
    ------
    ValueError
        Q not a finite 2-D matrix, N not a non-negative integer, tau negative, non-finite
        or of the wrong length.
    """
    Q = np.asarray(Q, dtype=float)
    if Q.ndim != 2 or not np.all(np.isfinite(Q)):
        raise ValueError(f"Q must be a finite 2-D matrix; got shape {Q.shape}")
    N = check_integer(N, "N", minimum=0)
    r = min(Q.shape)
    tau = np.asarray(tau, dtype=float)
    if tau.shape not in ((), (r,)) or not np.all(np.isfinite(tau)) or np.any(tau < 0):
        raise ValueError(f"tau must be non-negative, a scalar or {r} values; got {tau!r}")
    U, s, Vt = np.linalg.svd(Q, full_matrices=False)
    s_new = np.maximum(s - tau, 0.0)
    s_new[:N] = s[:N]
    P = (U * s_new) @ Vt
    return (P, s_new) if return_singular_values else P


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
    One iteration (Eq. 11-14), with ``Z = Phi^-1(X# + Y / rho)``: the X step per frame,
    ``X_f = (R_f'R_f + rho I)^-1 (R_f'W_f + rho Z_f) = Z_f + R_f'(W_f - R_f Z_f) / (1 + rho)``
    (orthonormal rows, Eq. 13); the X# step ``X# = P_{N, mu theta / rho}[Phi(X) - Y / rho]``
    (Eq. 14, 16-17); ``Y += rho (X# - Phi(X))``, ``rho = min(rho_max, lam rho)``; stop when
    ``max |X# - Phi(X)| < eps`` or ``rho >= rho_max``. ``X = X#`` start at the rank-K
    truncation of X_init, Y at zero; the iterate returned is X.
    """
    check_prior(prior)
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    st = settings
    N = PRIORS[prior] if st.N is None else st.N
    say = progress if callable(progress) else (lambda msg: None)
    Wf = W.reshape(F, 2, P)
    X_init = Rf.transpose(0, 2, 1) @ Wf  # pinv(R_f) = R_f' for orthonormal rows
    sigma = np.linalg.svd(phi(X_init), compute_uv=False)
    theta, reg_w, xi = _admm_weights(sigma, prior, N, st)
    Rt = Rf.transpose(0, 2, 1)  # (F, 3, 2)
    Xs = phi(truncate_rank(X_init, K)).copy()
    Y, rho, n_iter, converged = np.zeros_like(Xs), st.rho0, 0, False
    hist = {k: [] for k in ("cost", "data_term", "residual", "rho")}
    for n_iter in range(1, st.max_iter + 1):
        Z = phi_inv(Xs + Y / rho, P)  # X step (Eq. 13), closed form per frame
        X = Z + Rt @ (Wf - Rf @ Z) / (1.0 + rho)
        # X# step (Eq. 14, 17): PSVT with tau_i = mu theta_i / rho, the first N zero
        Xs, s_new = weighted_svt(phi(X) - Y / rho, reg_w / rho)
        D = Xs - phi(X)  # multiplier and penalty updates
        Y += rho * D
        resid = float(np.abs(D).max())
        data = 0.5 * float(np.sum((Wf - Rf @ X) ** 2))
        for key, value in zip(hist, (data + float(reg_w @ s_new), data, resid, rho)):
            hist[key].append(value)
        rho = min(st.rho_max, st.lam * rho)
        if n_iter % PROGRESS_EVERY == 0:
            say(
                f"shape ADMM ({prior}) iter {n_iter}: cost {hist['cost'][-1]:.6g}, "
                f"residual {resid:.3g}, rho {rho:.3g}"
            )
        converged = resid < st.eps
        if converged or rho >= st.rho_max:
            break
    hist = {k: np.asarray(v) for k, v in hist.items()}
    say(
        f"shape ADMM ({prior}, N={N}) stopped after {n_iter} iterations: "
        f"{'converged' if converged else 'not converged'}, residual {resid:.3g}, "
        f"cost {hist['cost'][-1]:.6g}"
    )
    result = ShapeResult(X, X_init, sigma, theta, N, prior, "admm", hist, n_iter, converged)
    result.objective, result.optimality = hist["cost"][-1], resid
    result.params = dict(vars(st), prior=prior, N=N, K=K, xi=xi)
    return result


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
    theta = shape_weights(sigma, xi, settings.gamma)  # Eq. (9)
    if prior == "nuclear":
        # Equal weights (BMM's plain nuclear norm), set so that X_init pays the same
        # penalty as under the weighted norm: c sum_i sigma_i = sum_i theta_i sigma_i.
        theta = np.full_like(sigma, float(theta @ sigma) / float(sigma.sum()))
    reg_w = settings.mu * theta.copy()
    reg_w[:N] = 0.0  # partial sum: first N free (Eq. 10)
    return theta, reg_w, xi
