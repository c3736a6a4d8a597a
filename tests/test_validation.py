import numpy as np
import pytest

import data_tools as dt
import nrsfm
import nrsfm.validation


@pytest.fixture(scope="module")
def seq():
    return dt.make_synthetic(F=30, P=20, K=2, seed=2)


def test_tracks_and_interleaved_give_the_same_result(seq):
    a = nrsfm.reconstruct(seq.W, 2, method="pseudo_inverse", rotations=seq.rotations)
    b = nrsfm.reconstruct(seq.tracks, 2, method="pseudo_inverse", rotations=seq.rotations)
    np.testing.assert_array_equal(a.shapes, b.shapes)


def test_input_is_not_modified_and_translation_is_removed(seq):
    W = seq.W + 5.0
    before = W.copy()
    res = nrsfm.reconstruct(W, 2, method="pseudo_inverse", rotations=seq.rotations)
    np.testing.assert_array_equal(W, before)
    np.testing.assert_allclose(res.row_means, 5.0)
    np.testing.assert_allclose(res.W, seq.W, atol=1e-12)


@pytest.mark.parametrize(
    "W, message",
    [
        (np.zeros((10,)), r"\(2F, P\) or \(F, 2, P\)"),
        (np.zeros((9, 12)), "even number of rows"),
        (np.zeros((5, 3, 12)), r"\(F, 2, P\)"),
        (np.zeros((2, 12)), "at least 2 frames"),
        (np.zeros((10, 2)), "at least 3 points"),
    ],
)
def test_bad_shapes(W, message):
    with pytest.raises(ValueError, match=message):
        nrsfm.reconstruct(W, 1)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite(seq, value):
    W = seq.W.copy()
    W[3, 4] = value
    # NaN means "not observed": refused with missing="error" (completed by default)
    with pytest.raises(ValueError, match="NaN or infinite|infinite|missing='error'"):
        nrsfm.reconstruct(W, 2, missing="error")


@pytest.mark.parametrize(
    "K, message",
    [(0, "at least 1"), (-2, "at least 1"), (7, "too large"), (2.5, "integer"), (True, "integer")],
)
def test_bad_K(seq, K, message):
    with pytest.raises(ValueError, match=message):
        nrsfm.reconstruct(seq.W, K)


def test_K_limit_is_min_of_2F_and_P_minus_1():
    W = dt.make_synthetic(F=4, P=30, K=2, seed=0).W  # 2F = 8 rows
    with pytest.raises(ValueError, match=r"min\(2F, P - 1\) = 8"):
        nrsfm.reconstruct(W, 3)
    W = dt.make_synthetic(F=30, P=9, K=2, seed=0).W  # P - 1 = 8 < 3K = 9 = P
    with pytest.raises(ValueError, match=r"min\(2F, P - 1\) = 8"):
        nrsfm.reconstruct(W, 3)


def test_unknown_method(seq):
    with pytest.raises(ValueError, match="method must be one of .*got .magic."):
        nrsfm.reconstruct(seq.W, 2, method="magic")


def test_bad_rotations(seq):
    with pytest.raises(ValueError, match=r"\(F, 3, 3\)"):
        nrsfm.reconstruct(seq.W, 2, rotations=seq.rotations[:, :2])
    with pytest.raises(ValueError, match="frames"):
        nrsfm.reconstruct(seq.W, 2, rotations=seq.rotations[:-1])
    with pytest.raises(ValueError, match="orthonormal"):
        nrsfm.reconstruct(seq.W, 2, rotations=2 * seq.rotations)
    with pytest.raises(ValueError, match="det -1"):
        nrsfm.reconstruct(seq.W, 2, rotations=seq.rotations @ np.diag([1, 1, -1]))


def test_constant_W_is_rejected():
    with pytest.raises(ValueError, match="constant"):
        nrsfm.reconstruct(
            np.ones((10, 6)), 1, method="pseudo_inverse", rotations=np.tile(np.eye(3), (5, 1, 1))
        )


def test_pseudo_inverse_with_given_rotations_result_object(seq):
    res = nrsfm.reconstruct(seq.W, 2, method="pseudo_inverse", rotations=seq.rotations)
    F, P = 30, 20
    assert res.rotations.shape == (F, 3, 3) and res.shapes.shape == (F, 3, P)
    assert res.X_init.shape == (F, 3, P) and res.rotation_stage is None
    assert res.factorization.M_hat.shape == (2 * F, 6)
    # X_init explains W exactly; its rank-K truncation is what is returned
    proj = (res.rotations[:, :2] @ res.X_init).reshape(2 * F, P)
    np.testing.assert_allclose(proj, res.W, atol=1e-10)
    s = np.linalg.svd(res.shapes.reshape(F, -1), compute_uv=False)
    assert s[2] < 1e-10 * s[0]
    assert "pseudo_inverse" in res.summary()


