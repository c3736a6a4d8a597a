"""Input checks shared by every stage: one place that names what is wrong."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np


def _finite(A, name):
    bad = int(np.size(A) - np.count_nonzero(np.isfinite(A)))
    if bad:
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
        Not real numbers (complex, bool, dates, strings, objects: the dtype is named), wrong
        shape, fewer than 2 frames or 3 points, infinite entries, or NaN entries unless
        ``allow_missing`` (counted apart).
    """
    _check_real(W, name)
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
    _measurement_values(A, name, allow_missing)
    return A


def _check_real(W, name):
    """ValueError naming ``name`` and its dtype unless W holds integers or real floats."""
    kind = np.asarray(W).dtype.kind if not isinstance(W, np.ndarray) else W.dtype.kind
    if kind in "iuf":
        return
    if isinstance(W, (str, bytes)):
        raise ValueError(
            f"{name} must be an array of numbers; got the string {W!r} (load the "
            f"file first, e.g. numpy.load)"
        )
    what = {
        "c": "complex numbers",
        "b": "booleans",
        "M": "dates",
        "m": "time intervals",
        "U": "strings",
        "S": "strings",
        "O": "Python objects",
    }.get(kind, "not numbers")
    raise ValueError(f"{name} must hold real numbers; got dtype {np.asarray(W).dtype} ({what})")


def _measurement_values(A, name, allow_missing):
    """Infinite entries are refused; NaN entries too unless they mark missing data."""
    n_nan = 0 if allow_missing else int(np.count_nonzero(np.isnan(A)))
    counts = {"NaN": n_nan, "infinite": int(np.count_nonzero(np.isinf(A)))}
    parts = [f"{n} {kind} entr{'y' if n == 1 else 'ies'}" for kind, n in counts.items() if n]
    if parts:
        note = " (NaN marks a missing observation; an infinite value is an error)"
        raise ValueError(f"{name} contains {' and '.join(parts)}{note if allow_missing else ''}")


def check_integer(value, name, minimum=None):
    """Return ``value`` as an int; a bool, a float or a value below ``minimum`` is refused.

    Raises
    ------
    ValueError
        Naming ``name``, the value and the bound.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer; got {value!r}")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} must be at least {minimum}; got {name}={value}")
    return value


def check_positive(name, value, strict=True):
    """Return ``value`` as a float, refusing non-finite values and ``value <= 0``
    (``value < 0`` when not ``strict``)."""
    ok = np.isfinite(value) and (value > 0 if strict else value >= 0)
    if not ok:
        raise ValueError(
            f"{name} must be {'positive' if strict else 'non-negative'} and finite; got {value!r}"
        )
    return float(value)


def check_K(K, F, P):
    """Check the number of shape bases: ``1 <= K`` and ``3K <= min(2F, P - 1)``.

    The one bound of the package: a row-centred W of 2F rows and P points has rank at most
    ``min(2F, P - 1)``, so a rank-3K factorisation with ``3K = P`` is not determined.

    Raises
    ------
    ValueError
        K not an integer, below 1, or 3K above ``min(2F, P - 1)`` (both numbers named).
    """
    K = check_integer(K, "K", minimum=1)
    bound = min(2 * F, P - 1)
    if 3 * K > bound:
        raise ValueError(
            f"K={K} is too large for the data: a row-centred W of {2 * F} rows and {P} "
            f"points has rank at most min(2F, P - 1) = {bound}, below 3K = {3 * K}"
        )
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
    _check_real(R, name)
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
    _check_real(X, name)
    A = np.asarray(X, dtype=float)
    if A.ndim != 3 or A.shape[1] != 3:
        raise ValueError(f"{name} must have shape (F, 3, P); got {A.shape}")
    if n_frames is not None and A.shape[0] != n_frames:
        raise ValueError(f"{name} has {A.shape[0]} frames but the data has {n_frames}")
    if n_points is not None and A.shape[2] != n_points:
        raise ValueError(f"{name} has {A.shape[2]} points but the data has {n_points}")
    _finite(A, name)
    return A


def check_shape_inputs(W, R, K=None):
    """W as (2F, P), the first two rows of R as (F, 2, 3), F, P (and K if given)."""
    W = check_measurements(W)
    F, P = W.shape[0] // 2, W.shape[1]
    Rf = check_rotations(R, "R", n_frames=F, allow_orthographic=True)[:, :2, :]
    if K is None:
        return W, Rf, F, P
    return W, Rf, F, P, check_K(K, F, P)


@contextmanager
def blas_threads(n=1):
    """Limit BLAS/OpenMP threads inside the block (small matrices run fastest on one)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=n):
        yield


def check_choice(name, value, allowed):
    """``value`` if it is one of ``allowed`` (a tuple or the keys of a dict); ValueError
    naming the value and the choices otherwise."""
    if value not in tuple(allowed):
        raise ValueError(f"{name} must be one of {list(allowed)}; got {value!r}")
    return value


def check_fraction(name, value):
    """``value`` if it is in (0, 1]; ValueError otherwise."""
    if not (check_positive(name, value) <= 1.0):
        raise ValueError(f"{name} must be in (0, 1]; got {value!r}")
    return value


def check_problem(W, K, rotations=None, missing="complete"):
    """Every input check of a reconstruction, before any computation.

    Returns
    -------
    W : (2F, P) ndarray
        NaN where an observation is missing.
    K : int
    rotations : (F, 3, 3) ndarray or None

    Raises
    ------
    ValueError
        As :func:`check_measurements`, :func:`check_K` and :func:`check_rotations`, and
        missing observations with ``missing="error"``.
    """
    W = check_measurements(W, allow_missing=True)
    F, P = W.shape[0] // 2, W.shape[1]
    missing_entries = np.isnan(W)
    if missing_entries.any() and missing == "error":
        n_miss = int(missing_entries.reshape(F, 2, P).any(axis=1).sum())
        raise ValueError(
            f"W has {n_miss} missing (frame, point) observations (NaN or masked) and missing="
            "'error'; use missing='complete' to fill them by low-rank completion"
        )
    K = check_K(K, F, P)
    if rotations is not None:
        rotations = check_rotations(rotations, "rotations", n_frames=F)
    return W, K, rotations
