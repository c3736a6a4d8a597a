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
over the frames that observe point p (inverted once per observation pattern); with B fixed
every frame's two rows and offset are an (r + 1) x (r + 1) system over the points the
frame observes. Both steps are batched Gram products, so one iteration costs O(|Omega| r^2):
no SVD after the start, a rank-r truncated SVD (through the smaller Gram matrix) of the
mean-filled W. Three measures keep the alternation from crawling (Buchanan & Fitzgibbon,
CVPR 2005, on its slow convergence). The data term has two exact symmetries that only the
small ridge pins, and plain alternation moves along them by a fraction of order
``lam / ||A_p||`` per sweep: ``M -> M G``, ``B -> G^-1 B`` (G invertible), and the offset's
``B -> B - c 1'``, ``t -> t + M c``. Both are fixed exactly in every sweep: after the
M-step the factors are re-balanced (``M'M = BB'``, the split of MB with the least ridge),
after the B-step the mean of B over the points is moved into t (the shift with the least
ridge). Without the second the alternation crawled on the synthetic videos with late
tracks (the data term flat to 2e-5 over 500 sweeps, the ridge shrinking by 1e-5 and the
mean of B by 0.2 % a sweep): 306 iterations on the 100-frame face video and 430-966 on the
12-frame one of the tests, against 7-14 with it. The sweep is also extrapolated by ``k^(1/3)`` when that lowers the cost (Bro's line search for
alternating least squares). The stopping test, the objective's relative decrease in one
iteration below ``tol``, is scale-free (W times c: the same iterations).

Tracks seen in a few frames only: a track's fill is an extrapolation whose noise gain
(:func:`fill_gain`) grows without bound as its observed
frames shrink. M and t are fitted on the *determined* tracks (gain <= ``MAX_GAIN``,
re-chosen up to ``MAX_ROUNDS`` times); every track's b_p is then solved with that M.
``Completion.determined()`` says which tracks the data pin down; the others are filled,
but their 3D cannot be trusted.

``lags=(-1, 0, 1)`` factorises the time-lagged matrix ``[S_-1 W, W, S_+1 W]`` instead (a
missing entry is the mean of its copies' fits), which ties a missing entry to its own
trajectory when the rank r leaves a frame's observations too few (MoCap: P = 41 points,
r = 3K = 36); the default ``(0,)`` is the plain factorisation (dense tracks). Measurements:
``benchmarks/missing_study.py``.

