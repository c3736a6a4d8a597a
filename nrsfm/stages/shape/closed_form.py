"""The closed-form rank-K solution of ``R X = W``: the nullspace method of Valmadre,
Sridharan, Denman, Fookes and Lucey ("Closed-form solutions for low-rank non-rigid
reconstruction", DICTA 2015), the bilinear solver's start.
"""

from __future__ import annotations

import numpy as np

from ..rotations.subspace import DETERMINED_RTOL
from ...validation import check_shape_inputs
from .factors import c_step

__all__ = ["closed_form_coefficients", "closed_form_shapes", "nullspace_coefficients"]

#: the rank-K fit counts as unique when the closed form's (K+1)-th eigenvalue exceeds this
NULLSPACE_GAP_MIN = 1e-12


def closed_form_coefficients(W, R, K):
    """Rank-K shape coefficients B (F, K) by the nullspace method.

    With ``W ~ M_hat B_hat`` (rank 3K), an exact rank-K shape ``X_f = sum_k b_fk S_k`` means
    ``M_hat_f G_k = b_fk R_f`` for a 3K x 3 triplet G_k per basis; eliminating
    ``b_fk = <R_f, M_hat_f G_k> / 2`` leaves ``sum_f ||(I - r_f r_f' / 2) vec(M_hat_f G)||^2``,
    a 9K x 9K quadratic form whose K smallest eigenvectors give B (up to a K x K mixing,
    which does not change X).

    Returns
    -------
    B : (F, K) ndarray
    eigenvalues : (K + 1,) ndarray
        The K + 1 smallest eigenvalues of the form relative to the largest: K near zero and
        a gap mean the rank-K solution is determined.
    """
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    U, s, _ = np.linalg.svd(W / np.linalg.norm(W), full_matrices=False)
    return nullspace_coefficients(U, s, Rf, K)


def nullspace_coefficients(U, s, Rf, K):
    """:func:`closed_form_coefficients` from the thin SVD ``U, s`` of W (any scale)."""
    F = Rf.shape[0]
    s = s / s[0]
    n = min(3 * K, int(np.sum(s > DETERMINED_RTOL)))  # W's numerical rank, at most 3K
    M = (U[:, :n] * s[:n]).reshape(F, 2, n)  # M_hat_f, (F, 2, n)
    # vec(M_f G) for G (n, 3) row-major: A_f = kron(M_f, I_3); sum_f A_f'A_f = kron(M'M, I3)
    MtM = np.einsum("fai,faj->ij", M, M)
    Q = np.kron(MtM, np.eye(3))
    v = np.einsum("fai,fac->fic", M, Rf).reshape(F, 3 * n)  # A_f' r_f = vec(M_f' R_f)
    Q -= 0.5 * v.T @ v
    evals, evecs = np.linalg.eigh((Q + Q.T) / 2)
    G = evecs[:, :K]  # (3n, K)
    B = 0.5 * v @ G  # b_fk = <R_f, M_f G_k> / 2
    return B, evals[: K + 1] / max(evals[-1], 1e-300)


def closed_form_shapes(W, R, K):
    """Closed-form rank-K shape (F, 3, P): coefficients by :func:`closed_form_coefficients`,
    bases by linear least squares. Exact (to rounding) when W is exactly ``R X`` with
    ``rank X# = K`` and the solution is unique; else a least-squares approximation."""
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    B, _ = closed_form_coefficients(W, Rf, K)
    B = B / np.linalg.norm(B, axis=0)
    return (B @ c_step(B, Rf, W, np.zeros(K)).T).reshape(F, 3, P)
