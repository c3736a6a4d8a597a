"""Missing data: low-rank completion of the measurement matrix W (paper Sec. 4e-ii).

A missing observation is a (frame, point) pair: both coordinates go together, so the mask
is per point and frame, ``observed`` (F, P), expanded to W's (2F, P) rows.

Method (choice, measurements and reasons in ``docs/experiments.md``): nuclear-norm
completion with free per-row offsets (the per-frame translation),

    minimise_{L, t}  1/2 ||P_Omega(W - L - t 1')||_F^2 + tau ||L||_*,

solved by soft-impute (Mazumder, Hastie & Tibshirani, JMLR 2010): fill the missing entries
with the current estimate, take the row means as t, soft-threshold the singular values of
the centred matrix by tau, repeat. tau is continued from ``sigma_1 / 10`` down to its final
value ``tau = 1e-3 sigma_1`` (sigma_1: the largest singular value of the mean-filled,
row-centred W), with warm starts: the same continuation idea as Cabral et al.'s rank
continuation (ICCV 2013), whose bilinear objective has the same minimisers as this
nuclear-norm problem when the factor rank is large enough (their Sec. 3). The regulariser
is computed from W alone and is scale-invariant (multiply W by c and the completion is
multiplied by c).

The paper completes W with Cabral et al.'s method and then runs its algorithm on the
completed matrix; :func:`nrsfm.reconstruct` does the same (``missing="complete"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CompletionResult", "complete_measurements", "observed_mask"]

#: Final threshold as a fraction of sigma_1 (see the module docstring).
TAU_FRACTION = 1e-3


@dataclass
class CompletionResult:
    """Result of :func:`complete_measurements`.

    Attributes
    ----------
    W : (2F, P) ndarray
        The completed matrix: observed entries unchanged, missing ones filled.
    observed : (F, P) bool ndarray
        True where the point was observed in the frame.
    tau : float
        Final singular value threshold (input units).
    rank : int
        Number of singular values left above the threshold at the end.
    n_iter : int
        Soft-impute iterations over the whole continuation.
    converged : bool
        The last stage's relative change fell below ``tol``.
    history : dict of ndarrays
        Per iteration: ``tau`` and ``change`` (relative change of the filled entries).
    """

    W: np.ndarray
    observed: np.ndarray
    tau: float
    rank: int
    n_iter: int
    converged: bool
    history: dict = field(default_factory=dict)

    @property
    def missing_fraction(self):
        return float(1.0 - self.observed.mean())


def observed_mask(W, min_points=3, min_frames=2):
    """The (F, P) observation mask of a (2F, P) W with NaN for missing entries.

    A point counts as observed in a frame only when both of its coordinates are finite.

    Parameters
    ----------
    W : (2F, P) ndarray
    min_points : int
        Each frame must observe at least this many points (an orthographic camera and its
        translation need 3).
    min_frames : int
        Each point must be observed in at least this many frames (its depth needs 2).

    Returns
    -------
    observed : (F, P) bool ndarray

    Raises
    ------
    ValueError
        Infinite entries, or a frame / point with too few observations (named).
    """
    W = np.asarray(W, dtype=float)
    if np.any(np.isinf(W)):
        raise ValueError(f"W contains {int(np.isinf(W).sum())} infinite entries "
                         "(use NaN for a missing observation)")
    F, P = W.shape[0] // 2, W.shape[1]
    finite = np.isfinite(W).reshape(F, 2, P)
    observed = finite.all(axis=1)
    per_frame = observed.sum(axis=1)
    bad = np.flatnonzero(per_frame < min_points)
    if bad.size:
        raise ValueError(
            f"frame {int(bad[0])} observes {int(per_frame[bad[0]])} points (at least "
            f"{min_points} are needed to determine it); {bad.size} frame(s) too sparse: "
            f"{bad[:10].tolist()}{' ...' if bad.size > 10 else ''}")
    per_point = observed.sum(axis=0)
    bad = np.flatnonzero(per_point < min_frames)
    if bad.size:
        raise ValueError(
            f"point {int(bad[0])} is observed in {int(per_point[bad[0]])} frames (at least "
            f"{min_frames} are needed to determine it); {bad.size} point(s) too sparse: "
            f"{bad[:10].tolist()}{' ...' if bad.size > 10 else ''}")
    return observed


def complete_measurements(W, observed=None, *, tau=None, tau_fraction=TAU_FRACTION,
                          n_stages=8, tol=1e-6, max_iter=3000):
    """Fill the missing entries of W by nuclear-norm completion (soft-impute).

    Parameters
    ----------
    W : (2F, P) array_like
        Measurements; NaN marks a missing entry (when ``observed`` is None).
    observed : (F, P) bool array_like, optional
        True where observed; default from the NaN pattern of W (:func:`observed_mask`).
    tau : float, optional
        Final singular value threshold in W's units; default ``tau_fraction * sigma_1``.
    tau_fraction : float
        See ``tau``; must be positive.
    n_stages : int
        Continuation stages, tau decreasing geometrically from ``sigma_1 / 10``.
    tol : float
        A stage stops when the relative change of the filled entries is below ``tol``.
    max_iter : int
        Total iteration cap; ``converged`` is False when it is reached.

    Returns
    -------
    CompletionResult

    Raises
    ------
    ValueError
        Bad shapes, a frame or point with too few observations, bad constants.
    """
    W = np.array(W, dtype=float, copy=True)
    if W.ndim != 2 or W.shape[0] % 2:
        raise ValueError(f"W must have shape (2F, P); got {W.shape}")
    F, P = W.shape[0] // 2, W.shape[1]
    if observed is None:
        observed = observed_mask(W)
    else:
        observed = np.asarray(observed, dtype=bool)
        if observed.shape != (F, P):
            raise ValueError(f"observed must have shape (F, P) = ({F}, {P}); "
                             f"got {observed.shape}")
        W[np.repeat(~observed, 2, axis=0)] = np.nan
        observed = observed & observed_mask(W)
    if not (np.isfinite(tau_fraction) and tau_fraction > 0):
        raise ValueError(f"tau_fraction must be positive; got {tau_fraction!r}")
    if n_stages < 1 or max_iter < 1:
        raise ValueError(f"n_stages and max_iter must be >= 1; got {n_stages}, {max_iter}")
    obs2 = np.repeat(observed, 2, axis=0)                       # (2F, P)
    if obs2.all():
        return CompletionResult(W=W, observed=observed, tau=0.0,
                                rank=int(np.linalg.matrix_rank(W)), n_iter=0,
                                converged=True, history=dict(tau=np.zeros(0),
                                                             change=np.zeros(0)))
    Wz = np.where(obs2, W, 0.0)
    t = Wz.sum(axis=1, keepdims=True) / obs2.sum(axis=1, keepdims=True)
    Z = np.where(obs2, W, t)                                    # mean fill
    sigma1 = float(np.linalg.svd(Z - Z.mean(axis=1, keepdims=True), compute_uv=False)[0])
    if not sigma1 > 0:
        raise ValueError("the observed entries of W have no spread: nothing to complete")
    tau_final = tau_fraction * sigma1 if tau is None else float(tau)
    if not (np.isfinite(tau_final) and tau_final > 0):
        raise ValueError(f"tau must be positive; got {tau!r}")
    taus = np.geomspace(max(sigma1 / 10, tau_final), tau_final, n_stages)
    hist_tau, hist_change = [], []
    n_iter, converged, rank = 0, False, 0
    missing = ~obs2
    for stage, tau_s in enumerate(taus):
        last = stage == len(taus) - 1
        converged = False
        while n_iter < max_iter:
            n_iter += 1
            t = Z.mean(axis=1, keepdims=True)                   # free row offsets
            U, s, Vt = np.linalg.svd(Z - t, full_matrices=False)
            s = np.maximum(s - tau_s, 0.0)                      # nuclear-norm prox
            rank = int(np.count_nonzero(s))
            L = (U[:, :rank] * s[:rank]) @ Vt[:rank] + t
            change = (np.linalg.norm(L[missing] - Z[missing])
                      / max(np.linalg.norm(Z), 1e-300))
            Z[missing] = L[missing]
            hist_tau.append(tau_s)
            hist_change.append(change)
            if change < (tol if last else 10 * tol):
                converged = True
                break
    return CompletionResult(W=Z, observed=observed, tau=float(tau_final), rank=rank,
                            n_iter=n_iter, converged=converged,
                            history=dict(tau=np.asarray(hist_tau),
                                         change=np.asarray(hist_change)))
