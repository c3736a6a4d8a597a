"""Soft-impute: nuclear-norm completion of the time-lagged W (paper Sec. 4e-ii).

With free per-row offsets t (the per-frame translation), of the lagged matrix H(W)
(:mod:`.lags`), every copy of a missing entry kept equal:

    minimise_{L, t}  1/2 ||P_Omega(H(W) - L - t 1')||_F^2 + tau ||L||_*.

Soft-impute (Mazumder, Hastie & Tibshirani, JMLR 2010) fills the missing entries with the
current estimate, takes the row means as t, soft-thresholds the singular values of the
centred H, averages the copies of each entry, and repeats; tau is continued from ``sigma_1 /
10`` down to ``TAU_FRACTION sigma_1`` (sigma_1 of the mean-filled, centred H), with warm
starts (Cabral et al.'s rank continuation, ICCV 2013). Scale-equivariant.
"""

from __future__ import annotations

import numpy as np

from ...linalg import weighted_svt
from .lags import NEIGHBOUR_LAGS, lag_copies, observed_entries
from .result import Completion

#: final threshold as a fraction of sigma_1; continuation stages; tolerance; iteration cap
TAU_FRACTION, N_STAGES, TOL, MAX_ITER = 1e-3, 8, 1e-6, 500


def complete_measurements(W, lags=NEIGHBOUR_LAGS):
    """Fill the missing entries of W (NaN) by nuclear-norm completion (soft-impute).

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        NaN marks a missing entry (:func:`~nrsfm.stages.completion.lags.observed_entries`).
    lags : sequence of int
        Temporal lags (frames), containing 0; ``(0,)``: plain nuclear-norm completion of W
        (for frames that are not a time sequence).

    Returns
    -------
    Completion
        ``method == "soft_impute"``.
    """
    Wz, observed = observed_entries(W)
    copies = lag_copies(*observed.shape, lags)
    obs2 = np.repeat(observed, 2, axis=0)  # (2F, P)
    result = dict(observed=observed, method="soft_impute", lags=copies.lags)
    if obs2.all():
        rank = int(np.linalg.matrix_rank(Wz))
        return Completion(W=Wz, rank=rank, n_iter=0, converged=True, **result)
    t = Wz.sum(axis=1, keepdims=True) / obs2.sum(axis=1, keepdims=True)
    Z = np.where(obs2, Wz, t)  # mean fill
    H = copies.lag(Z)
    sigma1 = float(np.linalg.svd(H - H.mean(axis=1, keepdims=True), compute_uv=False)[0])
    if not sigma1 > 0:
        raise ValueError("the observed entries of W have no spread: nothing to complete")
    tau = TAU_FRACTION * sigma1
    taus = np.geomspace(max(sigma1 / 10, tau), tau, N_STAGES)
    rank, n_iter, converged = _continuation(Z, ~obs2, copies, taus)
    return Completion(W=Z, rank=rank, n_iter=n_iter, converged=converged, **result)


def _continuation(Z, missing, copies, taus):
    """Soft-impute over the thresholds ``taus``, warm-started, filling ``Z[missing]`` in
    place; a stage stops when the relative change of the filled entries is below ``TOL``
    (the last) or ``10 TOL``. Returns ``(rank, n_iter, converged)``.

    Each step starts from an extrapolated point ``Z_k + (k - 1) / (k + 2) (Z_k - Z_k-1)``
    (FISTA, Beck and Teboulle 2009), restarted at each threshold and whenever the step turns
    against the momentum (O'Donoghue and Candes 2015): the fixed point of soft-impute."""
    n_iter, converged, rank = 0, False, 0
    scale = max(float(np.linalg.norm(Z)), 1e-300)
    for stage, tau_s in enumerate(taus):
        tol = TOL if stage == len(taus) - 1 else 10 * TOL
        converged = False
        prev, k = Z[missing], 0
        while n_iter < MAX_ITER:
            n_iter += 1
            k += 1
            cur = Z[missing]
            y = cur + (k - 1) / (k + 2) * (cur - prev)  # the extrapolated point
            Y = Z.copy()
            Y[missing] = y
            H = copies.lag(Y)
            t = H.mean(axis=1, keepdims=True)  # free row offsets
            # the prox, from the Gram matrix of H's short side (the small singular values
            # it loses are far below every threshold)
            fit, s = weighted_svt(H - t, np.full(min(H.shape), tau_s))
            rank = int(np.count_nonzero(s))
            fit += t
            new = copies.mean(fit, Z.shape)[missing]  # mean of each entry's copies
            change = np.linalg.norm(new - cur) / scale
            if np.vdot(y - new, new - cur) > 0:  # against the momentum
                k = 0
            prev = cur
            Z[missing] = new
            if change < tol:
                converged = True
                break
    return rank, n_iter, converged
