"""Input checks shared by every stage: one place that names what is wrong."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np


def _finite(A, name):
    if not np.all(np.isfinite(A)):
        bad = int(np.size(A) - np.count_nonzero(np.isfinite(A)))
        raise ValueError(f"{name} contains {bad} NaN or infinite entries")


def check_measurements(W, name="W", allow_missing=False):
    """Return the measurement matrix as a float (2F, P) array.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Interleaved rows ``x_f, y_f``, or per-frame tracks.
    allow_missing : bool
        Accept NaN entries (missing observations); infinite entries are still refused.
        A ``numpy.ma.MaskedArray`` then has its masked entries turned into NaN.

    Returns
    -------
    W : (2F, P) ndarray of float
        A new array (the input is never modified).

    Raises
    ------
    ValueError
        Wrong number of dimensions, an odd number of rows, fewer than 2 frames or
        3 points, or non-finite entries.
    """
    if allow_missing and isinstance(W, np.ma.MaskedArray):
        A = np.ma.filled(W.astype(float), np.nan)
    else:
        A = np.array(W, dtype=float, copy=True)
    if A.ndim == 3:
        if A.shape[1] != 2:
            raise ValueError(f"{name} as tracks must have shape (F, 2, P); got {A.shape}")
        A = A.reshape(A.shape[0] * 2, A.shape[2])
    elif A.ndim != 2:
        raise ValueError(f"{name} must have shape (2F, P) or (F, 2, P); got {A.shape}")
    elif A.shape[0] % 2:
        raise ValueError(f"{name} must have an even number of rows (2F, P); got {A.shape}")
    F, P = A.shape[0] // 2, A.shape[1]
    if F < 2:
        raise ValueError(f"{name} needs at least 2 frames; got F={F} (shape {A.shape})")
    if P < 3:
        raise ValueError(f"{name} needs at least 3 points; got P={P} (shape {A.shape})")
    if allow_missing:
        _finite(np.nan_to_num(A, nan=0.0, posinf=np.inf, neginf=-np.inf), name)
    else:
        _finite(A, name)
    return A


def check_K(K, F, P):
    """Check the number of shape bases against the data size: ``1 <= K`` and ``3K <= min(2F, P)``."""
    if isinstance(K, bool) or not isinstance(K, (int, np.integer)):
        raise ValueError(f"K must be an integer; got {K!r}")
    K = int(K)
    if K < 1:
        raise ValueError(f"K must be at least 1; got K={K}")
    if 3 * K > min(2 * F, P):
        raise ValueError(
            f"K={K} is too large for the data: a rank-3K factorisation needs "
            f"3K={3 * K} <= min(2F, P) = min({2 * F}, {P}) = {min(2 * F, P)}")
    return K


def check_centred_rank(K, F, P):
    """3K against the largest rank a row-centred W can have: ``rank(W) <= min(2F, P - 1)``.

    Centring the rows makes the columns sum to zero, so one direction of the column space
    is lost; a rank-3K factorisation of such a W is then not determined.

    Raises
    ------
    ValueError
        ``3K > min(2F, P - 1)``, naming both numbers.
    """
    bound = min(2 * F, P - 1)
    if 3 * K > bound:
        raise ValueError(
            f"K={K} is too large for the data: a row-centred W of {2 * F} rows and {P} "
            f"points has rank at most min(2F, P - 1) = {bound}, below 3K = {3 * K}")
    return K


def check_rotations(R, name="R", n_frames=None, allow_orthographic=False, atol=1e-6):
    """Return camera rotations as a float (F, 3, 3) array, or (F, 2, 3) where allowed.

    Parameters
    ----------
    R : (F, 3, 3) array_like, or (F, 2, 3) if ``allow_orthographic``
        Per-frame rotations. Rows must be orthonormal to ``atol``; (F, 3, 3) input must
        also have determinant +1.
    n_frames : int, optional
        Expected F.

    Raises
    ------
    ValueError
        Wrong shape, wrong F, non-finite entries, or rows not orthonormal.
    """
    A = np.array(R, dtype=float, copy=True)
    rows_ok = (2, 3) if allow_orthographic else (3,)
    if A.ndim != 3 or A.shape[2] != 3 or A.shape[1] not in rows_ok:
        want = "(F, 3, 3) or (F, 2, 3)" if allow_orthographic else "(F, 3, 3)"
        raise ValueError(f"{name} must have shape {want}; got {A.shape}")
    if n_frames is not None and A.shape[0] != n_frames:
        raise ValueError(f"{name} has {A.shape[0]} frames but the data has {n_frames}")
    _finite(A, name)
    gram = A @ A.transpose(0, 2, 1)
    dev = np.abs(gram - np.eye(A.shape[1])).max()
    if dev > atol:
        raise ValueError(f"{name} rows are not orthonormal (max |R R' - I| = {dev:.3g})")
    if A.shape[1] == 3:
        det = np.linalg.det(A)
        if np.any(det < 0):
            raise ValueError(f"{name} has {int(np.sum(det < 0))} frames with det -1 (reflections)")
    return A


def check_shapes(X, name="X", n_frames=None, n_points=None):
    """Return per-frame 3D shapes as a float (F, 3, P) array."""
    A = np.asarray(X, dtype=float)
    if A.ndim != 3 or A.shape[1] != 3:
        raise ValueError(f"{name} must have shape (F, 3, P); got {A.shape}")
    if n_frames is not None and A.shape[0] != n_frames:
        raise ValueError(f"{name} has {A.shape[0]} frames but the data has {n_frames}")
    if n_points is not None and A.shape[2] != n_points:
        raise ValueError(f"{name} has {A.shape[2]} points but the data has {n_points}")
    _finite(A, name)
    return A


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
    _, e = np.frexp(m)                  # m = f 2**e with 0.5 <= f < 1
    return float(np.ldexp(1.0, int(e) - 1))


@contextmanager
def blas_threads(n=1):
    """Limit BLAS/OpenMP threads inside the block (small matrices run fastest on one)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=n):
        yield
