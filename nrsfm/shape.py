"""Shape stage (paper Sec. 3.2): pseudo-inverse shape and the low-rank shape optimisation.

Notation: ``X`` is the per-frame shape, (F, 3, P); ``X#`` (``X_sharp``) its reshuffle
Phi(X), (F, 3P), whose row f is ``[x-coords, y-coords, z-coords]`` of frame f's P points.
"""

from __future__ import annotations

import numpy as np

__all__ = ["phi", "phi_inv", "pseudo_inverse_shapes", "truncate_rank"]


def phi(X):
    """Phi: (F, 3, P) shapes -> (F, 3P) X#."""
    X = np.asarray(X)
    return X.reshape(X.shape[0], -1)


def phi_inv(X_sharp, P):
    """Inverse of :func:`phi`: (F, 3P) -> (F, 3, P)."""
    X_sharp = np.asarray(X_sharp)
    return X_sharp.reshape(X_sharp.shape[0], 3, P)


def pseudo_inverse_shapes(W, R):
    """Per-frame pseudo-inverse shape ``X_init = pinv(R) W`` (paper Sec. 3.2).

    Parameters
    ----------
    W : (2F, P) ndarray
    R : (F, 2, 3) or (F, 3, 3) ndarray
        Per-frame cameras; only the first two rows are used.

    Returns
    -------
    X_init : (F, 3, P) ndarray
        The minimum-norm solution of ``R_f X_f = W_f`` per frame (planar for every frame).
    """
    F = W.shape[0] // 2
    Rf = np.asarray(R)[:, :2, :]
    return np.linalg.pinv(Rf) @ W.reshape(F, 2, -1)


def truncate_rank(X, K):
    """Project X# = Phi(X) onto its top-K singular vectors; returns (F, 3, P)."""
    U, s, Vt = np.linalg.svd(phi(X), full_matrices=False)
    return phi_inv((U[:, :K] * s[:K]) @ Vt[:K], X.shape[2])
