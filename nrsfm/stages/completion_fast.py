"""Missing data at the scale of video: low-rank factorisation of the observed entries.

A missing observation is a (frame, point) pair: both coordinates go together, so the mask
is ``observed`` (F, P), expanded to W's (2F, P) rows. The model is the orthographic
measurement model of the paper's Eq. 1 with the per-frame translation kept explicit,
because with missing entries W cannot be centred before it is factorised:

    W  ~  M B + t 1'          M (2F, r),  B (r, P),  t (2F,)

and the factorisation is fitted to the observed entries only, with a small ridge on the
factors (the bilinear form of a nuclear-norm penalty, Cabral et al., ICCV 2013):

    minimise_{M, B, t}  1/2 ||P_Omega(W - M B - t 1')||_F^2 + lam/2 (||M||_F^2 + ||B||_F^2).

It is solved by alternating exact least squares (the "ALS" baseline of Okatani, Yoshida &
Deguchi, ICCV 2011, here with a ridge): with M fixed every column b_p is an r x r system
over the frames that observe point p; with B fixed every frame's two rows (and their offset)
are an (r + 1) x (r + 1) system over the points the frame observes. Both steps are batched
Gram products, so one iteration costs O(|Omega| r^2) -- no SVD at all after the start,
which is a rank-r truncated SVD (through the smaller Gram matrix) of the mean-filled W.
The missing entries are then filled with ``M B + t`` and the observed ones kept.

The ridge is ``lam = lam_fraction * sigma_1`` (sigma_1: largest singular value of the
mean-filled, row-centred W): computed from W alone and scale-equivariant (W times c gives
the completion times c). Frames need not be in time order.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FastCompletion", "complete_low_rank", "fill_gain", "observed_entries"]

#: Ridge as a fraction of sigma_1 (see the module docstring).
LAM_FRACTION = 1e-4
#: A track is "determined" when its fill amplifies measurement noise at most this much
#: (see :func:`fill_gain`).
MAX_GAIN = 3.0


@dataclass
class FastCompletion:
    """Result of :func:`complete_low_rank`.

    Attributes
    ----------
    W : (2F, P) ndarray
        Completed matrix: observed entries unchanged, missing ones ``M B + t``.
    observed : (F, P) bool ndarray
        True where the point was observed in the frame.
    M : (2F, r) ndarray
        Motion factor (row pairs per frame).
    B : (r, P) ndarray
        Structure factor.
    t : (2F,) ndarray
        Per-row offset (the per-frame translation, before centring).
    rank, n_iter : int
    lam : float
        Ridge weight (input units).
    converged : bool
        The relative decrease of the objective fell below ``tol`` before ``max_iter``.
    history : dict of ndarrays
        ``cost`` per iteration (objective / (1/2 ||P_Omega(W - mean)||^2)).
    """

    W: np.ndarray
    observed: np.ndarray
    M: np.ndarray
    B: np.ndarray
    t: np.ndarray
    rank: int
    lam: float
    n_iter: int
    converged: bool
    history: dict = field(default_factory=dict)

    @property
    def missing_fraction(self):
        return float(1.0 - self.observed.mean())

    def determined(self, max_gain=MAX_GAIN):
        """(P,) bool: tracks whose filled entries amplify noise at most ``max_gain`` x."""
        return fill_gain(self.M, self.observed) <= max_gain

    def rms_residual(self):
        """RMS of the fit on the observed entries (input units)."""
        o2 = np.repeat(self.observed, 2, axis=0)
        fit = self.M @ self.B + self.t[:, None]
        return float(np.sqrt(np.mean((self.W - fit)[o2] ** 2)))


def observed_entries(W, observed=None):
    """Split W into zero-filled values and the (F, P) observation mask.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        NaN marks a missing coordinate; a point is observed in a frame when both are finite.
    observed : (F, P) bool array_like, optional
        Further restricts the mask.

    Returns
    -------
    Wz : (2F, P) ndarray
        W with every unobserved entry set to 0.
    observed : (F, P) bool ndarray

    Raises
    ------
    ValueError
        Bad shapes, infinite entries, a frame observing fewer than 3 points or a point
        observed in fewer than 2 frames (named).
    """
    A = np.array(W, dtype=float)
    if A.ndim == 3 and A.shape[1] == 2:
        A = A.reshape(2 * A.shape[0], A.shape[2])
    if A.ndim != 2 or A.shape[0] % 2:
        raise ValueError(f"W must have shape (2F, P) or (F, 2, P); got {np.shape(W)}")
    if np.isinf(A).any():
        raise ValueError(f"W contains {int(np.isinf(A).sum())} infinite entries "
                         "(use NaN for a missing observation)")
    F, P = A.shape[0] // 2, A.shape[1]
    obs = np.isfinite(A).reshape(F, 2, P).all(axis=1)
    if observed is not None:
        observed = np.asarray(observed, dtype=bool)
        if observed.shape != (F, P):
            raise ValueError(f"observed must have shape (F, P) = ({F}, {P}); "
                             f"got {observed.shape}")
        obs &= observed
    _check_coverage(obs)
    Wz = np.where(np.repeat(obs, 2, axis=0), A, 0.0)
    return Wz, obs


def _check_coverage(obs, min_points=3, min_frames=2):
    """Raise ValueError naming the first frame / point with too few observations."""
    for axis, what, other, need in ((1, "frame", "points", min_points),
                                    (0, "point", "frames", min_frames)):
        n = obs.sum(axis=axis)
        bad = np.flatnonzero(n < need)
        if bad.size:
            raise ValueError(f"{what} {int(bad[0])} is observed with {int(n[bad[0]])} "
                             f"{other} (at least {need} are needed); {bad.size} "
                             f"{what}(s) too sparse: {bad[:10].tolist()}")


def _truncated_svd(A, r):
    """Rank-r SVD ``U s Vt`` of A (m, n) through the Gram matrix of its smaller side."""
    tall = A.shape[0] > A.shape[1]
    G = A.T @ A if tall else A @ A.T
    lam, V = np.linalg.eigh(G)
    order = np.argsort(lam)[::-1][:r]
    s = np.sqrt(np.clip(lam[order], 0.0, None))
    V = V[:, order]
    inv = np.where(s > s[0] * 1e-12, 1.0 / np.maximum(s, 1e-300), 0.0)
    if tall:
        return (A @ V) * inv, s, V.T
    return V, s, (V * inv).T @ A


def _mask_groups(obs):
    """Points that share an observation pattern: ``(patterns (U, F) bool, index (P,))``."""
    packed = np.packbits(obs.T, axis=1)
    _, first, index = np.unique(packed, axis=0, return_index=True, return_inverse=True)
    return obs[:, first].T, index.ravel()


def _solve_structure(Wz, groups, M, t, lam):
    """B-step: per point, ridge least squares over the frames that observe it. (r, P).

    ``groups`` from :func:`_mask_groups`: the r x r normal matrix depends on the point only
    through its observation pattern, so it is inverted once per pattern.
    """
    patterns, index = groups
    F2, r = M.shape
    Mf = M.reshape(F2 // 2, 2, r)
    G = np.einsum("fir,fis->frs", Mf, Mf).reshape(F2 // 2, r * r)
    A = (patterns.astype(float) @ G).reshape(-1, r, r) + lam * np.eye(r)
    inv = np.linalg.inv(A)                                    # (U, r, r)
    o2 = np.repeat(patterns, 2, axis=1).astype(float)         # (U, 2F)
    rhs = M.T @ Wz - ((M * t[:, None]).T @ o2.T)[:, index]    # (r, P)
    return np.einsum("prs,sp->rp", inv[index], rhs)


def _solve_motion(Wz, obs, B, lam):
    """M-step: per frame, ridge least squares for its two rows and offset.

    Returns ``(M, t, data)``: ``data`` is ``||P_Omega(W - M B - t 1')||^2`` at the solution,
    from the normal equations (no 2F x P residual is formed).
    """
    r, P = B.shape
    F = obs.shape[0]
    Bt = np.vstack([B, np.ones((1, P))])                      # (r + 1, P)
    outer = np.einsum("ip,jp->pij", Bt, Bt).reshape(P, -1)
    A = (obs.astype(float) @ outer).reshape(F, r + 1, r + 1)
    reg = np.diag(np.r_[np.full(r, lam), 0.0])
    rhs = (Wz @ Bt.T).reshape(F, 2, r + 1).transpose(0, 2, 1)  # (F, r + 1, 2)
    X = np.linalg.solve(A + reg, rhs)                          # (F, r + 1, 2)
    data = (np.sum(Wz * Wz) - 2.0 * np.sum(X * rhs)
            + np.einsum("fia,fij,fja->", X, A, X))
    X = X.transpose(0, 2, 1).reshape(2 * F, r + 1)
    return X[:, :r], X[:, r], max(float(data), 0.0)


def complete_low_rank(W, rank, observed=None, *, lam_fraction=LAM_FRACTION, tol=1e-7,
                      max_iter=300):
    """Fill the missing entries of W by a rank-r factorisation of its observed entries.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Measurements; NaN marks a missing entry.
    rank : int
        Rank r of ``W - t 1'`` (3K for K shape bases, Eq. 1); ``1 <= r < min(2F, P)``.
    observed : (F, P) bool array_like, optional
        Restricts the observation mask further (default: the NaN pattern).
    lam_fraction : float
        Ridge weight as a fraction of sigma_1; positive.
    tol : float
        Stop when the objective's relative decrease in an iteration is below ``tol``.
    max_iter : int
        Iteration cap (``converged`` is False when reached).

    Returns
    -------
    FastCompletion

    Raises
    ------
    ValueError
        Bad shapes or constants, rank out of range, too sparse observations.
    """
    Wz, obs = observed_entries(W, observed)
    F, P = obs.shape
    r = int(rank)
    if not 1 <= r < min(2 * F, P):
        raise ValueError(f"rank must be in [1, min(2F, P)) = [1, {min(2 * F, P)}); got {rank}")
    if not (np.isfinite(lam_fraction) and lam_fraction > 0):
        raise ValueError(f"lam_fraction must be positive; got {lam_fraction!r}")
    if max_iter < 1:
        raise ValueError(f"max_iter must be >= 1; got {max_iter}")
    o2 = np.repeat(obs, 2, axis=0)
    t = Wz.sum(axis=1) / o2.sum(axis=1)
    Z = np.where(o2, Wz - t[:, None], 0.0)                    # mean fill, centred
    U, s, Vt = _truncated_svd(Z, r)
    if not s[0] > 0:
        raise ValueError("the observed entries of W have no spread: nothing to complete")
    lam = lam_fraction * float(s[0])
    root = np.sqrt(s)
    M, B = U * root, root[:, None] * Vt
    scale = 0.5 * float(np.sum(Z * Z))
    groups = _mask_groups(obs)
    cost, converged = [], False
    for _ in range(max_iter):
        B = _solve_structure(Wz, groups, M, t, lam)
        M, t, data = _solve_motion(Wz, obs, B, lam)
        cost.append(0.5 * (data + lam * (np.sum(M * M) + np.sum(B * B))) / scale)
        if len(cost) > 1 and cost[-2] - cost[-1] <= tol * cost[-1]:
            converged = True
            break
    Wc = np.where(o2, Wz, M @ B + t[:, None])
    return FastCompletion(W=Wc, observed=obs, M=M, B=B, t=t, rank=r, lam=lam,
                          n_iter=len(cost), converged=converged,
                          history=dict(cost=np.asarray(cost)))


def fill_gain(M, observed):
    """Noise gain of each track's filled entries (unitless, scale-free).

    A point's structure column b_p is fitted to the frames that observe it, normal matrix
    ``A_p = sum_{f observed} M_f' M_f``; the fill ``M_f b_p`` of a frame then has
    covariance ``sigma^2 M_f A_p^{-1} M_f'`` for white measurement noise sigma. The gain
    is ``max_f sqrt(lambda_max(M_f A_p^{-1} M_f'))`` over all frames: at most 1 inside the
    observed frames of a complete track, large when a short track is extrapolated.

    Parameters
    ----------
    M : (2F, r) ndarray
    observed : (F, P) bool ndarray

    Returns
    -------
    gain : (P,) ndarray
    """
    F2, r = M.shape
    observed = np.asarray(observed, dtype=bool)
    if observed.shape[0] * 2 != F2:
        raise ValueError(f"observed must have shape (F, P) with 2F = {F2}; "
                         f"got {observed.shape}")
    patterns, index = _mask_groups(observed)
    Mf = M.reshape(F2 // 2, 2, r)
    G = np.einsum("fir,fis->frs", Mf, Mf).reshape(F2 // 2, r * r)
    A = (patterns.astype(float) @ G).reshape(-1, r, r)
    Ai = np.linalg.pinv(A, hermitian=True)                    # (U, r, r)
    lev = np.einsum("fir,urs,fjs->ufij", Mf, Ai, Mf)           # (U, F, 2, 2)
    gain = np.sqrt(np.clip(np.linalg.eigvalsh(lev)[..., -1], 0.0, None).max(axis=1))
    return gain[index]
