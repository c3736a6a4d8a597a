"""Rotation stage (paper Sec. 3.1): triplets -> per-triplet rotations -> registration ->
filtering -> per-frame L1 single rotation averaging.

Conventions
-----------
* A triplet G (3K x 3) maps frame f's 2 x 3K block to ``M_f G = c_f R_f[:2]`` (a scaled
  orthographic camera).  Lifting it to SO(3) (:func:`rotations_from_triplets`) gives
  ``R_f`` when ``c_f > 0`` and ``diag(-1, -1, 1) R_f`` ("depth reversal" of frame f: the
  same image with the shape negated) when ``c_f < 0``; a triplet may also come out with
  the opposite handedness (``diag(1, 1, -1) R_f D``, D = diag(1, 1, -1)), which equals the
  depth reversal of every frame times a fixed rotation, so the per-frame flips absorb it.
* Registration (:func:`register_rotations`) solves Eq. 3 with one R_reg in SO(3) per
  triplet plus a per-frame choice of I or diag(-1, -1, 1).
* The final per-frame depth sign is chosen by motion smoothness (Dai's rule, see
  :func:`resolve_depth_signs`); ``sign_from_smoothness`` flags the frames it changed.

Where the K triplets come from (the paper says only "using Dai et al." for every k): the
best triplet from :func:`nrsfm.corrective.corrective_triplets`, K - 1 triplets refined on
temporal windows, and (default ``organic``) the K-dimensional family of triplets
consistent with their average, combined per frame by signal-to-noise weights
(:func:`triplet_family`, :func:`combine_family`). The measurements behind these choices
(strategies on the 8 MoCap sequences, behaviour under track noise) are in
``docs/rotation_stage.md``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from .corrective import corrective_triplets, refine_triplet, triplet_cost

__all__ = ["RotationResult", "STRATEGIES", "project_to_so3", "rotations_from_triplets",
           "register_rotations", "filter_rotations", "average_rotations",
           "chordal_mean", "rotation_angle", "resolve_depth_signs", "window_triplets",
           "estimate_rotations", "triplet_from_rotations", "triplet_family",
           "combine_family"]

FLIP = np.diag([-1.0, -1.0, 1.0])          # depth reversal of one frame (c_f < 0)
MIRROR = np.diag([1.0, 1.0, -1.0])         # handedness

#: strategy name -> what it does (see :func:`estimate_rotations`)
STRATEGIES = {
    "organic": "default: the best triplet plus K-1 triplets refined on temporal windows "
               "of 90% of the frames (leave-10%-out), registered, filtered at delta "
               "against their L1 average, L1-averaged; then the K triplets of the family "
               "consistent with that average, combined per frame by signal-to-noise "
               "weights (maximum-ratio combination)",
    "bmm": "Dai et al.: the best single triplet only",
    "literal": "the paper read literally: the K column triplets of the relaxed Gram "
               "matrix, each refined; register to the lowest-cost one; filter at delta; "
               "L1 average",
    "multistart": "the K lowest-cost refined minima from the multistart",
    "windows": "the best triplet plus K-1 triplets on half-length windows, plain L1 "
               "average (no filter): lowest e_R, worse e3d",
    "bootstrap": "as organic, with bootstrap resamples of the frames instead of windows: "
                 "e_R within 5% of the single triplet, e3d tied with the default",
}


# --------------------------------------------------------------------------- basics
def project_to_so3(A):
    """Nearest rotation(s) to ``A`` (..., 3, 3): ``U diag(1, 1, det(UV')) V'``."""
    A = np.asarray(A, float)
    U, _, Vt = np.linalg.svd(A)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0, 1.0, d)
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    return U @ Vt


def rotation_angle(R1, R2):
    """Geodesic angle (radians) between rotations, broadcasting over leading axes."""
    c = (np.einsum("...ij,...ij->...", R1, R2) - 1.0) / 2.0
    return np.arccos(np.clip(c, -1.0, 1.0))


def _chordal(R1, R2):
    return np.linalg.norm(np.asarray(R1) - np.asarray(R2), axis=(-2, -1))


# --------------------------------------------------------------------------- lifting
def rotations_from_triplets(M_hat, G, handedness=1):
    """Per-triplet, per-frame rotations from ``M_f G^k``.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    G : (m, 3K, 3) or (3K, 3) ndarray
    handedness : {1, -1}
        -1 negates the third column of every 2 x 3 block before lifting.

    Returns
    -------
    R : (m, F, 3, 3) ndarray in SO(3)
        Rows scaled to unit length, ``r3 = r1 x r2``, projected onto SO(3). Never NaN: a
        frame where ``M_f G`` is degenerate (a zero row or parallel rows) gets the
        identity and ``valid`` False.
    coefficients : (m, F) ndarray
        ``|c_fk|``: RMS norm of the two rows of ``M_f G^k``.
    valid : (m, F) bool
    """
    G = np.asarray(G, float)
    single = G.ndim == 2
    if single:
        G = G[None]
    M = np.asarray(M_hat, float)
    F = M.shape[0] // 2
    B = np.einsum("ri,kij->krj", M, G).reshape(G.shape[0], F, 2, 3)
    if handedness == -1:
        B = B * np.array([1.0, 1.0, -1.0])
    norms = np.linalg.norm(B, axis=3)                             # (m, F, 2)
    coef = np.sqrt(0.5 * (norms ** 2).sum(axis=2))
    scale = np.max(coef, axis=1, keepdims=True)
    tiny = 1e-12 * np.where(scale > 0, scale, 1.0)
    ok_rows = norms > tiny[..., None]
    U = B / np.where(ok_rows, norms, 1.0)[..., None]
    r3 = np.cross(U[:, :, 0], U[:, :, 1])
    valid = ok_rows.all(axis=2) & (np.linalg.norm(r3, axis=2) > 1e-8)
    L = np.concatenate([U, r3[:, :, None]], axis=2)
    L = np.where(valid[..., None, None], L, np.eye(3))
    R = project_to_so3(L)
    coef = np.where(valid, coef, 0.0)
    if single:
        return R[0], coef[0], valid[0]
    return R, coef, valid


# --------------------------------------------------------------------------- registration
def _procrustes_so3(N):
    """argmax_{R in SO(3)} trace(R' N)."""
    U, _, Vt = np.linalg.svd(N)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt


def _register_one(R_ref, R_k, w, max_iter=20):
    """Flip-aware registration of one triplet for one handedness: (R_reg, flips, cost)."""
    # Start from the third rows (a frame's depth reversal leaves them unchanged):
    # maximise sum_f w_f r3_ref . (R r3_k)  ->  N = sum_f w_f r3_ref r3_k'.
    N = np.einsum("f,fi,fj->ij", w, R_ref[:, 2], R_k[:, 2])
    R = _procrustes_so3(N)
    flips = np.zeros(len(R_k), bool)
    for _ in range(max_iter):
        X = R_k @ R.T                                               # R_k R_reg'
        # flipping rows 1-2 of X changes trace(R_ref' X) by -2 (d1 + d2)
        d12 = np.einsum("fij,fij->f", R_ref[:, :2], X[:, :2])
        new_flips = d12 < 0
        S = np.where(new_flips[:, None, None], FLIP @ R_k, R_k)
        # refit: maximise sum_f w_f trace(R_ref' S R') = trace(R' N), N = sum w S' R_ref
        N = np.einsum("f,fki,fkj->ij", w, S, R_ref).T
        R_new = _procrustes_so3(N)
        if np.array_equal(new_flips, flips) and np.allclose(R_new, R, atol=1e-12):
            flips, R = new_flips, R_new
            break
        flips, R = new_flips, R_new
    S = np.where(flips[:, None, None], FLIP @ R_k, R_k)
    cost = float(np.sum(w * np.sum((R_ref - S @ R.T) ** 2, axis=(1, 2))))
    return R, flips, cost


def register_rotations(R_ref, R_k, weights=None, handedness="both"):
    """Register one triplet's rotations onto the reference (Eq. 3, flip-aware).

    Minimises ``sum_f w_f || R_ref,f - s_f H(R_k,f) R_reg' ||_F^2`` over R_reg in SO(3),
    per-frame ``s_f`` in {I, diag(-1, -1, 1)} and, with ``handedness="both"``, the
    handedness ``H`` (identity, or ``R -> diag(1, 1, -1) R diag(1, 1, -1)``, the lift of
    the mirrored 2 x 3 blocks). Closed-form SO(3) Procrustes started from the third rows,
    then alternation between the flips and R_reg (converges in a few steps).

    Parameters
    ----------
    R_ref, R_k : (F, 3, 3) ndarray
    weights : (F,) ndarray, optional
        0 leaves a frame out of the fit (its flip is still chosen).
    handedness : {"both", "same"}

    Returns
    -------
    registered : (F, 3, 3) ndarray
        ``s_f H(R_k,f) R_reg'``.
    R_reg : (3, 3) ndarray
        In the sense of Eq. 3 (for the mirrored handedness, applied after the mirror).
    flips : (F,) bool
    mirrored : bool
    cost : float
    """
    R_ref = np.asarray(R_ref, float)
    R_k = np.asarray(R_k, float)
    w = np.ones(len(R_k)) if weights is None else np.asarray(weights, float)
    best = None
    options = [False, True] if handedness == "both" else [False]
    for mirrored in options:
        Rk = MIRROR @ R_k @ MIRROR if mirrored else R_k
        R, flips, cost = _register_one(R_ref, Rk, w)
        if best is None or cost < best[3] - 1e-12:
            best = (R, flips, mirrored, cost, Rk)
    R, flips, mirrored, cost, Rk = best
    S = np.where(flips[:, None, None], FLIP @ Rk, Rk)
    return S @ R.T, R, flips, mirrored, cost


# --------------------------------------------------------------------------- filtering
def filter_rotations(registered, reference, delta=0.05, metric="angle", valid=None):
    """Keep the samples within ``delta`` of the reference (paper: delta = 0.05).

    Parameters
    ----------
    registered : (m, F, 3, 3) ndarray
    reference : (F, 3, 3) ndarray
    delta : float
    metric : {"angle", "chordal"}
        ``angle``: geodesic angle in radians, the metric the L1 average minimises (0.05 rad
        = 2.9 degrees). ``chordal``: ``||R - R_ref||_F`` (= 2 sqrt(2) sin(angle / 2),
        so 0.05 is 2.0 degrees).
    valid : (m, F) bool, optional
        Samples already known to be unusable.

    Returns
    -------
    kept : (m, F) bool
    distance : (m, F) ndarray
    """
    if metric == "angle":
        dist = rotation_angle(registered, reference[None])
    elif metric == "chordal":
        dist = _chordal(registered, reference[None])
    else:
        raise ValueError(f"unknown metric {metric!r}")
    kept = dist <= delta
    if valid is not None:
        kept &= valid
    return kept, dist


# --------------------------------------------------------------------------- averaging
def _median_start(samples, mask):
    """Element-wise median of the kept samples, projected onto SO(3) (Lee & Civera)."""
    S = np.where(mask[..., None, None], samples, np.nan)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(S, axis=0)
    med = np.where(np.isfinite(med), med, np.eye(3))
    return project_to_so3(med)


def average_rotations(samples, mask=None, weights=None, max_iter=50, eps=1e-3,
                      return_info=False):
    """L1 single rotation averaging per frame (Alg. 1), vectorised over frames.

    Start: element-wise median of the samples projected onto SO(3); then Weiszfeld steps
    in the tangent space, ``v_i = log(R_i R')``, ``dv = sum w_i v_i/|v_i| / sum w_i/|v_i|``,
    ``R <- exp(dv) R``, at most ``max_iter`` iterations, a frame stops when ``|dv| < eps``.

    Parameters
    ----------
    samples : (m, F, 3, 3) ndarray
    mask : (m, F) bool, optional
        Samples to use. A frame with no sample gets the identity (and ``info["empty"]``).
    weights : (m, F) ndarray, optional
        Non-negative sample weights (weighted L1 mean); default 1.

    Returns
    -------
    R : (F, 3, 3) ndarray
    info : dict (iterations, converged per frame, empty frames) if ``return_info``
    """
    samples = np.asarray(samples, float)
    m, F = samples.shape[:2]
    mask = np.ones((m, F), bool) if mask is None else np.asarray(mask, bool)
    w = np.ones((m, F)) if weights is None else np.asarray(weights, float)
    w = np.where(mask, w, 0.0)
    empty = ~(w > 0).any(axis=0)
    R = _median_start(samples, w > 0)
    active = ~empty
    flat = samples.transpose(1, 0, 2, 3).reshape(F * m, 3, 3)     # frame-major
    wt = w.T                                                       # (F, m)
    iters = np.zeros(F, int)
    for it in range(max_iter):
        if not active.any():
            break
        idx = np.flatnonzero(active)
        Ra = R[idx]
        rel = flat.reshape(F, m, 3, 3)[idx] @ Ra[:, None].transpose(0, 1, 3, 2)
        v = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape(len(idx), m, 3)
        nv = np.linalg.norm(v, axis=2)
        inv = wt[idx] / np.maximum(nv, 1e-12)
        den = inv.sum(axis=1)
        dv = np.einsum("fm,fmi->fi", inv, v) / np.where(den > 0, den, 1.0)[:, None]
        R[idx] = Rotation.from_rotvec(dv).as_matrix() @ Ra
        iters[idx] += 1
        step = np.linalg.norm(dv, axis=1)
        active[idx[step < eps]] = False
    R = project_to_so3(R)
    if return_info:
        return R, dict(iterations=iters, converged=~active, empty=empty)
    return R


def chordal_mean(samples, mask=None):
    """Chordal L2 mean per frame: projection of the arithmetic mean onto SO(3)."""
    samples = np.asarray(samples, float)
    mask = np.ones(samples.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    S = np.einsum("mf,mfij->fij", mask.astype(float), samples)
    S = np.where(mask.any(axis=0)[:, None, None], S, np.eye(3))
    return project_to_so3(S)


# --------------------------------------------------------------------------- depth sign
def resolve_depth_signs(R):
    """Per-frame depth sign by motion smoothness (Dai's rule).

    Frame f is replaced by ``diag(-1, -1, 1) R_f`` when that is closer to the (resolved)
    frame f - 1, i.e. when the two cameras' rows disagree by more than 90 degrees on
    average (``r1.r1' + r2.r2' < 0``).

    Returns
    -------
    R : (F, 3, 3) ndarray
    flipped : (F,) bool, frames changed
    """
    R = np.array(R, float, copy=True)
    F = len(R)
    flipped = np.zeros(F, bool)
    # d_f = agreement of frame f with frame f-1 (unresolved); resolving sequentially only
    # needs the parity of the flips so far.
    d = np.einsum("fij,fij->f", R[1:, :2], R[:-1, :2])
    parity = np.cumsum(np.concatenate([[0], (d < 0).astype(int)])) % 2
    flipped = parity.astype(bool)
    R[flipped] = FLIP @ R[flipped]
    return R, flipped


# --------------------------------------------------------------------------- windows
def window_triplets(M_hat, G0, n_windows, window=0.5, method="lm", subsets="windows",
                    seed=0):
    """Triplets refined on subsets of the frames, started from ``G0``.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    G0 : (3K, 3) ndarray
    n_windows : int
    window : float
        Subset size as a fraction of F (at least 8 frames).
    subsets : {"windows", "bootstrap", "random"}
        ``windows``: contiguous temporal windows, starts spread evenly from the first to
        the last possible frame. ``bootstrap``: F frames drawn with replacement (weights
        = counts). ``random``: ``window * F`` frames drawn without replacement.
    seed : int
        For the random subsets.

    Returns
    -------
    G : (n_windows, 3K, 3) ndarray
    spans : (n_windows, 2) int ndarray, [start, stop) of each window (-1 for random subsets)
    costs : (n_windows,) ndarray, Dai's cost per frame on the subset
    """
    F = np.asarray(M_hat).shape[0] // 2
    L = int(min(F, max(8, round(window * F))))
    rng = np.random.default_rng(seed)
    Gs, spans, costs = [], [], []
    if subsets == "windows":
        starts = np.round(np.linspace(0, F - L, n_windows)).astype(int) \
            if n_windows > 1 else np.array([0])
    for i in range(n_windows):
        w = np.zeros(F)
        if subsets == "windows":
            s = starts[i]
            w[s:s + L] = 1.0
            spans.append((s, s + L))
        elif subsets == "bootstrap":
            w = np.bincount(rng.integers(0, F, F), minlength=F).astype(float)
            spans.append((-1, -1))
        elif subsets == "random":
            w[rng.choice(F, L, replace=False)] = 1.0
            spans.append((-1, -1))
        else:
            raise ValueError(f"unknown subsets {subsets!r}")
        G, inf = refine_triplet(G0, M_hat, weights=w, method=method)
        Gs.append(G)
        costs.append(inf["cost"] / w.sum())
    return np.stack(Gs), np.array(spans), np.array(costs)


def triplet_from_rotations(M_hat, R, G0, n_iter=30):
    """The triplet whose cameras best match given rotations: ``M_f G ~ s_f R_f[:2]``.

    Alternating least squares over G (3K x 3) and the per-frame scales s_f (normalised to
    ``sum_f s_f^2 = F``), started from ``G0``. Used to project averaged rotations back onto
    the factorisation model (one G for all frames, as the shape stage assumes).

    Returns
    -------
    G : (3K, 3) ndarray
    scales : (F,) ndarray
    """
    M = np.asarray(M_hat, float)
    F = M.shape[0] // 2
    A = np.asarray(R, float)[:, :2]
    pinvM = np.linalg.pinv(M)
    G = np.asarray(G0, float).copy()
    s = np.ones(F)
    for _ in range(n_iter):
        B = (M @ G).reshape(F, 2, 3)
        s = np.einsum("fij,fij->f", B, A) / 2.0
        n = np.sqrt(np.sum(s ** 2))
        if not n > 0:
            break
        s *= np.sqrt(F) / n
        G_new = pinvM @ (s[:, None, None] * A).reshape(2 * F, 3)
        if np.allclose(G_new, G, rtol=1e-10, atol=1e-14):
            G = G_new
            break
        G = G_new
    return G, s


# --------------------------------------------------------------------------- combining
def triplet_family(M_hat, R, K):
    """The K triplets most consistent with given rotations: ``M_f G ~ c_f R_f[:2]``.

    For fixed rotations the valid triplets form a linear family (``G_full (a (x) I_3)``,
    a in R^K, for the true corrective matrix G_full): the null space of the map
    ``G -> (I - P_f) vec(M_f G)`` over all frames, P_f the projection onto ``R_f[:2]``.
    Returned: the K eigenvectors of its Gram matrix with the smallest eigenvalues.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    R : (F, 3, 3) ndarray
    K : int

    Returns
    -------
    G : (K, 3K, 3) ndarray, unit Frobenius norm each
    eigenvalues : (K,) ndarray, relative to the largest one (small = consistent)
    """
    M = np.asarray(M_hat, float)
    F, n = M.shape[0] // 2, M.shape[1]
    Mf = M.reshape(F, 2, n)
    # vec(M_f G) (row-major 2 x 3) = A_f vec(G), vec(G) row-major (3K x 3)
    A = np.einsum("fil,jm->fijlm", Mf, np.eye(3)).reshape(F, 6, 3 * n)
    r = np.asarray(R, float)[:, :2].reshape(F, 6) / np.sqrt(2.0)
    PA = A - r[:, :, None] * np.einsum("fa,faj->fj", r, A)[:, None, :]
    H = A.reshape(-1, 3 * n).T @ PA.reshape(-1, 3 * n)
    w, V = np.linalg.eigh(0.5 * (H + H.T))
    return V[:, :K].T.reshape(K, n, 3), w[:K] / max(w[-1], 1e-300)


def combine_family(M_hat, G, R_ref, singular_values=None):
    """Per-frame maximum-ratio combination of the K family triplets' camera blocks.

    Each block ``B_fk = M_f G^k`` is ``c_fk R_f[:2]`` plus noise whose variance is
    proportional to ``g_k = ||S^-1/2 G^k||_F^2`` (noise on W reaches M_hat through
    ``S^-1/2``, S the top 3K singular values). The combination
    ``sum_k (c_fk / g_k) B_fk`` (``c_fk = <B_fk, R_ref,f[:2]> / 2``, each triplet's
    3 x 3 gauge first aligned to ``R_ref`` by Procrustes) weights every sample by its
    signal-to-noise ratio; its rows, completed by their cross product and projected onto
    SO(3), give R_f.

    Returns
    -------
    R : (F, 3, 3) ndarray
    weights : (K, F) ndarray, ``c_fk^2 / g_k`` (the samples' relative information)
    """
    M = np.asarray(M_hat, float)
    F = M.shape[0] // 2
    s = np.sum(M ** 2, axis=0) if singular_values is None else \
        np.asarray(singular_values, float)[:M.shape[1]]
    ref = np.asarray(R_ref, float)[:, :2]
    B = np.einsum("ri,kij->krj", M, G).reshape(len(G), F, 2, 3)
    S = np.zeros((F, 2, 3))
    weights = np.zeros((len(G), F))
    for k in range(len(G)):
        g = float(np.sum(G[k] ** 2 / s[:, None]))
        c = np.einsum("fij,fij->f", B[k], ref)
        N = np.einsum("f,fij,fik->jk", np.sign(c), B[k], ref)       # gauge (Procrustes)
        U, _, Vt = np.linalg.svd(N)
        Bk = B[k] @ (U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0]) @ Vt)
        c = 0.5 * np.einsum("fij,fij->f", Bk, ref)
        S += (c / g)[:, None, None] * Bk
        weights[k] = c ** 2 / g
    L = np.concatenate([S, np.cross(S[:, 0], S[:, 1])[:, None]], axis=1)
    bad = ~(np.linalg.norm(L[:, 2], axis=1) > 0)
    L[bad] = np.asarray(R_ref, float)[bad]
    return project_to_so3(L), weights


# --------------------------------------------------------------------------- result
@dataclass
class RotationResult:
    """Output of :func:`estimate_rotations` (every intermediate of the rotation stage).

    Attributes
    ----------
    rotations : (F, 3, 3) ndarray
        Final per-frame rotations in SO(3) (depth sign resolved by smoothness).
    G : (m, 3K, 3) ndarray
        The triplets G^k (m = K for the averaging strategies, 1 for ``bmm``).
    per_triplet : (m, F, 3, 3) ndarray
        Lifted rotations R^k before registration.
    coefficients : (m, F) ndarray
        ``|c_fk|``, RMS norm of the rows of ``M_f G^k``.
    registration : (m, 3, 3) ndarray
        R_reg^k (identity for k = 0).
    registered : (m, F, 3, 3) ndarray
        After registration and flip handling.
    kept : (m, F) bool
        Samples that passed the filter.
    averaged : (F, 3, 3) ndarray
        The L1 average (before the smoothness sign rule).
    sign_from_smoothness : (F,) bool
        Frames whose depth sign was changed by the motion-smoothness rule.
    strategy : str
    params : dict
    timings : dict
    info : dict
        Triplet costs, their starts, flips, handedness, filter distances, ...
    """

    rotations: np.ndarray
    G: np.ndarray
    per_triplet: np.ndarray
    coefficients: np.ndarray
    registration: np.ndarray
    registered: np.ndarray
    kept: np.ndarray
    averaged: np.ndarray
    sign_from_smoothness: np.ndarray
    strategy: str
    params: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    @property
    def n_triplets(self):
        return self.G.shape[0]


# --------------------------------------------------------------------------- entry point
_DEFAULTS = dict(
    delta=0.05,              # filter threshold (paper)
    filter_metric="angle",   # "angle" or "chordal"
    filter_against="reference",  # "reference" (paper), "average", or None (no filter)
    coef_gate=0.0,           # drop samples with |c_fk| < coef_gate * median_f |c_fk|
    coef_weights=False,      # weight samples by |c_fk| / median_f |c_fk| in the average
    window=0.5,              # window length (fraction of F) for window triplets
    subsets="windows",       # "windows", "bootstrap" or "random" frame subsets
    n_triplets=None,         # default K
    starts="search",         # triplet starts, see nrsfm.corrective.corrective_triplets
    hits=2, max_starts=40,   # stopping rule of nrsfm.corrective.search_triplet
    lam=1e2,                 # penalty of nrsfm.corrective.penalized_gram
    gram="penalized",        # relaxation whose column blocks "literal" refines
    n_random=32, n_full=4, screen_frames=80, screen_iter=30,
    sdp_solver="admm", refine="lm",
    max_iter=50, eps=1e-3,   # Weiszfeld
    average="l1",            # "l1" (Alg. 1) or "chordal" (L2, for the ablation)
    refit=False,             # project the average back onto one triplet (see below)
    combine=None,            # "family": maximum-ratio combination of the triplet family
    combine_iter=5,          # at most this many family <-> rotation alternations ...
    combine_tol=1e-3,        # ... stopped when the median per-frame change (rad) is below
)

_STRATEGY_DEFAULTS = {
    # chosen by benchmarks/rotation_study.py and benchmarks/noise_study.py
    # (docs/rotation_stage.md)
    "organic": dict(subsets="windows", window=0.9, filter_against="average",
                    combine="family"),
    "windows": dict(window=0.5, filter_against=None),
    "bootstrap": dict(subsets="bootstrap", window=0.5, filter_against="average"),
    "literal": dict(filter_against="reference", gram="nuclear"),
    "multistart": dict(filter_against="reference", starts="multistart"),
    "bmm": dict(),
}


def estimate_rotations(M_hat, K, strategy="organic", seed=0, progress=None, **options):
    """Camera rotations from the rank-3K motion factor.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
        From ``nrsfm.measurement.factorize(W / scale, K).M_hat``.
    K : int
    strategy : str
        One of :data:`STRATEGIES`:

        * ``organic`` (default): the best triplet (the search of
          :func:`nrsfm.corrective.corrective_triplets`) plus K - 1 triplets refined on
          temporal windows of 90% of the frames; register (flip-aware Eq. 3), filter at
          delta = 0.05 rad from the L1 average of the samples, per-frame L1 average
          (Alg. 1); then the K triplets of the family consistent with that average,
          combined per frame by maximum-ratio weights (``combine="family"``); depth
          signs by smoothness.
        * ``bmm``: the best triplet only (Dai et al.).
        * ``literal``: the K column triplets of the relaxed Gram matrix, each refined,
          registered to the lowest-cost one, filtered, L1-averaged.
        * ``multistart``: the K lowest-cost distinct minima of the multistart.
        * ``windows``: half-length windows, no filter (lowest e_R, worse e3d).
        * ``bootstrap``: bootstrap resamples instead of windows.
    seed : int
        Seed of the random refinement starts and random subsets (deterministic per seed).
    progress : callable(str) or None
    **options
        Override the defaults (``_DEFAULTS``, then ``_STRATEGY_DEFAULTS[strategy]``):
        ``delta`` (0.05), ``filter_metric`` ("angle" | "chordal"), ``filter_against``
        ("reference" | "average" | None), ``coef_gate`` (drop samples with
        ``|c_fk| < coef_gate * median_f |c_fk|``), ``coef_weights`` (weight samples by
        ``|c_fk|`` in the average), ``window`` (fraction of F), ``subsets`` ("windows" |
        "bootstrap" | "random"), ``n_triplets`` (default K), ``average`` ("l1" |
        "chordal"), ``refit`` (replace the average by the rotations of the single triplet
        that fits it best, :func:`triplet_from_rotations`), ``combine`` (None |
        "family", :func:`combine_family`, alternated with :func:`triplet_family` at most
        ``combine_iter`` times until the median per-frame change is below ``combine_tol``
        rad), ``hits`` and ``max_starts`` (stopping rule
        of the triplet search), ``n_random``, ``n_full``,
        ``screen_frames``, ``screen_iter``, ``sdp_solver``, ``refine``, ``max_iter``,
        ``eps``.

    Returns
    -------
    RotationResult

    Raises
    ------
    ValueError
        Unknown strategy or option, or M_hat not (2F, 3K).
    """
    if strategy not in STRATEGIES:
        raise ValueError(f"unknown rotation strategy {strategy!r}; "
                         f"expected one of {sorted(STRATEGIES)}")
    unknown = set(options) - set(_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown rotation options {sorted(unknown)}")
    say = progress if callable(progress) else (lambda msg: None)
    p = dict(_DEFAULTS)
    p.update(_STRATEGY_DEFAULTS[strategy])
    p.update(options)
    M = np.asarray(M_hat, float)
    if M.ndim != 2 or M.shape[1] != 3 * K or M.shape[0] % 2:
        raise ValueError(f"M_hat must have shape (2F, 3K) = (2F, {3 * K}); got {M.shape}")
    F = M.shape[0] // 2
    m = int(p["n_triplets"] or K)
    timings = {}
    info = {}

    # 1. triplets -------------------------------------------------------------------------
    t0 = time.perf_counter()
    starts = "columns" if strategy == "literal" else p["starts"]
    cor = corrective_triplets(M, K, starts=starts, seed=seed, n_random=p["n_random"],
                              n_full=max(p["n_full"], m if strategy == "multistart" else 0),
                              screen_frames=p["screen_frames"],
                              screen_iter=p["screen_iter"], sdp_solver=p["sdp_solver"],
                              refine=p["refine"], lam=p["lam"], gram=p["gram"],
                              hits=p["hits"], max_starts=p["max_starts"])
    info.update(corrective_costs=cor.costs, corrective_starts=cor.info["starts"],
                corrective_search=cor.info.get("search"),
                sdp={k: cor.info[k] for k in ("penalized", "nuclear") if k in cor.info},
                corrective_timings=cor.timings)
    G_best = cor.G[0]
    say(f"best corrective triplet: Dai cost {cor.costs[0]:.4g} (start {cor.info['starts'][0]})")
    if strategy == "bmm":
        G = G_best[None]
    elif strategy == "literal":
        G = cor.G[:m]                                  # sorted by cost: reference first
    elif strategy == "multistart":
        G = _distinct(cor.G, cor.costs, m)
    else:                                              # organic / windows
        if m > 1:
            Gw, spans, wcost = window_triplets(M, G_best, m - 1, window=p["window"],
                                               method=p["refine"], subsets=p["subsets"],
                                               seed=seed)
            G = np.concatenate([G_best[None], Gw])
            info.update(window_spans=spans, window_costs=wcost)
        else:
            G = G_best[None]
    timings["triplets"] = time.perf_counter() - t0
    info["triplet_costs"] = np.array([triplet_cost(g, M) for g in G])

    # 2. lift --------------------------------------------------------------------------
    t0 = time.perf_counter()
    per_triplet, coef, valid = rotations_from_triplets(M, G)
    timings["lift"] = time.perf_counter() - t0

    # 3. register ------------------------------------------------------------------------
    t0 = time.perf_counter()
    registered = np.empty_like(per_triplet)
    registration = np.tile(np.eye(3), (len(G), 1, 1))
    flips = np.zeros((len(G), F), bool)
    mirrored = np.zeros(len(G), bool)
    reg_cost = np.zeros(len(G))
    registered[0] = per_triplet[0]
    ref_w = valid[0].astype(float)
    for k in range(1, len(G)):
        registered[k], registration[k], flips[k], mirrored[k], reg_cost[k] = \
            register_rotations(per_triplet[0], per_triplet[k], weights=ref_w * valid[k])
    timings["registration"] = time.perf_counter() - t0
    info.update(flips=flips, mirrored=mirrored, registration_cost=reg_cost)

    # 4. filter ------------------------------------------------------------------------
    t0 = time.perf_counter()
    med = np.array([np.median(c[v]) if v.any() else 0.0 for c, v in zip(coef, valid)])
    rel = coef / np.where(med > 0, med, 1.0)[:, None]     # |c_fk| / median_f |c_fk|
    rel = np.where(valid & np.isfinite(rel), rel, 0.0)
    usable = valid & (rel >= p["coef_gate"])
    usable[0] |= valid[0]                                  # the reference always counts
    weights = np.where(usable, rel if p["coef_weights"] else 1.0, 0.0)
    if p["filter_against"] == "reference":
        kept, dist = filter_rotations(registered, registered[0], p["delta"],
                                      p["filter_metric"], usable)
    elif p["filter_against"] == "average":
        pre = average_rotations(registered, usable, weights, p["max_iter"], p["eps"])
        kept, dist = filter_rotations(registered, pre, p["delta"], p["filter_metric"], usable)
    elif p["filter_against"] is None:
        kept, dist = usable.copy(), np.zeros(usable.shape)
    else:
        raise ValueError(f"unknown filter_against {p['filter_against']!r}")
    none_left = ~kept.any(axis=0)
    kept[0] |= none_left & valid[0]                        # fall back on the reference
    timings["filtering"] = time.perf_counter() - t0
    info.update(filter_distance=dist)

    # 5. average -----------------------------------------------------------------------
    t0 = time.perf_counter()
    if p["average"] == "l1":
        averaged, avg_info = average_rotations(registered, kept,
                                               np.where(weights > 0, weights, 1.0),
                                               p["max_iter"], p["eps"], return_info=True)
    elif p["average"] == "chordal":
        averaged = chordal_mean(registered, kept)
        avg_info = dict(iterations=np.zeros(F, int), empty=~kept.any(axis=0))
    else:
        raise ValueError(f"unknown average {p['average']!r}")
    if np.any(avg_info["empty"]):                          # frames with no usable sample
        averaged = _fill_empty(averaged, avg_info["empty"])
    timings["averaging"] = time.perf_counter() - t0
    info.update(averaging_iterations=avg_info["iterations"], empty_frames=avg_info["empty"])

    final = averaged
    if p["refit"] and len(G) > 1:
        t0 = time.perf_counter()
        G_fit, _ = triplet_from_rotations(M, averaged, G[0])
        R_fit, _, ok = rotations_from_triplets(M, G_fit)
        final = np.where(ok[:, None, None], R_fit, averaged)
        info.update(G_refit=G_fit, refit_cost=triplet_cost(G_fit, M))
        timings["refit"] = time.perf_counter() - t0
    if p["combine"] == "family" and K > 1:
        t0 = time.perf_counter()
        sv = np.sum(M ** 2, axis=0)                        # M_hat = U sqrt(S): |col|^2 = s
        steps = []
        for _ in range(max(1, int(p["combine_iter"]))):   # family <-> rotations, alternated
            G_fam, fam_eig = triplet_family(M, final, K)
            new, fam_w = combine_family(M, G_fam, final, sv)
            steps.append(float(np.median(rotation_angle(new, final))))
            final = new
            if steps[-1] < p["combine_tol"]:
                break
        info.update(G_family=G_fam, family_eigenvalues=fam_eig, family_weights=fam_w,
                    combine_steps=np.array(steps))
        timings["combine"] = time.perf_counter() - t0
    elif p["combine"] not in (None, "family"):
        raise ValueError(f"unknown combine {p['combine']!r}")
    rotations, flipped = resolve_depth_signs(final)
    say(f"rotations: {len(G)} triplet(s), {kept.sum()} of {kept.size} samples kept, "
        f"{int(flipped.sum())} frames' depth sign from smoothness")
    params = dict(p, strategy=strategy, seed=seed, K=K, n_triplets=len(G))
    return RotationResult(rotations=rotations, G=G, per_triplet=per_triplet,
                          coefficients=coef, registration=registration,
                          registered=registered, kept=kept, averaged=averaged,
                          sign_from_smoothness=flipped, strategy=strategy, params=params,
                          timings=timings, info=info)


def _distinct(G, costs, m, rtol=1e-4):
    """The m lowest-cost triplets whose costs differ (distinct minima), padded with the best."""
    out, seen = [], []
    for g, c in zip(G, costs):
        if all(abs(c - s) > rtol * max(abs(s), 1e-12) for s in seen):
            out.append(g)
            seen.append(c)
        if len(out) == m:
            break
    while len(out) < m:
        out.append(G[0])
    return np.stack(out)


def _fill_empty(R, empty):
    """Give frames without any sample the rotation of the nearest frame that has one."""
    R = R.copy()
    good = np.flatnonzero(~empty)
    if len(good) == 0:
        return np.tile(np.eye(3), (len(R), 1, 1))
    for f in np.flatnonzero(empty):
        R[f] = R[good[np.argmin(np.abs(good - f))]]
    return R
