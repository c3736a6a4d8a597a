"""Error metrics of the MoCap benchmark (the paper, Sec. 4), three because the published
tables mix them:

* :func:`e3d`, the paper's: per frame, a similarity Procrustes alignment (rotation,
  reflection, scale) of the estimate onto the centred truth, then ``||X_gt - aligned||_F /
  ||X_gt||_F``, averaged over frames.
* :func:`e3d_akhter`, Akhter's / Dai's ``compareStructs``: both shapes divided by ``s =
  mean(std(X_gt))`` (std over points, ddof 0), one global orthogonal alignment (no scale),
  mean point distance per frame, averaged over frames.
* :func:`rotation_error`, ``e_R``: one global orthogonal alignment of the cameras, then the
  spectral norm of the 2 x 3 difference of the first two rows per frame, averaged (the
  published BMM figures use the spectral norm although the paper writes Frobenius).
* :func:`depth_amplification`: how far the cameras leave the depth of the deformation open
  (read by the diagnostics, from the run alone).
"""

from __future__ import annotations

import numpy as np

from .geometry import align_similarity, centre_points, procrustes_orthogonal
from .stages.measurement import power_of_two_scale
from .validation import check_rotations, check_shapes


def e3d(X_est, X_gt, per_frame=False):
    """The paper's normalised 3D error (per-frame similarity Procrustes).

    Parameters
    ----------
    X_est, X_gt : (F, 3, P) ndarray
        Estimated and ground-truth shapes; a per-frame translation, scale, rotation or
        reflection of ``X_est`` is factored out.
    per_frame : bool
        Return the (F,) per-frame errors instead of their mean.

    Returns
    -------
    float or (F,) ndarray
    """
    X_est, X_gt = _pair(X_est, X_gt)
    # e3d ignores the scale of either input: bring both to max|X| in [1, 2) (exact).
    X_est = X_est / power_of_two_scale(X_est)
    X_gt = X_gt / power_of_two_scale(X_gt)
    B = centre_points(X_gt)
    err = np.linalg.norm(B - align_similarity(X_est, X_gt), axis=(1, 2))
    err = err / np.linalg.norm(B, axis=(1, 2))
    return err if per_frame else float(err.mean())


def e3d_akhter(X_est, X_gt, per_frame=False):
    """Akhter et al.'s 3D error, as used by BMM's tables (one global alignment).

    Parameters
    ----------
    X_est, X_gt : (F, 3, P) ndarray
    per_frame : bool
        Return the (F,) per-frame mean point distances instead of their mean.

    Returns
    -------
    float or (F,) ndarray
        In units of ``s = mean(std(X_gt))``.
    """
    X_est, X_gt = _pair(X_est, X_gt)
    p2 = power_of_two_scale(X_gt)  # a common exact rescaling changes nothing
    B = centre_points(X_gt / p2)
    A = centre_points(X_est / p2)
    s = np.mean(np.std(B, axis=2))
    A, B = A / s, B / s
    # One orthogonal Q for the whole sequence: maximise trace(Q' sum_f B_f A_f').
    A = procrustes_orthogonal(np.einsum("fip,fjp->ij", B, A)) @ A
    err = np.linalg.norm(B - A, axis=1).mean(axis=1)
    return err if per_frame else float(err.mean())


def _pair(X_est, X_gt):
    """The two (F, 3, P) shape arrays, checked to match."""
    X_est, X_gt = check_shapes(X_est, "X_est"), check_shapes(X_gt, "X_gt")
    if X_est.shape != X_gt.shape:
        raise ValueError(f"X_est has shape {X_est.shape} but X_gt has shape {X_gt.shape}")
    return X_est, X_gt


def camera_alignment(R_est, R_gt):
    """Global orthogonal Q minimising ``sum_f ||R_gt,f[:2] - R_est,f[:2] Q||_F^2``.

    Parameters
    ----------
    R_est, R_gt : (F, 3, 3) or (F, 2, 3) ndarray

    Returns
    -------
    Q : (3, 3) ndarray, orthogonal (reflection allowed: the mirror ambiguity).
    """
    A = np.asarray(R_est, float)[:, :2]
    B = np.asarray(R_gt, float)[:, :2]
    return procrustes_orthogonal(np.einsum("fki,fkj->ij", A, B))