def test_power_of_two_scale_is_exact():
    from nrsfm.stages.measurement import power_of_two_scale

    rng = np.random.default_rng(0)
    for c in (1e153, 1e-165, 3.0, 2.0**-1060, 1e300):
        A = rng.standard_normal((6, 5)) * c
        p = power_of_two_scale(A)
        assert 1.0 <= np.abs(A / p).max() < 2.0
        np.testing.assert_array_equal((A / p) * p, A)  # only exponents change
    assert power_of_two_scale(np.zeros((3, 3))) == 1.0


@pytest.mark.parametrize("factor", [1e153, 1e-165, 1e300, 1e-300])
def test_any_finite_scale_of_W(seq, factor):
    ref = nrsfm.reconstruct(seq.W, 2)
    res = nrsfm.reconstruct(seq.W * factor, 2)
    assert np.all(np.isfinite(res.shapes)) and res.scale > 0
    np.testing.assert_allclose(
        res.shapes / factor, ref.shapes, rtol=0, atol=1e-6 * np.abs(ref.shapes).max()
    )
    # exact data: the reprojection error is round-off, so compare it on W's scale
    np.testing.assert_allclose(
        res.reprojection_error() / factor,
        ref.reprojection_error(),
        rtol=1e-4,
        atol=1e-7 * np.abs(seq.W).max(),
    )
    e_ref = ref.errors(seq.shapes, seq.rotations)
    e = res.errors(seq.shapes * factor, seq.rotations)
    for key in e_ref:
        np.testing.assert_allclose(e[key], e_ref[key], rtol=1e-5, atol=1e-7)


def test_tiny_variation_on_a_large_offset_is_not_constant(seq):
    """Only a W whose rows are all constant is 'constant'."""
    res = nrsfm.reconstruct(seq.W * 1e-9 + 1e6, 2, method="pseudo_inverse", rotations=seq.rotations)
    assert np.all(np.isfinite(res.shapes)) and res.scale > 0


@pytest.mark.parametrize("value", [np.inf, -np.inf])
def test_infinite_entry_is_called_infinite(seq, value):
    """With missing data allowed (the default), NaN is a missing observation and an
    infinite entry is an error whose message says infinite, not "NaN or infinite"."""
    W = seq.W.copy()
    W[3, 4] = value
    W[5, 6] = np.nan  # missing: not counted as an error
    with pytest.raises(ValueError) as info:
        nrsfm.reconstruct(W, 2)
    msg = str(info.value)
    assert msg.startswith("W contains 1 infinite entry (NaN marks a missing observation")
    assert "NaN or" not in msg


def test_non_finite_counts_each_kind_when_missing_is_refused():
    from nrsfm.validation import check_measurements

    W = np.ones((6, 5))
    W[0, 0], W[1, 1], W[2, 2] = np.nan, np.nan, np.inf
    with pytest.raises(ValueError, match=r"^W contains 2 NaN entries and 1 infinite entry$"):
        check_measurements(W)
    W[2, 2] = 1.0
    assert np.isnan(check_measurements(W, allow_missing=True)).sum() == 2
    with pytest.raises(ValueError, match=r"^W contains 2 NaN entries$"):
        check_measurements(W)


@pytest.mark.parametrize(
    "dtype,what",
    [
        (complex, "complex numbers"),
        (bool, "booleans"),
        ("datetime64[s]", "dates"),
        ("timedelta64[s]", "time intervals"),
        (str, "strings"),
        (object, "Python objects"),
    ],
)
def test_measurements_must_be_real_numbers(dtype, what):
    W = np.arange(40.0).reshape(8, 5)
    with pytest.raises(ValueError, match=rf"^W must hold real numbers; got dtype .*\({what}\)"):
        nrsfm.reconstruct(W.astype(dtype), 1)


def test_a_file_name_is_not_measurements():
    with pytest.raises(ValueError, match="W must be an array of numbers; got the string 'W.npz'"):
        nrsfm.reconstruct("W.npz", 1)


@pytest.mark.parametrize("dtype", [np.int64, np.uint16, np.float32])
def test_integer_and_single_precision_measurements_are_numbers(dtype):
    W = nrsfm.validation.check_measurements((100 * np.arange(40.0).reshape(8, 5)).astype(dtype))
    assert W.dtype == np.float64
