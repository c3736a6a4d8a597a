"""The family combination: a research step after the rotation average (strategy ``family``
of :mod:`nrsfm.research.rotations`, the ``organic`` default before issue 18).

For fixed rotations the triplets consistent with them form a K-dimensional linear family
(:func:`triplet_family`); the K family triplets see ``M_f`` through different directions
and are combined per frame by signal-to-noise weights (:func:`combine_family`,
maximum-ratio combination), alternated with the rotations (:func:`combine_triplets`). It
lowers e_R and raised e3d (drink .0080 -> .0105 with the same shape solver):
``docs/rotation_stage.md`` section 7.
"""

from __future__ import annotations

import numpy as np

from ..geometry import procrustes_so3, project_to_so3, rotation_angle

__all__ = ["combine_family", "combine_triplets", "triplet_family"]


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
        Bk = B[k] @ procrustes_so3(N)
        c = 0.5 * np.einsum("fij,fij->f", Bk, ref)
        S += (c / g)[:, None, None] * Bk
        weights[k] = c ** 2 / g
    L = np.concatenate([S, np.cross(S[:, 0], S[:, 1])[:, None]], axis=1)
    bad = ~(np.linalg.norm(L[:, 2], axis=1) > 0)
    L[bad] = np.asarray(R_ref, float)[bad]
    return project_to_so3(L), weights


def combine_triplets(M, K, R, settings, info):
    """The step after the average (``combine="family"``): the family of triplets
    consistent with ``R``, combined per frame by maximum-ratio weights, alternated at most
    ``combine_iter`` times until the median per-frame change (rad) is below
    ``combine_tol``."""
    sv = np.sum(M ** 2, axis=0)                            # M_hat = U sqrt(S): |col|^2 = s
    steps = []
    for _ in range(settings.combine_iter):
        G_fam, fam_eig = triplet_family(M, R, K)
        new, fam_w = combine_family(M, G_fam, R, sv)
        steps.append(float(np.median(rotation_angle(new, R))))
        R = new
        if steps[-1] < settings.combine_tol:
            break
    info.update(G_family=G_fam, family_eigenvalues=fam_eig, family_weights=fam_w,
                combine_steps=np.array(steps))
    return R
