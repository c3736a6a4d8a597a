"""Steps of the rotation stage on given triplets: lifting ``M_f G^k`` to SO(3), registration
(Eq. 3), filtering, and the depth sign by motion smoothness. Conventions: the docstring of
:mod:`nrsfm.stages.rotations`.
"""

from __future__ import annotations

import numpy as np

from ...geometry import procrustes_so3, rotation_angle

__all__ = ["filter_rotations", "register_rotations", "resolve_depth_signs"]

FLIP = np.diag([-1.0, -1.0, 1.0])  # depth reversal of one frame (c_f < 0)
MIRROR = np.diag([1.0, 1.0, -1.0])  # handedness
#: a lifted frame is degenerate when |r1 x r2| is below this (parallel rows)
DEGENERATE_CROSS = 1e-8
#: ... or a row norm below this fraction of the largest camera scale
DEGENERATE_ROW = 1e-12


def rotations_from_triplets(M_hat, G, handedness=1):
    """Per-triplet, per-frame rotations from ``M_f G^k``, for M_hat (2F, 3K) and G
    (m, 3K, 3) or (3K, 3); ``handedness=-1`` negates the third column of every 2 x 3 block.

    Returns
    -------
    R : (m, F, 3, 3) ndarray in SO(3)
        Rows scaled to unit length, ``r3 = r1 x r2``, projected onto SO(3); the identity
        (and ``valid`` False) where ``M_f G`` is degenerate (a zero row, parallel rows).
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
    norms = np.linalg.norm(B, axis=3)  # (m, F, 2)
    coef = np.sqrt(0.5 * (norms**2).sum(axis=2))
    scale = np.max(coef, axis=1, keepdims=True)
    tiny = DEGENERATE_ROW * np.where(scale > 0, scale, 1.0)
    ok_rows = norms > tiny[..., None]
    U = B / np.where(ok_rows, norms, 1.0)[..., None]
    r3 = np.cross(U[:, :, 0], U[:, :, 1])
    valid = ok_rows.all(axis=2) & (np.linalg.norm(r3, axis=2) > DEGENERATE_CROSS)
    R = np.broadcast_to(np.eye(3), valid.shape + (3, 3)).copy()
    R[valid] = _nearest_rotation(U[valid][:, 0], U[valid][:, 1])
    coef = np.where(valid, coef, 0.0)
    if single:
        return R[0], coef[0], valid[0]
    return R, coef, valid


def _nearest_rotation(u1, u2):
    """Nearest rotation to ``[u1; u2; u1 x u2]`` (unit rows, not parallel) in closed form:
    rows ``(e1 +- e2) / sqrt 2`` and their cross product, e1, e2 the unit vectors along
    ``u1 + u2`` and ``u1 - u2`` (:func:`nrsfm.geometry.project_to_so3` without an SVD)."""
    p, q = u1 + u2, u1 - u2
    e1 = p / np.linalg.norm(p, axis=-1, keepdims=True)
    e2 = q / np.linalg.norm(q, axis=-1, keepdims=True)
    r1, r2 = (e1 + e2) / np.sqrt(2.0), (e1 - e2) / np.sqrt(2.0)
    return np.stack([r1, r2, np.cross(r1, r2)], axis=-2)


def _register_one(R_ref, R_k, w, max_iter=20):
    """Flip-aware registration of one triplet for one handedness: (R_reg, flips, cost)."""
    F = len(R_k)
    # Start from the third rows (a frame's depth reversal leaves them unchanged):
    # maximise sum_f w_f r3_ref . (R r3_k)  ->  N = sum_f w_f r3_ref r3_k'.
    N = (R_ref[:, 2] * w[:, None]).T @ R_k[:, 2]
    R = procrustes_so3(N)
    flips = np.zeros(F, bool)
    FR_k = FLIP @ R_k
    top_k, wR_ref = R_k[:, :2].reshape(2 * F, 3), (R_ref * w[:, None, None]).reshape(3 * F, 3)
    for _ in range(max_iter):
        # flipping rows 1-2 of X = R_k R_reg' changes trace(R_ref' X) by -2 (d1 + d2)
        d12 = np.einsum("fij,fij->f", R_ref[:, :2], (top_k @ R.T).reshape(F, 2, 3))
        new_flips = d12 < 0
        S = np.where(new_flips[:, None, None], FR_k, R_k)
        # refit: maximise sum_f w_f trace(R_ref' S R') = trace(R' N), N = sum w S' R_ref
        N = (S.reshape(3 * F, 3).T @ wR_ref).T
        R_new = procrustes_so3(N)
        if np.array_equal(new_flips, flips) and np.allclose(R_new, R, atol=1e-12):
            flips, R = new_flips, R_new
            break
        flips, R = new_flips, R_new
    S = np.where(flips[:, None, None], FR_k, R_k)
    cost = float(np.sum(w * np.sum((R_ref - S @ R.T) ** 2, axis=(1, 2))))
    return R, flips, cost


def register_rotations(R_ref, R_k, weights=None, handedness="both"):
    """Register one triplet's rotations R_k (F, 3, 3) onto R_ref (Eq. 3, flip-aware).

    Minimises ``sum_f w_f || R_ref,f - s_f H(R_k,f) R_reg' ||_F^2`` over R_reg in SO(3),
    per-frame ``s_f`` in {I, diag(-1, -1, 1)} and, with ``handedness="both"`` (not
    ``"same"``), the handedness H (identity or ``R -> MIRROR R MIRROR``): SO(3) Procrustes
    from the third rows, then alternation between the flips and R_reg. A zero weight leaves
    a frame out of the fit (its flip is still chosen).

    Returns
    -------
    registered : (F, 3, 3) ndarray
        ``s_f H(R_k,f) R_reg'``.
    R_reg : (3, 3) ndarray
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


def filter_rotations(registered, reference, delta=0.05, valid=None):
    """(kept, distance), each (m, F): the samples ``registered`` (m, F, 3, 3) within
    ``delta`` (geodesic angle, rad; paper: 0.05) of ``reference`` (F, 3, 3), among the
    ``valid`` ones (m, F) when given, and their angles."""
    dist = rotation_angle(registered, reference[None])
    kept = dist <= delta
    if valid is not None:
        kept &= valid
    return kept, dist


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
    # d_f = agreement of frame f with frame f-1 (unresolved); resolving sequentially only
    # needs the parity of the flips so far.
    d = np.einsum("fij,fij->f", R[1:, :2], R[:-1, :2])
    parity = np.cumsum(np.concatenate([[0], (d < 0).astype(int)])) % 2
    flipped = parity.astype(bool)
    R[flipped] = FLIP @ R[flipped]
    return R, flipped
