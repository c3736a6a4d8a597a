"""Missing data: low-rank completion of the measurement matrix W (paper Sec. 4e-ii).

A missing observation is a (frame, point) pair: both coordinates go together, so the mask
is per point and frame, ``observed`` (F, P), expanded to W's (2F, P) rows.

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
the centred H by tau, average the copies of each missing entry, repeat. tau is continued
from ``sigma_1 / 10`` down to its final value ``tau = 1e-3 sigma_1`` (sigma_1: the largest
singular value of the mean-filled, row-centred H), with warm starts: the continuation idea
of Cabral et al.'s rank continuation (ICCV 2013), whose bilinear objective has the same
minimisers as the nuclear norm when the factor rank is large enough. The regulariser is
computed from W alone and the completion is scale-equivariant (W times c gives the
completion times c).

The paper completes W with Cabral et al.'s method and then runs its algorithm on the
completed matrix; :func:`nrsfm.reconstruct` does the same (``missing="complete"``), by
default with the rank-3K factorisation of the observed entries of
:mod:`nrsfm.stages.completion_fast`, which scales to video (no SVD per iteration) and
was more accurate on every case of ``docs/missing_data_scale.md``; soft-impute stays as
``MeasurementSettings(completion="soft_impute")``. :func:`complete` chooses between them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CompletionResult", "choose_lags", "complete", "complete_measurements",
           "observed_mask"]

#: Final threshold as a fraction of sigma_1 (see the module docstring).
TAU_FRACTION = 1e-3
#: Default temporal lags (frames) of the lagged matrix H(W).
LAGS = (-1, 0, 1)
#: :func:`choose_lags`: lags when a frame observes fewer than this many points per unknown
#: of its rows (r + 1).
LAG_RATIO = 2


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
    lags : tuple of int
        Temporal lags used.
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
    lags: tuple = LAGS

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
    _refuse_sparse(observed.sum(axis=1), min_points, "frame", "observes {n} points")
    _refuse_sparse(observed.sum(axis=0), min_frames, "point", "is observed in {n} frames")
    return observed


def _refuse_sparse(counts, minimum, what, observes):
    """ValueError naming the first of the frames (or points) with fewer than ``minimum``
    observations, and how many there are."""
    bad = np.flatnonzero(counts < minimum)
    if bad.size:
        raise ValueError(
            f"{what} {int(bad[0])} {observes.format(n=int(counts[bad[0]]))} (at least "
            f"{minimum} are needed to determine it); {bad.size} {what}(s) too sparse: "
            f"{bad[:10].tolist()}{' ...' if bad.size > 10 else ''}")


def _lag_index(F, lags):
    """(len(lags), F) frame index of each lagged copy (edges repeated)."""
    return np.clip(np.arange(F)[None, :] + np.asarray(lags)[:, None], 0, F - 1)


def _lag(A, idx):
    """The lagged matrix ``[S_d A]_d`` (n_rows, n_lags P) of A (n_rows, P) whose rows come
    in equal groups per frame (W: 2 rows per frame; the mask (F, P): 1)."""
    F, P = idx.shape[1], A.shape[1]
    Af = A.reshape(F, -1, P)
    return np.concatenate([Af[i].reshape(-1, P) for i in idx], axis=1)


def _average_copies(L, idx):
    """(2F, P): each entry of W as the mean of its copies in the lagged L (2F, n_lags P)."""
    n, F = idx.shape
    P = L.shape[1] // n
    acc, counts = np.zeros((F, 2, P)), np.zeros(F)
    for j, i in enumerate(idx):
        np.add.at(acc, i, L[:, j * P:(j + 1) * P].reshape(F, 2, P))
        np.add.at(counts, i, 1.0)
    return (acc / counts[:, None, None]).reshape(2 * F, P)


def choose_lags(observed, rank):
    """Temporal lags for completing W at rank r, from its (F, P) observation mask alone.

    Each frame's two rows and offset (r + 1 unknowns per row) are fitted to the points the
    frame observes. When the frame observing the fewest points has fewer than
    ``LAG_RATIO * (r + 1)`` of them, a frame's own observations barely determine its rows
    (MoCap: 41 markers, r = 3K = 30-36, about 29 observed at 30 % missing) and the lags
    ``(-1, 0, 1)`` add its neighbours' observations; otherwise (dense tracks: thousands of
    points per frame at r = 3-6) ``(0,)``. Measurements: ``docs/missing_data_scale.md``.

    Parameters
    ----------
    observed : (F, P) bool ndarray
    rank : int

    Returns
    -------
    tuple of int
    """
    fewest = int(np.asarray(observed, bool).sum(axis=1).min())
    return (-1, 0, 1) if fewest < LAG_RATIO * (int(rank) + 1) else (0,)


def complete(W, K, settings):
    """Fill the missing entries of W for K shape bases, as ``settings`` say.

    Parameters
    ----------
    W : (2F, P) ndarray
        NaN where missing.
    K : int
        Rank of the completion: 3K (Eq. 1).
    settings : nrsfm.settings.MeasurementSettings
        ``completion`` (``auto``, ``factorisation`` or ``soft_impute``) and ``lags``.

    Returns
    -------
    CompletionResult or nrsfm.stages.completion_fast.FastCompletion
        Both with ``W`` (completed), ``observed``, ``n_iter``, ``converged`` and ``lags``.
    """
    observed = observed_mask(W)
    lags = (choose_lags(observed, 3 * K) if settings.lags == "auto"
            else tuple(settings.lags))
    method = settings.completion
    if method == "auto":                  # the full SVD is cheap exactly where lags are due
        method = "soft_impute" if len(lags) > 1 else "factorisation"
    if method == "soft_impute":
        return complete_measurements(W, observed, lags=lags)
    from .completion_fast import complete_low_rank

    return complete_low_rank(W, 3 * K, observed, lags=lags)


def complete_measurements(W, observed=None, *, tau=None, tau_fraction=TAU_FRACTION,
                          lags=LAGS, n_stages=8, tol=1e-6, max_iter=500):
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
    lags = tuple(int(d) for d in lags)
    if 0 not in lags or len(set(lags)) != len(lags):
        raise ValueError(f"lags must be distinct integers including 0; got {lags}")
    if n_stages < 1 or max_iter < 1:
        raise ValueError(f"n_stages and max_iter must be >= 1; got {n_stages}, {max_iter}")
    obs2 = np.repeat(observed, 2, axis=0)                       # (2F, P)
    if obs2.all():
        return CompletionResult(W=W, observed=observed, tau=0.0,
                                rank=int(np.linalg.matrix_rank(W)), n_iter=0,
                                converged=True, history=dict(tau=np.zeros(0),
                                                             change=np.zeros(0)), lags=lags)
    Wz = np.where(obs2, W, 0.0)
    t = Wz.sum(axis=1, keepdims=True) / obs2.sum(axis=1, keepdims=True)
    Z = np.where(obs2, W, t)                                    # mean fill
    idx = _lag_index(F, lags)                                   # (n_lags, F)
    H = _lag(Z, idx)
    sigma1 = float(np.linalg.svd(H - H.mean(axis=1, keepdims=True), compute_uv=False)[0])
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
            H = _lag(Z, idx)
            t = H.mean(axis=1, keepdims=True)                   # free row offsets
            U, s, Vt = np.linalg.svd(H - t, full_matrices=False)
            s = np.maximum(s - tau_s, 0.0)                      # nuclear-norm prox
            rank = int(np.count_nonzero(s))
            L = _average_copies((U[:, :rank] * s[:rank]) @ Vt[:rank] + t, idx)
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
                                         change=np.asarray(hist_change)), lags=lags)
