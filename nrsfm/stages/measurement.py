"""Measurement stage (paper Sec. 2, Eq. 1): centring, scale and the rank-3K factorisation.

:func:`measure` maps the (complete) input W to :class:`Measurements`: the row-centred W,
``Wn = W_c / scale`` with ``||Wn||_F = WORKING_FROBENIUS`` (the later stages run on Wn, so
their result does not depend on the input's units) and the rank-3K SVD of Wn.

Why a fixed norm: the stages are scale-free in exact arithmetic but not in their paths (the
relaxation's ADMM has absolute tolerances, L-BFGS stops at a gradient tolerance); 170 is
also the norm the paper's ADMM constants are tuned at (:mod:`nrsfm.stages.shape.admm`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..noise import noise_from_singular_values

__all__ = ["Factorization", "Measurements", "factorize", "measure"]

#: Frobenius norm of the W the stages work on (see the module docstring)
WORKING_FROBENIUS = 170.0
#: W is "wide" (dense tracks) when P > WIDE_RATIO * 2F: its SVD then goes through W W'
WIDE_RATIO = 4


def power_of_two_scale(A):
    """``2**e`` with ``2**e <= max|A| < 2**(e+1)``, or 1 when ``A`` is zero or empty.

    Dividing a finite array by it is exact (only exponents change), which brings any finite
    input to ``max|A|`` in ``[1, 2)`` before norms, products or SVDs that would overflow
    (``|A| ~ 1e153``) or underflow (``|A| ~ 1e-165``).
    """
    A = np.asarray(A, dtype=float)
    m = float(np.max(np.abs(A))) if A.size else 0.0
    if m == 0.0 or not np.isfinite(m):
        return 1.0
    _, e = np.frexp(m)  # m = f 2**e with 0.5 <= f < 1
    return float(np.ldexp(1.0, int(e) - 1))


def left_singular(W):
    """(U, s, Vt): the left singular vectors and singular values of W (2F, P), largest
    first, and the right singular vectors, or None where W is wide (``P > WIDE_RATIO 2F``).

    Wide W (dense tracks) goes through the small 2F x 2F Gram matrix W W': one product
    linear in P instead of LAPACK's SVD of W (30,000 points x 100 frames: 0.12 s against
    1.5 - 6 s). Squaring costs accuracy only in the tiny singular values (relative to s_1,
    about 1e-8), not in the leading ones. Otherwise the thin SVD (U is then (2F, min(2F, P))).
    """
    if W.shape[1] > WIDE_RATIO * W.shape[0]:
        lam, U = np.linalg.eigh(W @ W.T)
        order = np.argsort(lam)[::-1]
        return U[:, order], np.sqrt(np.clip(lam[order], 0.0, None)), None
    return np.linalg.svd(W, full_matrices=False)


def centre_rows(W):
    """Subtract each row's mean (removes per-frame translation). Returns (W_c, means)."""
    means = W.mean(axis=1, keepdims=True)
    return W - means, means[:, 0]


@dataclass
class Factorization:
    """Rank-3K SVD ``W ~ M_hat B_hat`` (Eq. 1): ``M_hat = U_3K sqrt(S_3K)`` (2F, 3K),
    ``B_hat = sqrt(S_3K) V_3K'`` (3K, P), all singular values of W, the relative residual
    ``||W - M_hat B_hat||_F / ||W||_F`` and W's noise level beyond rank 3K in W's units
    (:func:`nrsfm.noise.noise_from_singular_values`)."""

    M_hat: np.ndarray
    B_hat: np.ndarray
    singular_values: np.ndarray
    residual: float
    noise_level: float


def factorize(W, K):
    """Rank-3K factorisation of W by SVD.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements.
    K : int
        Number of shape bases; 3K <= min(2F, P) (checked by the caller).

    Returns
    -------
    Factorization
    """
    r = 3 * K
    U, s, Vt = left_singular(W)
    if Vt is None:  # wide W: the right vectors from the left ones
        if not s[r - 1] > 0:
            raise ValueError(f"W has rank below 3K = {r}")
        Vt_r = (U[:, :r] / s[:r]).T @ W
    else:
        Vt_r = Vt[:r]
    root = np.sqrt(s[:r])
    M_hat = U[:, :r] * root
    B_hat = root[:, None] * Vt_r
    nW = np.linalg.norm(W)
    residual = float(np.linalg.norm(W - M_hat @ B_hat) / nW) if nW > 0 else 0.0
    return Factorization(
        M_hat=M_hat,
        B_hat=B_hat,
        singular_values=s,
        residual=residual,
        noise_level=noise_from_singular_values(s, W.shape, K),
    )


def working_scale(W):
    """``||W||_F / WORKING_FROBENIUS`` of a row-centred W (2F, P); ValueError when W is
    zero (a constant input: nothing to reconstruct)."""
    norm = float(np.linalg.norm(W))
    if not norm > 0:
        raise ValueError(
            "W is constant (every row has zero spread, W is zero after centring): "
            "nothing to reconstruct"
        )
    return norm / WORKING_FROBENIUS


@dataclass
class Measurements:
    """What the measurement stage hands on: the row-centred input ``W`` (2F, P) in its
    units, ``row_means`` (2F,) (what centring removed: per-frame translation), ``Wn = W /
    scale`` (``||Wn||_F = WORKING_FROBENIUS``: what the later stages run on), ``scale`` and
    the rank-3K ``factorization`` of Wn."""

    W: np.ndarray
    row_means: np.ndarray
    Wn: np.ndarray
    scale: float
    factorization: Factorization
    _p2: float = 1.0
    _s: float = 1.0

    def restore(self, X):
        """Shapes (or any array linear in W) from Wn's units to the input's units."""
        return (X * self._s) * self._p2


def measure(W, K):
    """Centre, normalise and factorise a complete W (2F, P).

    Any finite W: it is first divided by an exact power of two near max|W|, so that
    centring, norms and the SVD neither overflow (|W| ~ 1e153) nor underflow (~ 1e-165).

    Returns
    -------
    Measurements
    """
    p2 = power_of_two_scale(W)
    Wc_p, row_means_p = centre_rows(W / p2)
    s = working_scale(Wc_p)
    Wn = Wc_p / s
    return Measurements(
        W=Wc_p * p2,
        row_means=row_means_p * p2,
        Wn=Wn,
        scale=s * p2,
        factorization=factorize(Wn, K),
        _p2=p2,
        _s=s,
    )