def rotation_error(R_est, R_gt, per_frame=False):
    """Mean camera rotation error ``e_R`` after one global orthogonal alignment.

    Parameters
    ----------
    R_est, R_gt : (F, 3, 3) or (F, 2, 3) ndarray
        Only the first two rows (the orthographic camera) are compared.
    per_frame : bool
        Return the (F,) per-frame errors.

    Returns
    -------
    float or (F,) ndarray
        Mean of ``||R_gt,f - R_est,f Q||_2`` (spectral norm of the 2 x 3 difference), with
        ``Q`` the orthogonal 3 x 3 matrix minimising ``sum_f ||R_gt,f - R_est,f Q||_F^2``.
    """
    A = check_rotations(R_est, "R_est", allow_orthographic=True)[:, :2]
    B = check_rotations(R_gt, "R_gt", allow_orthographic=True)[:, :2]
    if A.shape != B.shape:
        raise ValueError(f"R_est has {A.shape[0]} frames but R_gt has {B.shape[0]}")
    D = B - A @ camera_alignment(A, B)
    err = np.linalg.norm(D, ord=2, axis=(1, 2))
    return err if per_frame else float(err.mean())


#: modes below ``MODE_RTOL`` times the first (singular values of X#) are left out
MODE_RTOL = 1e-6


def _mode_factors(X, K):
    """Whitened coefficients ``C`` (F, k), ``C'C = F I``, and bases ``B`` (k, 3, P) of the
    rank-K part of the centred shapes, ``X_f ~ sum_k C_fk B_k``, k <= K the modes above
    ``MODE_RTOL`` (from the smaller Gram matrix of X#, F x 3P)."""
    F, _, P = X.shape
    Xs = (X - X.mean(axis=2, keepdims=True)).reshape(F, 3 * P)
    small = F <= 3 * P
    lam, E = np.linalg.eigh(Xs @ Xs.T if small else Xs.T @ Xs)
    lam, E = lam[::-1], E[:, ::-1]
    # modes of no energy (shapes of rank below K) have arbitrary coefficients: left out
    K = int(np.sum(lam[: min(K, F, 3 * P)] > MODE_RTOL**2 * lam[0])) if lam[0] > 0 else 0
    if small:
        C = E[:, :K] * np.sqrt(F)
        B = (C.T @ Xs) / F
    else:
        B = E[:, :K].T  # unit bases, then their scale
        A = Xs @ B.T  # (F, K) = U S
        norms = np.linalg.norm(A, axis=0)
        C = A / np.maximum(norms, 1e-300) * np.sqrt(F)
        B = B * (norms / np.sqrt(F))[:, None]
    return C, B.reshape(K, 3, P)


def depth_amplification(R, X, K):
    """How much more the camera motion leaves the shapes' deformation modes open than
    cameras spread evenly over all directions would: 1 for such cameras, large where the
    depth of the deformation is decided by the prior rather than by the images.

    The centred shapes' rank-K part is ``X_f = sum_k c_fk B_k`` with whitened coefficients
    (``sum_f c_f c_f' = F I``, :func:`_mode_factors`). With the coefficients and the
    cameras known, the images determine each point's column of the bases through the
    information matrix ``M = (1/F) sum_f (c_f c_f') kron (R_f[:2]' R_f[:2])`` (3K x 3K): a
    direction of mode k that no camera sees while mode k is active makes ``M`` singular.
    The error that noise on the images puts on mode k grows as the trace of the k-th 3 x 3
    diagonal block of ``M^-1`` (a Cramer-Rao bound); cameras spread evenly over the sphere
    give ``M = (2/3) I``, a trace of 4.5. The signal is that growth, averaged over the
    modes with their energy ``e_k = s_k^2 / sum s^2`` (singular values of X#):

        ``amplification = sum_k e_k tr(M^-1)_kk / 4.5``

    It uses the modes' energy, not the shapes' depth, so shapes that came out flat where
    the depth is not seen still read as undetermined.

    R (F, 3, 3) or (F, 2, 3) are the cameras, X (F, 3, P) the shapes (any units), K the
    number of modes (those below ``MODE_RTOL`` of the first left out). Returns a float:
    ``inf`` where no camera sees a direction of a mode, ``nan`` for shapes all zero.
    """
    R, X = np.asarray(R, float)[:, :2], np.asarray(X, float)  # from reconstruct: checked
    if X.ndim != 3 or X.shape[1] != 3 or R.shape != (X.shape[0], 2, 3):
        raise ValueError(f"R (F, 3, 3) and X (F, 3, P) expected; got {R.shape}, {X.shape}")
    C, B = _mode_factors(X, int(K))
    k = C.shape[1]
    if k == 0:
        return float("nan")
    energy = np.sum(B.reshape(k, -1) ** 2, axis=1)
    Pf = np.einsum("fai,faj->fij", R, R)
    M = np.einsum("fk,fl,fij->kilj", C, C, Pf).reshape(3 * k, 3 * k) / R.shape[0]
    lam, V = np.linalg.eigh(M)
    if not lam[0] > 1e-12 * max(lam[-1], 1e-300):
        return float("inf")
    blocks = np.einsum("ai,i,ai->a", V, 1.0 / lam, V).reshape(k, 3).sum(axis=1)
    return float(np.sum(energy * blocks) / np.sum(energy) / 4.5)
