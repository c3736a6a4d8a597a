"""Soft-impute: nuclear-norm completion of the time-lagged W (paper Sec. 4e-ii).

Method (choice, measurements and reasons in ``docs/experiments.md``): nuclear-norm
completion with free per-row offsets (the per-frame translation) of the time-lagged matrix

    H(W) = [S_{-1} W, W, S_{+1} W]      (2F, 3P),   S_d: frames shifted by d,

    minimise_{L, t}  1/2 ||P_Omega(H(W) - L - t 1')||_F^2 + tau ||L||_*,

with every copy of a missing entry kept equal. The lags put a frame's neighbours beside it
in the same row, so a missing point is seen through its own trajectory at the adjacent
frames as well as through the other points: the rows of H are still low-rank (the
trajectories are smooth), and a row of H has three times the observed entries of a row of
W. ``lags=(0,)`` is plain nuclear-norm completion of W (for frames in no particular order).
Solved by soft-impute (Mazumder, Hastie & Tibshirani, JMLR 2010): fill the missing entries
with the current estimate, take the row means as t, soft-threshold the singular values of
the centred H by tau, average the copies of each missing entry, repeat; each step is
taken from a point extrapolated along the last one (Nesterov's momentum with adaptive
restart). tau is continued from ``sigma_1 / 10`` down to its final value ``tau = 1e-3 sigma_1`` (sigma_1: the largest
singular value of the mean-filled, row-centred H), with warm starts: the continuation idea
of Cabral et al.'s rank continuation (ICCV 2013), whose bilinear objective has the same
minimisers as the nuclear norm when the factor rank is large enough. The regulariser is
computed from W alone and the completion is scale-equivariant (W times c gives the
completion times c).

The paper completes W with Cabral et al.'s method and then runs its algorithm on the
completed matrix; :func:`nrsfm.reconstruct` does the same (``missing="complete"``). Its
default completion ``"auto"`` (:func:`nrsfm.stages.completion.complete`) runs soft-impute
where the lags rule asks for lags (MoCap-sized W: few points per frame for the rank, where
the full SVD per iteration is cheap), and the factorisation of
:mod:`~nrsfm.stages.completion.factorisation` elsewhere (dense tracks).
"""

from __future__ import annotations

import numpy as np

from ..measurement import weighted_svt
from .lags import NEIGHBOUR_LAGS, lag_copies
from .masks import observed_entries
from .result import Completion

__all__ = ["TAU_FRACTION", "complete_measurements", "soft_impute_lagged"]

#: Final threshold as a fraction of sigma_1 (see the module docstring).
TAU_FRACTION = 1e-3


def complete_measurements(W, observed=None, *, tau=None, tau_fraction=TAU_FRACTION,
                          lags=NEIGHBOUR_LAGS, n_stages=8, tol=1e-6, max_iter=500):
    """Fill the missing entries of W by nuclear-norm completion (soft-impute).

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Measurements; NaN marks a missing entry (a point is observed in a frame when both
        of its coordinates are finite).
    observed : (F, P) bool array_like, optional
        Further restricts the observation mask
        (:func:`~nrsfm.stages.completion.masks.observed_entries`).
    tau : float, optional
        Final singular value threshold in W's units; default ``tau_fraction * sigma_1``.
    tau_fraction : float
        See ``tau``; must be positive.
    lags : sequence of int
        Temporal lags (frames) of the lagged matrix, containing 0; ``(0,)``: plain
        nuclear-norm completion of W (use it when the frames are not a time sequence).
    n_stages : int
        Continuation stages, tau decreasing geometrically from ``sigma_1 / 10``.
    tol : float
        A stage stops when the relative change of the filled entries is below ``tol``.
    max_iter : int
        Total iteration cap; ``converged`` is False when it is reached.

    Returns
    -------
    Completion
        ``method == "soft_impute"``, with ``tau`` and ``history`` (``tau``, ``change``).

    Raises
    ------
    ValueError
        Bad shapes, a frame or point with too few observations, bad constants.
    """
    Wz, observed = observed_entries(W, observed)
    copies = lag_copies(*observed.shape, lags)
    return soft_impute_lagged(Wz, observed, copies, tau=tau, tau_fraction=tau_fraction,
                              n_stages=n_stages, tol=tol, max_iter=max_iter)


