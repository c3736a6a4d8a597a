"""Property-based checks of ``nrsfm.reconstruct`` on inputs a user may have: every outcome
is a ValueError that names the argument, or a finite result with its invariants (shapes,
rotations in SO(3), the same answer twice), and no numpy warning escapes."""

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import data_tools
import nrsfm
from nrsfm.warnings_catalog import CATALOG, UNRELIABLE

#: bounded: about 15 s (the whole test suite runs in CI)
SETTINGS = settings(
    max_examples=200, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck)
)


def _run(W, K, **kw):
    """reconstruct(W, K): the result, or the ValueError; a warning that is not one of the
    library's own (an id of ``nrsfm.warnings_catalog.CATALOG``) fails."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = nrsfm.reconstruct(W, K, **kw)
        except ValueError as exc:
            out = exc
    ids = tuple(CATALOG)
    other = [str(w.message)[:80] for w in caught if not str(w.message).startswith(ids)]
    other = [m for m in other if not m.startswith(UNRELIABLE)]
    assert not other, other
    return out


def _check_result(res, F, P):
    assert res.rotations.shape == (F, 3, 3) and res.shapes.shape == (F, 3, P)
    assert np.isfinite(res.shapes).all() and np.isfinite(res.rotations).all()
    eye = np.broadcast_to(np.eye(3), (F, 3, 3))
    np.testing.assert_allclose(res.rotations @ res.rotations.transpose(0, 2, 1), eye, atol=1e-8)
    np.testing.assert_allclose(np.linalg.det(res.rotations), 1.0, atol=1e-8)


@st.composite
def measurements(draw):
    """W (2F, P) of a synthetic sequence or of noise, at some magnitude, with some missing
    entries, in some dtype; and K."""
    F, P = draw(st.integers(2, 14)), draw(st.integers(3, 16))
    K = draw(st.integers(1, 3))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    if draw(st.booleans()) and 3 * K + 2 <= P and 2 * F >= 3 * K:
        W = data_tools.make_synthetic(F=F, P=P, K=K, motion="random", seed=seed).W
    else:
        W = rng.standard_normal((2 * F, P))
    dtype = draw(st.sampled_from(["float64", "float64", "float32", "int64"]))
    exponent = {"float64": (-60, 60), "float32": (-20, 20), "int64": (1, 6)}[dtype]
    W = W * 10.0 ** draw(st.integers(*exponent))
    missing = draw(st.sampled_from([0.0, 0.0, 0.1, 0.3]))
    if missing:
        lost = rng.random((F, P)) < missing
        W = W.copy()
        W[np.repeat(lost, 2, axis=0)] = np.nan
    elif dtype != "float64":
        W = W.astype(np.float32) if dtype == "float32" else np.round(W).astype(np.int64)
    return W, K


@SETTINGS
@given(measurements())
def test_reconstruct_gives_a_clear_error_or_a_finite_result(case):
    W, K = case
    F, P = W.shape[0] // 2, W.shape[1]
    res = _run(W, K)
    if isinstance(res, ValueError):
        message = str(res)
        assert message and "could not broadcast" not in message and "reshape" not in message
        return
    _check_result(res, F, P)
    again = _run(W, K)  # one answer: the same input, the same result
    np.testing.assert_array_equal(again.shapes, res.shapes)


@pytest.mark.parametrize(
    "bad,match",
    [
        (np.zeros((4, 5, 6)), "W as tracks must have shape"),
        (np.zeros(7), "W must have shape"),
        (np.full((6, 5), np.inf), "W contains"),
        (np.zeros((6, 2)), "at least 3 points"),
    ],
)
def test_shapes_and_values_are_named(bad, match):
    with pytest.raises(ValueError, match=match):
        nrsfm.reconstruct(bad, 1)