The ridge is ``lam = lam_fraction * sigma_1`` (sigma_1: largest singular value of the
mean-filled, row-centred W): computed from W alone and scale-equivariant (W times c gives
the completion times c); a per-row offset added to W is carried by t.
"""

from __future__ import annotations

import numpy as np

from .lags import NO_LAGS, lag_copies
from .masks import observed_entries
from .result import MAX_GAIN, Completion

__all__ = ["LAM_FRACTION", "complete_low_rank", "factorise_lagged", "fill_gain",
           "mask_groups", "normal_matrices"]

#: Ridge as a fraction of sigma_1 (see the module docstring).
LAM_FRACTION = 1e-4
#: Rounds of (choose the determined tracks, fit M on them).
MAX_ROUNDS = 4
#: Determined tracks per dimension of b_p needed to estimate the prior of the short tracks.
PRIOR_SAMPLES = 10


def mask_groups(obs):
    """Points that share an observation pattern of ``obs`` (F, P): ``(patterns (U, F)
    bool, index (P,))``, with ``patterns[index] == obs.T``; the patterns in the order of
    ``np.unique(np.packbits(obs.T, axis=1), axis=0)``, by a stable sort of the packed rows
    read as big-endian 64-bit words (the same groups and order; 20,000 points x 100
    frames: 5.7 ms against 19.6 ms)."""
    packed = np.packbits(obs.T, axis=1)                         # (P, bytes)
    P, nbytes = packed.shape
    words = np.zeros((P, -(-nbytes // 8) * 8), np.uint8)
    words[:, :nbytes] = packed
    keys = words.view(">u8")                                    # numeric order = byte order
    order = np.lexsort(keys.T[::-1])                            # the first word first
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

    A point's structure column b_p is fitted to the frames that observe it, normal matrix
    ``A_p = sum_{f observed} M_f' M_f``; the fill ``M_f b_p`` of a frame then has
    covariance ``sigma^2 M_f A_p^{-1} M_f'`` for white measurement noise sigma. The gain
    is ``max_f sqrt(lambda_max(M_f A_p^{-1} M_f'))`` over all frames: at most 1 inside the
    observed frames of a complete track, large when a short track is extrapolated.

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
        raise ValueError(f"observed must have shape (F, P) with 2F = {F2}; "
                         f"got {observed.shape}")
    patterns, index = mask_groups(observed) if groups is None else groups
    Mf, A = normal_matrices(M, patterns)
    Ai = np.linalg.pinv(A, hermitian=True)                    # (U, r, r)
    lev = np.einsum("fir,urs,fjs->ufij", Mf, Ai, Mf, optimize=True)   # (U, F, 2, 2)
    a, b, d = lev[..., 0, 0], lev[..., 0, 1], lev[..., 1, 1]
    top = 0.5 * (a + d) + np.hypot(0.5 * (a - d), b)          # its larger eigenvalue
    gain = np.sqrt(np.clip(top, 0.0, None).max(axis=1))
    w = np.linalg.eigvalsh(A)
    gain[w[:, 0] <= 1e-12 * w[:, -1]] = np.inf                # b_p not determined at all
    return gain[index]


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


def _sums(Wz):
    """``(||Wz||^2, row sums)``: the constants of the data terms below."""
    return np.sum(Wz * Wz), Wz.sum(axis=1)


def _solve_structure(Wz, groups, M, t, lam, prior_mean=None, sums=None):
    """B-step: per point, ridge least squares over the frames that observe it.

    ``groups`` from :func:`mask_groups`: the r x r normal matrix depends on the point only
    through its observation pattern, so it is inverted once per pattern. ``lam``: the
    ridge weight, or an (r, r) prior precision with ``prior_mean`` (r,). ``sums``:
    :func:`_sums` of Wz (computed when not given). Returns ``(B, data)``: B (r, P) and
    ``||P_Omega(W - M B - t 1')||^2`` at the solution, from the normal equations.
    """
    patterns, index = groups
    r = M.shape[1]
    ww, row_sum = _sums(Wz) if sums is None else sums
    A = normal_matrices(M, patterns)[1]
    reg = lam * np.eye(r) if np.ndim(lam) == 0 else lam
    inv = np.linalg.inv(A + reg)                              # (U, r, r)
    o2 = np.repeat(patterns, 2, axis=1).astype(float)         # (U, 2F)
    n_rows = np.bincount(index, minlength=o2.shape[0]) @ o2   # (2F,) observed per row
    rhs = M.T @ Wz - ((M * t[:, None]).T @ o2.T)[:, index]    # (r, P)
    shift = 0.0 if prior_mean is None else (reg @ prior_mean)[:, None]
    B = np.einsum("prs,sp->rp", inv[index], rhs + shift)
    # b' A_p b = b' (rhs_p + shift) - b' reg b at the solution of (A_p + reg) b = rhs + shift
    quad = np.sum(B * (rhs + shift)) - np.sum(B * (reg @ B))
    data = ww - 2.0 * t @ row_sum + (t * t) @ n_rows - 2.0 * np.sum(B * rhs) + quad
    return B, max(float(data), 0.0)


def _solve_motion(Wz, obs, B, lam, ww=None):
    """M-step: per frame, ridge least squares for its two rows and offset; ``obs`` (F, P)
    as float, ``ww`` = ``||Wz||^2`` (computed when not given).

    Returns ``(M, t, data)``: ``data`` is ``||P_Omega(W - M B - t 1')||^2`` at the solution,
    from the normal equations (no 2F x P residual is formed).
    """
    r, P = B.shape
    F = obs.shape[0]
    Bt = np.vstack([B, np.ones((1, P))])                      # (r + 1, P)
    i, j = np.triu_indices(r + 1)                             # A is symmetric
    upper = obs @ (Bt[i] * Bt[j]).T                           # (F, pairs)
    A = np.empty((F, r + 1, r + 1))
    A[:, i, j] = upper
    A[:, j, i] = upper
    reg = np.diag(np.r_[np.full(r, lam), 0.0])
    rhs = (Wz @ Bt.T).reshape(F, 2, r + 1).transpose(0, 2, 1)  # (F, r + 1, 2)
    X = np.linalg.solve(A + reg, rhs)                          # (F, r + 1, 2)
    data = ((np.sum(Wz * Wz) if ww is None else ww) - 2.0 * np.sum(X * rhs)
            + np.einsum("fia,fij,fja->", X, A, X))
    X = X.transpose(0, 2, 1).reshape(2 * F, r + 1)
    return X[:, :r], X[:, r], max(float(data), 0.0)


def _balance(M, B):
    """M' with ``M' B' = M B`` and ``M'^T M' = B' B'^T``: the split of the product with the
    least ridge ``||M||^2 + ||B||^2`` (the alternation moves along this gauge slowly)."""
    Qm, Rm = np.linalg.qr(M)
    Qb, Rb = np.linalg.qr(B.T)
    U, s, _ = np.linalg.svd(Rm @ Rb.T)
    return Qm @ (U * np.sqrt(s))


def _alternate(Wz, obs, M, t, lam, tol, max_iter, scale):
    """Alternate the M- and B-steps from M, t. Returns ``(M, t, costs, converged)``.

    Every B-step is followed by the offset's gauge (the mean of B over the points moved
    into t: the data term is unchanged, the ridge lowered; see the module docstring), and
    each sweep by an extrapolation of (M, t) along the sweep's step by
    ``k^(1/3)`` (iteration k), kept when it lowers the cost (the line search Bro uses to
    accelerate alternating least squares, 1998): plain alternation crawls along the
    shallow valleys of a factorisation with missing data (Buchanan & Fitzgibbon, CVPR 2005).
    """
    groups, sums, obs_f = mask_groups(obs), _sums(Wz), obs.astype(float)

    def f(M, t):                                    # B-step, the gauge, and the cost
        B, data = _solve_structure(Wz, groups, M, t, lam, sums=sums)
        mean = B.mean(axis=1)
        B, t = B - mean[:, None], t + M @ mean
        return B, t, 0.5 * (data + lam * (np.sum(M * M) + np.sum(B * B))) / scale

    B, t, c = f(M, t)
    cost = []
    for k in range(1, max(max_iter, 1) + 1):
        M1, t1, _ = _solve_motion(Wz, obs_f, B, lam, ww=sums[0])
        M1 = _balance(M1, B)
        B1, t1, c1 = f(M1, t1)
        d = k ** (1.0 / 3.0)
        if d > 1.0:
            Me, te = M + d * (M1 - M), t + d * (t1 - t)
            Be, te, ce = f(Me, te)
            if ce < c1:
                M1, t1, B1, c1 = Me, te, Be, ce
        cost.append(c1)
        done = c - c1 <= tol * c1
        M, t, B, c = M1, t1, B1, c1
        if done:
            return M, t, cost, True
    return M, t, cost, False


def complete_low_rank(W, rank, observed=None, *, lags=NO_LAGS, lam_fraction=LAM_FRACTION,
                      tol=1e-6, max_iter=300):
    """Fill the missing entries of W by a rank-r factorisation of its observed entries.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Measurements; NaN marks a missing entry.
    rank : int
        Rank r of ``W - t 1'`` (3K for K shape bases, Eq. 1); ``1 <= r < min(2F, P)``.
    observed : (F, P) bool array_like, optional
        Restricts the observation mask further (default: the NaN pattern).
    lags : sequence of int
        Temporal lags (frames), containing 0: the factorisation is of the lagged matrix
        ``[S_d W]`` (2F, n_lags P) (:mod:`~nrsfm.stages.completion.lags`), and a missing
        entry is the mean of its copies' fits; ``(0,)`` factorises W itself (frames in
        any order).
    lam_fraction : float
        Ridge weight as a fraction of sigma_1; positive.
    tol : float
        Stop when the objective's relative decrease in an iteration is below ``tol``.
    max_iter : int
        Iteration cap (``converged`` is False when reached).

    Returns
    -------
    Completion
        ``method == "factorisation"``, with the factors ``M``, ``B``, ``t``, the ridge
        ``lam``, ``history["cost"]`` and ``fill_gain`` under M (lag-0 columns).

    Raises
    ------
    ValueError
        Bad shapes or constants, rank out of range, too sparse observations.
    """
    Wz, obs = observed_entries(W, observed)
    copies = lag_copies(*obs.shape, lags)
    return factorise_lagged(Wz, obs, rank, copies, lam_fraction=lam_fraction, tol=tol,
                            max_iter=max_iter)


def factorise_lagged(Wz, obs, rank, copies, *, lam_fraction=LAM_FRACTION, tol=1e-6,
                     max_iter=300):
    """:func:`complete_low_rank` of checked input: ``Wz`` (2F, P) zero where not ``obs``
    (F, P) (:func:`~nrsfm.stages.completion.masks.observed_entries`), the lagged matrix's
    :class:`~nrsfm.stages.completion.lags.Copies`."""
    F, P = obs.shape
    r = int(rank)
    if not 1 <= r < min(2 * F, P):
        raise ValueError(f"rank must be in [1, min(2F, P)) = [1, {min(2 * F, P)}); got {rank}")
    if not (np.isfinite(lam_fraction) and lam_fraction > 0):
        raise ValueError(f"lam_fraction must be positive; got {lam_fraction!r}")
    if max_iter < 1:
        raise ValueError(f"max_iter must be >= 1; got {max_iter}")
    Hz, obs_h = copies.lag(Wz), copies.lag(obs, mask=True)
    groups = mask_groups(obs_h)
    M, B, t, lam, cost, converged, gain_h = _factorise(Hz, obs_h, groups, r, lam_fraction,
                                                       tol, max_iter)
    B = _posterior_structure(Hz, obs_h, M, t, B, gain_h <= MAX_GAIN, groups)
    fit = M @ B + t[:, None]
    fit = copies.mean(fit, Wz.shape)                          # mean of each entry's copies
    j = copies.lags.index(0)
    return Completion(W=np.where(np.repeat(obs, 2, axis=0), Wz, fit), observed=obs,
                      method="factorisation", lags=copies.lags, rank=r, n_iter=len(cost),
                      converged=converged, fill_gain=gain_h[j * P:(j + 1) * P],
                      history=dict(cost=np.asarray(cost)), lam=lam, M=M, B=B, t=t)


def _posterior_structure(Wz, obs, M, t, B, determined, groups):
    """Every b_p again, under the prior the determined tracks give (empirical Bayes).

    ``b_p ~ N(mu, S)`` with mu, S the mean and covariance of the determined tracks' b_p,
    and white noise of the variance of their residuals: ``b_p = (A_p + sigma^2 S^-1)^-1
    (M_p'(w_p - t_p) + sigma^2 S^-1 mu)``. A long track is unchanged (its A_p dominates);
    a short one falls back towards the typical point where its frames say nothing;
    ``groups``: :func:`mask_groups` of ``obs``.
    Returns B unchanged when fewer than ``PRIOR_SAMPLES * r`` tracks are determined: the
    r x r covariance S needs many more samples than dimensions (MoCap: 41 markers at
    r = 3K = 30-36, where the prior made drink's uniform case worse, 0.0089 -> 0.0107).
    """
    r = M.shape[1]
    if determined.sum() < PRIOR_SAMPLES * r:
        return B
    o2 = np.repeat(obs[:, determined], 2, axis=0)
    res = (Wz[:, determined] - M @ B[:, determined] - t[:, None])[o2]
    sigma2 = float(np.mean(res ** 2))
    mu = B[:, determined].mean(axis=1)
    prec = sigma2 * np.linalg.pinv(np.cov(B[:, determined]), hermitian=True)
    return _solve_structure(Wz, groups, M, t, prec, prior_mean=mu)[0]


def _factorise(Wz, obs, groups, r, lam_fraction, tol, max_iter):
    """Rank-r factorisation of the observed entries (``groups``: :func:`mask_groups` of
    ``obs``). ``(M, B, t, lam, costs, converged, gain)``, ``gain`` the :func:`fill_gain` of
    every track under the final M."""
    P = obs.shape[1]
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
    core = fill_gain(M, obs, groups) <= MAX_GAIN
    if core.sum() <= r:
        core[:] = True
    cost, converged = [], False
    for _ in range(MAX_ROUNDS):
        # fit M, t on the tracks the current M determines; an undetermined track only
        # slows the alternation down (its b_p drifts along near-null directions)
        M, t, c, converged = _alternate(Wz[:, core], obs[:, core], M, t, lam, tol,
                                        max_iter - len(cost), scale)
        cost += c
        gain = fill_gain(M, obs, groups)                      # under the final M at the end
        new = gain <= MAX_GAIN
        if new.sum() <= r or np.array_equal(new, core) or len(cost) >= max_iter:
            break
        core = new
    B = _solve_structure(Wz, groups, M, t, lam)[0]
    return M, B, t, lam, cost, converged, gain