def soft_impute_lagged(Wz, observed, copies, *, tau=None, tau_fraction=TAU_FRACTION,
                       n_stages=8, tol=1e-6, max_iter=500):
    """:func:`complete_measurements` of checked input: ``Wz`` (2F, P) zero where not
    ``observed`` (F, P) (:func:`~nrsfm.stages.completion.masks.observed_entries`), the
    lagged matrix's :class:`~nrsfm.stages.completion.lags.Copies`."""
    if not (np.isfinite(tau_fraction) and tau_fraction > 0):
        raise ValueError(f"tau_fraction must be positive; got {tau_fraction!r}")
    if n_stages < 1 or max_iter < 1:
        raise ValueError(f"n_stages and max_iter must be >= 1; got {n_stages}, {max_iter}")
    obs2 = np.repeat(observed, 2, axis=0)                       # (2F, P)
    result = dict(observed=observed, method="soft_impute", lags=copies.lags)
    if obs2.all():
        return Completion(W=Wz, tau=0.0, rank=int(np.linalg.matrix_rank(Wz)), n_iter=0,
                          converged=True, history=dict(tau=np.zeros(0), change=np.zeros(0)),
                          **result)
    t = Wz.sum(axis=1, keepdims=True) / obs2.sum(axis=1, keepdims=True)
    Z = np.where(obs2, Wz, t)                                   # mean fill
    H = copies.lag(Z)
    sigma1 = float(np.linalg.svd(H - H.mean(axis=1, keepdims=True), compute_uv=False)[0])
    if not sigma1 > 0:
        raise ValueError("the observed entries of W have no spread: nothing to complete")
    tau_final = tau_fraction * sigma1 if tau is None else float(tau)
    if not (np.isfinite(tau_final) and tau_final > 0):
        raise ValueError(f"tau must be positive; got {tau!r}")
    taus = np.geomspace(max(sigma1 / 10, tau_final), tau_final, n_stages)
    rank, n_iter, converged, history = _continuation(Z, ~obs2, copies, taus, tol, max_iter)
    return Completion(W=Z, tau=float(tau_final), rank=rank, n_iter=n_iter,
                      converged=converged, history=history, **result)


def _continuation(Z, missing, copies, taus, tol, max_iter):
    """Soft-impute over the thresholds ``taus``, warm-started, filling ``Z[missing]`` in
    place. Returns ``(rank, n_iter, converged, history)``.

    Each step is soft-impute's (a proximal gradient step of step 1 on the missing entries)
    from an extrapolated point ``Z_k + (k - 1) / (k + 2) (Z_k - Z_k-1)`` (Nesterov's
    momentum, FISTA: Beck and Teboulle 2009), restarted at each threshold and whenever the
    step turns against the momentum (the gradient restart of O'Donoghue and Candes 2015).
    The same fixed point as plain soft-impute. Pickup with 30 % of the tracks lost (the
    ``lost`` pattern, seed 31): 500 iterations without reaching ``tol`` before, 282 with
    it (``docs/missing_data_scale.md``)."""
    hist_tau, hist_change = [], []
    n_iter, converged, rank = 0, False, 0
    scale = max(float(np.linalg.norm(Z)), 1e-300)
    for stage, tau_s in enumerate(taus):
        last = stage == len(taus) - 1
        converged = False
        prev, k = Z[missing], 0
        while n_iter < max_iter:
            n_iter += 1
            k += 1
            cur = Z[missing]
            y = cur + (k - 1) / (k + 2) * (cur - prev)          # the extrapolated point
            Y = Z.copy()
            Y[missing] = y
            H = copies.lag(Y)
            t = H.mean(axis=1, keepdims=True)                   # free row offsets
            # nuclear-norm prox: singular value thresholding from the Gram matrix of H's
            # short side (a third of the thin SVD's cost on pickup's 714 x 123 H; the small
            # singular values it loses are far below every threshold here)
            fit, s = weighted_svt(H - t, np.full(min(H.shape), tau_s))
            rank = int(np.count_nonzero(s))
            fit += t
            new = copies.mean(fit, Z.shape)[missing]            # mean of each entry's copies
            change = np.linalg.norm(new - cur) / scale
            if np.vdot(y - new, new - cur) > 0:                 # against the momentum
                k = 0
            prev = cur
            Z[missing] = new
            hist_tau.append(tau_s)
            hist_change.append(change)
            if change < (tol if last else 10 * tol):
                converged = True
                break
    return rank, n_iter, converged, dict(tau=np.asarray(hist_tau),
                                         change=np.asarray(hist_change))
