"""The two completions of W, and the time lags that they share (paper Sec. 4e-ii).

W (2F, P) comes checked by :func:`nrsfm.validation.check_problem`, NaN marking a missing
entry; a missing observation is a (frame, point) pair, the mask ``observed`` (F, P). A frame
must observe at least 3 points and a point be observed in at least 2 frames.

The time-lagged matrix for lags ``d_1, ..., d_n``, ``H(W) = [S_{d_1} W, ..., S_{d_n} W]``
(2F, n P; ``S_d`` shifts the frames by d, edges repeated), lets a missing point be seen
through its own trajectory at the adjacent frames (lags ``(-1, 0, 1)``); ``(0,)`` is W
itself. Both completions fit H(W) and fill a missing entry with the mean of its copies' fits:

* :func:`complete_low_rank` (at the scale of video): ``min 1/2 ||P_Omega(H(W) - M B - t 1')||^2
  + lam/2 (||M||^2 + ||B||^2)`` (Cabral et al., ICCV 2013) by alternating exact least squares
  (Okatani et al., ICCV 2011) with the gauge fixed in every sweep (Buchanan & Fitzgibbon,
  CVPR 2005) and Bro's line search; M and t fitted on the *determined* tracks (fill gain at
  most ``MAX_GAIN``), every b_p under their prior.
* :func:`complete_measurements`: soft-impute (Mazumder, Hastie & Tibshirani, JMLR 2010) of
  ``min 1/2 ||P_Omega(H(W) - L - t 1')||^2 + tau ||L||_*``, every copy of a missing entry kept
  equal, tau continued from ``sigma_1 / 10`` down to ``TAU_FRACTION sigma_1`` with warm
  starts. Scale-equivariant.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

from ...linalg import weighted_svt
from .result import MAX_GAIN, Completion

NEIGHBOUR_LAGS = (-1, 0, 1)
NO_LAGS = (0,)
LAG_RATIO = 2  # lags when a frame observes fewer than this many points per unknown
#: ridge as a fraction of sigma_1
LAM_FRACTION = 1e-4
#: rounds of (choose the determined tracks, fit M on them)
MAX_ROUNDS = 4
#: determined tracks per dimension of b_p needed to estimate the prior of the short tracks
PRIOR_SAMPLES = 10
#: final threshold as a fraction of sigma_1; continuation stages; tolerance; iteration cap
TAU_FRACTION, N_STAGES, TOL, MAX_ITER = 1e-3, 8, 1e-6, 500


@dataclass(frozen=True)
class Copies:
    """The entries of the lagged matrix H (2F, n P) as copies of W's (2F, P) entries, as
    index arrays (all None for the lags ``(0,)``, where H is W): ``H = W.ravel()[gather]``,
    the same for the (F, P) mask with ``gather_mask``; ``order`` the entries of H lag by
    lag, ``target`` the flat index in W of each, ``counts`` the copies of each entry of W
    (an edge frame is repeated)."""

    lags: tuple
    gather: np.ndarray = None
    gather_mask: np.ndarray = None
    order: np.ndarray = None
    target: np.ndarray = None
    counts: np.ndarray = None

    def lag(self, Z, mask=False):
        """H of Z (2F, P), or of an (F, P) mask: a new array."""
        if self.gather is None:
            return np.array(Z)
        return Z.ravel()[self.gather_mask if mask else self.gather]

    def mean(self, L, shape):
        """The mean of the copies of each entry of a (2F, P) ``shape`` from L shaped like H."""
        if self.gather is None:
            return np.array(L).reshape(shape)
        size = int(np.prod(shape))
        return (np.bincount(self.target, L.ravel()[self.order], size) / self.counts).reshape(shape)


def check_lags(lags):
    """``lags`` as a tuple of int; ValueError (naming them) unless distinct and with 0."""
    try:
        out = tuple(operator.index(d) for d in lags)
    except TypeError:
        out = ()
    if 0 not in out or len(set(out)) != len(out):
        raise ValueError(f"lags must be distinct integers including 0; got {lags!r}")
    return out


def choose_lags(observed, rank):
    """Temporal lags for completing W at rank r, from its (F, P) observation mask alone.

    Each frame's two rows and offset (r + 1 unknowns) are fitted to the points the frame
    observes. When the frame observing the fewest points has fewer than ``LAG_RATIO * (r +
    1)`` of them (MoCap: 41 markers at r = 3K = 30-36), its own observations barely
    determine its rows and :data:`NEIGHBOUR_LAGS` add its neighbours'; otherwise (dense
    tracks) :data:`NO_LAGS`.
    """
    fewest = int(np.asarray(observed, bool).sum(axis=1).min())
    return NEIGHBOUR_LAGS if fewest < LAG_RATIO * (int(rank) + 1) else NO_LAGS


def lag_copies(F, P, lags):
    """The :class:`Copies` of the lagged matrix of a (2F, P) W for ``lags`` (checked)."""
    lags = check_lags(lags)
    if lags == NO_LAGS:
        return Copies(lags)
    frames = np.clip(np.arange(F)[:, None] + np.asarray(lags)[None, :], 0, F - 1)  # (F, n)
    points = np.arange(P)
    rows = 2 * frames[:, None, :, None] + np.arange(2)[None, :, None, None]  # (F, 2, n, 1)
    gather = (rows * P + points).reshape(2 * F, -1)
    order = np.arange(gather.size).reshape(2 * F, len(lags), P).transpose(1, 0, 2).ravel()
    target = gather.ravel()[order]
    mask = (frames[:, :, None] * P + points).reshape(F, -1)
    counts = np.bincount(target, minlength=2 * F * P).astype(float)
    return Copies(lags, gather, mask, order, target, counts)


def observed_entries(W):
    """Split W into zero-filled values and the (F, P) observation mask.

    Parameters
    ----------
    W : (2F, P) ndarray
        Checked by :func:`nrsfm.validation.check_problem`: NaN marks a missing coordinate; a
        point is observed in a frame when both of its coordinates are.

    Returns
    -------
    Wz : (2F, P) ndarray
        W with every unobserved entry set to 0.
    observed : (F, P) bool ndarray

    Raises
    ------
    ValueError
        A frame observing fewer than 3 points or a point observed in fewer than 2 frames
        (named).
    """
    F, P = W.shape[0] // 2, W.shape[1]
    obs = np.isfinite(W).reshape(F, 2, P).all(axis=1)
    _refuse_sparse(obs.sum(axis=1), 3, "frame", "observes {n} points")
    _refuse_sparse(obs.sum(axis=0), 2, "point", "is observed in {n} frames")
    return np.where(np.repeat(obs, 2, axis=0), W, 0.0), obs


def observed_mask(W):
    """The (F, P) observation mask of W, checked as by :func:`observed_entries`."""
    return observed_entries(W)[1]


def _refuse_sparse(counts, minimum, what, observes):
    """ValueError naming the first frame (or point) with fewer than ``minimum`` observations."""
    bad = np.flatnonzero(counts < minimum)
    if bad.size:
        raise ValueError(
            f"{what} {int(bad[0])} {observes.format(n=int(counts[bad[0]]))} (at least "
            f"{minimum} are needed to determine it); {bad.size} {what}(s) too sparse: "
            f"{bad[:10].tolist()}{' ...' if bad.size > 10 else ''}"
        )


def mask_groups(obs):
    """Points that share an observation pattern of ``obs`` (F, P): ``(patterns (U, F) bool,
    index (P,))`` with ``patterns[index] == obs.T``, in the order of ``np.unique`` of the
    packed rows (here a stable sort of them read as big-endian 64-bit words: faster)."""
    packed = np.packbits(obs.T, axis=1)  # (P, bytes)
    P, nbytes = packed.shape
    words = np.zeros((P, -(-nbytes // 8) * 8), np.uint8)
    words[:, :nbytes] = packed
    keys = words.view(">u8")  # numeric order = byte order
    order = np.lexsort(keys.T[::-1])  # the first word first
    k = keys[order]
    new = np.ones(P, bool)
    new[1:] = np.any(k[1:] != k[:-1], axis=1)
    index = np.empty(P, int)
    index[order] = np.cumsum(new) - 1
    return obs[:, order[new]].T, index


def normal_matrices(M, patterns):
    """``(Mf, A)``: M (2F, r) as (F, 2, r) row pairs, and the (U, r, r) normal matrices
    ``A_u = sum_{f observed} M_f' M_f`` of the observation patterns (U, F) bool."""
    F2, r = M.shape
    Mf = M.reshape(F2 // 2, 2, r)
    G = np.einsum("fir,fis->frs", Mf, Mf).reshape(F2 // 2, r * r)
    return Mf, (patterns.astype(float) @ G).reshape(-1, r, r)


def fill_gain(M, observed, groups=None):
    """Noise gain of each track's filled entries (unitless, scale-free).

    ``max_f sqrt(lambda_max(M_f A_p^-1 M_f'))``, ``A_p = sum_{f observed} M_f' M_f`` the
    normal matrix of b_p: the fill ``M_f b_p`` has covariance ``sigma^2 M_f A_p^-1 M_f'``
    under white noise sigma. At most 1 for a complete track, large for a short one.

    Parameters
    ----------
    M : (2F, r) ndarray
    observed : (F, P) bool ndarray
    groups : tuple, optional
        :func:`mask_groups` of ``observed``, when already computed.

    Returns
    -------
    gain : (P,) ndarray
    """
    F2 = M.shape[0]
    observed = np.asarray(observed, dtype=bool)
    if observed.shape[0] * 2 != F2:
        raise ValueError(f"observed must have shape (F, P) with 2F = {F2}; got {observed.shape}")
    patterns, index = mask_groups(observed) if groups is None else groups
    Mf, A = normal_matrices(M, patterns)
    Ai = np.linalg.pinv(A, hermitian=True)  # (U, r, r)
    lev = np.einsum("fir,urs,fjs->ufij", Mf, Ai, Mf, optimize=True)  # (U, F, 2, 2)
    a, b, d = lev[..., 0, 0], lev[..., 0, 1], lev[..., 1, 1]
    top = 0.5 * (a + d) + np.hypot(0.5 * (a - d), b)  # its larger eigenvalue
    gain = np.sqrt(np.clip(top, 0.0, None).max(axis=1))
    w = np.linalg.eigvalsh(A)
    gain[w[:, 0] <= 1e-12 * w[:, -1]] = np.inf  # b_p not determined at all
    return gain[index]


def _truncated_svd(A, r):
    """``(U, s)``: the r leading left singular vectors and values of A (m, n), through the
    Gram matrix of its smaller side."""
    tall = A.shape[0] > A.shape[1]
    lam, V = np.linalg.eigh(A.T @ A if tall else A @ A.T)
    order = np.argsort(lam)[::-1][:r]
    s = np.sqrt(np.clip(lam[order], 0.0, None))
    V = V[:, order]
    if not tall:
        return V, s
    return (A @ V) * np.where(s > s[0] * 1e-12, 1.0 / np.maximum(s, 1e-300), 0.0), s


def _solve_structure(Wz, groups, M, t, lam, prior_mean=None, sums=None):
    """B-step: per point, ridge least squares over the frames that observe it (``lam``: the
    ridge weight, or an (r, r) prior precision with ``prior_mean``; ``sums``: ``(||Wz||^2,
    row sums)``). ``(B, data)``: B (r, P) and ``||P_Omega(W - M B - t 1')||^2``."""
    patterns, index = groups
    r = M.shape[1]
    ww, row_sum = sums or (np.sum(Wz * Wz), Wz.sum(axis=1))
    A = normal_matrices(M, patterns)[1]
    reg = lam * np.eye(r) if np.ndim(lam) == 0 else lam
    inv = np.linalg.inv(A + reg)  # (U, r, r)
    o2 = np.repeat(patterns, 2, axis=1).astype(float)  # (U, 2F)
    n_rows = np.bincount(index, minlength=o2.shape[0]) @ o2  # (2F,) observed per row
    rhs = M.T @ Wz - ((M * t[:, None]).T @ o2.T)[:, index]  # (r, P)
    shift = 0.0 if prior_mean is None else (reg @ prior_mean)[:, None]
    B = np.einsum("prs,sp->rp", inv[index], rhs + shift)
    # b' A_p b = b' (rhs_p + shift) - b' reg b at the solution of (A_p + reg) b = rhs + shift
    quad = np.sum(B * (rhs + shift)) - np.sum(B * (reg @ B))
    data = ww - 2.0 * t @ row_sum + (t * t) @ n_rows - 2.0 * np.sum(B * rhs) + quad
    return B, max(float(data), 0.0)


def _solve_motion(Wz, obs, B, lam, ww):
    """M-step: per frame, ridge least squares for its two rows and offset; ``obs`` (F, P)
    as float, ``ww = ||Wz||^2``. Returns ``(M, t, data)``, data as in the B-step."""
    r, P = B.shape
    F = obs.shape[0]
    Bt = np.vstack([B, np.ones((1, P))])  # (r + 1, P)
    i, j = np.triu_indices(r + 1)  # A is symmetric
    upper = obs @ (Bt[i] * Bt[j]).T  # (F, pairs)
    A = np.empty((F, r + 1, r + 1))
    A[:, i, j] = upper
    A[:, j, i] = upper
    reg = np.diag(np.r_[np.full(r, lam), 0.0])
    rhs = (Wz @ Bt.T).reshape(F, 2, r + 1).transpose(0, 2, 1)  # (F, r + 1, 2)
    X = np.linalg.solve(A + reg, rhs)  # (F, r + 1, 2)
    data = ww - 2.0 * np.sum(X * rhs) + np.einsum("fia,fij,fja->", X, A, X)
    X = X.transpose(0, 2, 1).reshape(2 * F, r + 1)
    return X[:, :r], X[:, r], max(float(data), 0.0)


def _balance(M, B):
    """M' with ``M' B' = M B`` and ``M'^T M' = B' B'^T``: the split of the product with the
    least ridge ``||M||^2 + ||B||^2``."""
    Qm, Rm = np.linalg.qr(M)
    Qb, Rb = np.linalg.qr(B.T)
    U, s, _ = np.linalg.svd(Rm @ Rb.T)
    return Qm @ (U * np.sqrt(s))


def _alternate(Wz, obs, core, M, t, lam, tol, max_iter, scale):
    """Alternate the M- and B-steps from M, t, with the two gauges and the extrapolation of
    the module docstring, on the tracks ``core``. Returns ``(M, t, iterations, converged)``."""
    Wz, obs = Wz[:, core], obs[:, core]
    groups, obs_f = mask_groups(obs), obs.astype(float)
    sums = (np.sum(Wz * Wz), Wz.sum(axis=1))

    def f(M, t):  # B-step, the offset's gauge, and the cost
        B, data = _solve_structure(Wz, groups, M, t, lam, sums=sums)
        mean = B.mean(axis=1)
        B, t = B - mean[:, None], t + M @ mean
        return B, t, 0.5 * (data + lam * (np.sum(M * M) + np.sum(B * B))) / scale

    B, t, c = f(M, t)
    for k in range(1, max(max_iter, 1) + 1):
        M1, t1, _ = _solve_motion(Wz, obs_f, B, lam, sums[0])
        M1 = _balance(M1, B)
        B1, t1, c1 = f(M1, t1)
        d = k ** (1.0 / 3.0)
        if d > 1.0:
            Me, te = M + d * (M1 - M), t + d * (t1 - t)
            Be, te, ce = f(Me, te)
            if ce < c1:
                M1, t1, B1, c1 = Me, te, Be, ce
        done = c - c1 <= tol * c1
        M, t, B, c = M1, t1, B1, c1
        if done:
            return M, t, k, True
    return M, t, k, False


def complete_low_rank(W, rank, lags=NO_LAGS, tol=1e-6, max_iter=300):
    """Fill the missing entries of W by a rank-r factorisation of its observed entries.

    Parameters
    ----------
    W : (2F, P) ndarray
        NaN marks a missing entry (:func:`observed_entries`).
    rank : int
        Rank r of ``W - t 1'`` (3K, Eq. 1); ``1 <= r < min(2F, P)``.
    lags : sequence of int
        Temporal lags (frames), containing 0: the factorisation is of the lagged matrix H(W)
        (module docstring), a missing entry the mean of its copies' fits; ``(0,)``
        factorises W itself.
    tol : float
        Stop when the objective's relative decrease in an iteration is below ``tol``.
    max_iter : int
        Iteration cap (``converged`` is False when reached).

    Returns
    -------
    Completion
        ``method == "factorisation"``, with the factors, the ridge and ``fill_gain``.
    """
    Wz, obs = observed_entries(W)
    F, P = obs.shape
    r = int(rank)
    if not 1 <= r < min(2 * F, P):
        raise ValueError(f"rank must be in [1, min(2F, P)) = [1, {min(2 * F, P)}); got {rank}")
    copies = lag_copies(F, P, lags)
    Hz, obs_h = copies.lag(Wz), copies.lag(obs, mask=True)
    groups = mask_groups(obs_h)
    M, B, t, lam, n_iter, converged, gain = _factorise(Hz, obs_h, groups, r, tol, max_iter)
    B = _posterior_structure(Hz, obs_h, M, t, B, gain <= MAX_GAIN, groups)
    fit = copies.mean(M @ B + t[:, None], Wz.shape)  # mean of each entry's copies
    j = copies.lags.index(0)
    factors = dict(fill_gain=gain[j * P : (j + 1) * P], lam=lam, M=M, B=B, t=t)
    W = np.where(np.repeat(obs, 2, axis=0), Wz, fit)
    return Completion(W, obs, "factorisation", copies.lags, r, n_iter, converged, **factors)


def _posterior_structure(Wz, obs, M, t, B, determined, groups):
    """Every b_p again, under the prior the determined tracks give (empirical Bayes).

    ``b_p ~ N(mu, S)``, mu and S the mean and covariance of the determined tracks' b_p, and
    white noise of the variance of their residuals: ``b_p = (A_p + sigma^2 S^-1)^-1 (M_p'(w_p
    - t_p) + sigma^2 S^-1 mu)``. A long track is unchanged; a short one falls back towards
    the typical point where its frames say nothing. B unchanged when fewer than
    ``PRIOR_SAMPLES * r`` tracks are determined (S needs many more samples than dimensions).
    """
    r = M.shape[1]
    if determined.sum() < PRIOR_SAMPLES * r:
        return B
    o2 = np.repeat(obs[:, determined], 2, axis=0)
    res = (Wz[:, determined] - M @ B[:, determined] - t[:, None])[o2]
    sigma2 = float(np.mean(res**2))
    mu = B[:, determined].mean(axis=1)
    prec = sigma2 * np.linalg.pinv(np.cov(B[:, determined]), hermitian=True)
    return _solve_structure(Wz, groups, M, t, prec, prior_mean=mu)[0]


def _factorise(Wz, obs, groups, r, tol, max_iter):
    """Rank-r factorisation of the observed entries (``groups``: :func:`mask_groups` of
    ``obs``): ``(M, B, t, lam, n_iter, converged, gain)``, ``gain`` the :func:`fill_gain`
    of every track under the final M."""
    o2 = np.repeat(obs, 2, axis=0)
    t = Wz.sum(axis=1) / o2.sum(axis=1)
    Z = np.where(o2, Wz - t[:, None], 0.0)  # mean fill, centred
    U, s = _truncated_svd(Z, r)
    if not s[0] > 0:
        raise ValueError("the observed entries of W have no spread: nothing to complete")
    lam = LAM_FRACTION * float(s[0])
    M = U * np.sqrt(s)
    scale = 0.5 * float(np.sum(Z * Z))
    core = fill_gain(M, obs, groups) <= MAX_GAIN
    if core.sum() <= r:
        core[:] = True
    n_iter, converged = 0, False
    for _ in range(MAX_ROUNDS):
        # fit M, t on the tracks the current M determines (an undetermined track only slows
        # the alternation down: its b_p drifts along near-null directions)
        M, t, k, converged = _alternate(Wz, obs, core, M, t, lam, tol, max_iter - n_iter, scale)
        n_iter += k
        gain = fill_gain(M, obs, groups)  # under the final M at the end
        new = gain <= MAX_GAIN
        if new.sum() <= r or np.array_equal(new, core) or n_iter >= max_iter:
            break
        core = new
    B = _solve_structure(Wz, groups, M, t, lam)[0]
    return M, B, t, lam, n_iter, converged, gain


def complete_measurements(W, lags=NEIGHBOUR_LAGS):
    """Fill the missing entries of W (NaN) by nuclear-norm completion (soft-impute).

    Parameters
    ----------
    W : (2F, P) ndarray
        NaN marks a missing entry (:func:`observed_entries`).
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
            if copies.gather is not None:  # the mean of each entry's copies (Copies.mean)
                fit = np.bincount(copies.target, fit.ravel()[copies.order], Z.size) / copies.counts
            new = fit.reshape(Z.shape)[missing]
            change = np.linalg.norm(new - cur) / scale
            if np.vdot(y - new, new - cur) > 0:  # against the momentum
                k = 0
            prev = cur
            Z[missing] = new
            if change < tol:
                converged = True
                break
    return rank, n_iter, converged
