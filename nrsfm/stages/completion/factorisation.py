"""Missing data at the scale of video: low-rank factorisation of the observed entries.

The measurement model (Eq. 1) with the translation t explicit, fitted to the observed entries
with a small ridge (the bilinear form of a nuclear norm, Cabral et al., ICCV 2013):

    minimise_{M, B, t}  1/2 ||P_Omega(W - M B - t 1')||_F^2 + lam/2 (||M||_F^2 + ||B||_F^2),

M (2F, r), B (r, P), by alternating exact least squares (Okatani, Yoshida & Deguchi, ICCV
2011), no SVD after the start. The symmetries that only the ridge pins (``M -> M G``, ``B ->
G^-1 B``; ``B -> B - c 1'``, ``t -> t + M c``), along which alternation crawls (Buchanan &
Fitzgibbon, CVPR 2005), are fixed in every sweep, and the sweep is extrapolated by
``k^(1/3)`` when that lowers the cost (Bro's line search). M and t are fitted on the
*determined* tracks (fill gain at most ``MAX_GAIN``), every b_p then under their prior.
"""

from __future__ import annotations

import numpy as np

from .lags import NO_LAGS, lag_copies, observed_entries
from .result import MAX_GAIN, Completion

#: ridge as a fraction of sigma_1
LAM_FRACTION = 1e-4
#: rounds of (choose the determined tracks, fit M on them)
MAX_ROUNDS = 4
#: determined tracks per dimension of b_p needed to estimate the prior of the short tracks
PRIOR_SAMPLES = 10


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
    W : (2F, P) or (F, 2, P) array_like
        NaN marks a missing entry.
    rank : int
        Rank r of ``W - t 1'`` (3K, Eq. 1); ``1 <= r < min(2F, P)``.
    lags : sequence of int
        Temporal lags (frames), containing 0: the factorisation is of the lagged matrix
        (:mod:`~nrsfm.stages.completion.lags`), a missing entry the mean of its copies'
        fits; ``(0,)`` factorises W itself.
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
