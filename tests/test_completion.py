"""Missing data: completion, masks, the pipeline's missing-data path, drop patterns."""

import numpy as np
import pytest

import data_tools as dt
import nrsfm
from nrsfm.validation import check_measurements
from nrsfm.stages.completion import complete_measurements, observed_mask


def _low_rank(F=60, P=30, r=6, seed=0):
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((2 * F, r)) @ rng.standard_normal((r, P))
    return W + rng.standard_normal((2 * F, 1)) * 3.0  # per-row offsets


def test_completion_recovers_low_rank_matrix():
    W = _low_rank()
    Wm, mask = dt.drop_tracks(W, 0.3, seed=1)
    res = complete_measurements(Wm)
    miss = np.repeat(~mask, 2, axis=0)
    fill = np.linalg.norm((res.W - W)[miss]) / np.linalg.norm(W[miss])
    assert fill < 0.02, fill
    assert res.converged
    np.testing.assert_array_equal(res.W[~miss], W[~miss])  # observed entries kept
    np.testing.assert_array_equal(res.observed, mask)


def test_completion_beats_mean_fill_and_is_scale_invariant():
    seq = dt.make_synthetic(F=60, P=30, K=2, seed=4)
    Wm, mask = dt.drop_tracks(seq.W, 0.3, seed=2)
    miss = np.repeat(~mask, 2, axis=0)
    a = complete_measurements(Wm)
    b = complete_measurements(1000.0 * Wm)
    np.testing.assert_allclose(b.W, 1000.0 * a.W, rtol=1e-7, atol=1e-7)
    mean_fill = np.where(miss, np.nanmean(Wm, axis=1, keepdims=True), Wm)
    err = lambda Z: np.linalg.norm((Z - seq.W)[miss])  # noqa: E731
    assert err(a.W) < 0.2 * err(mean_fill)


def test_complete_input_is_returned_unchanged():
    W = _low_rank()
    res = complete_measurements(W)
    np.testing.assert_array_equal(res.W, W)
    assert res.n_iter == 0


def test_observed_mask_pairs_coordinates_and_names_sparse_rows():
    W = _low_rank(F=10, P=8)
    W[0, 3] = np.nan  # only x of point 3, frame 0
    m = observed_mask(W)
    assert not m[0, 3] and m.sum() == m.size - 1
    W2 = _low_rank(F=10, P=8)
    W2[4:6, :6] = np.nan  # frame 2 keeps 2 points
    with pytest.raises(ValueError, match="frame 2 observes 2 points"):
        observed_mask(W2)
    W3 = _low_rank(F=10, P=8)
    W3[2:, 5] = np.nan  # point 5 seen once
    with pytest.raises(ValueError, match="point 5 is observed in 1 frames"):
        observed_mask(W3)


def test_check_measurements_allow_missing():
    W = _low_rank(F=5, P=6)
    W[1, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        check_measurements(W)
    assert np.isnan(check_measurements(W, allow_missing=True)[1, 1])
    W[2, 2] = np.inf
    with pytest.raises(ValueError):
        check_measurements(W, allow_missing=True)
    masked = np.ma.masked_array(_low_rank(F=5, P=6), mask=np.zeros((10, 6), bool))
    masked.mask[3, 4] = True
    assert np.isnan(check_measurements(masked, allow_missing=True)[3, 4])


@pytest.fixture(scope="module")
def seq():
    return dt.make_synthetic(F=60, P=30, K=2, seed=3)  # the completion converges


def test_reconstruct_with_missing_data(seq):
    Wm, mask = dt.drop_tracks(seq.W, 0.2, seed=0)
    res = nrsfm.reconstruct(Wm, 2)
    np.testing.assert_array_equal(res.observed, mask)
    assert res.W_completed.shape == seq.W.shape and np.all(np.isfinite(res.W_completed))
    assert "completion" in res.timings and 0 < res.completion.n_iter
    assert res.completion.converged and res.completion.method == "factorisation"
    full = nrsfm.reconstruct(seq.W, 2).errors(seq.shapes)["e3d"]
    assert full < 1e-3
    assert res.errors(seq.shapes)["e3d"] < 0.05
    # tracks (F, 2, P) with NaN and a MaskedArray give the same result
    tracks = Wm.reshape(-1, 2, Wm.shape[1])
    r2 = nrsfm.reconstruct(tracks, 2)
    r3 = nrsfm.reconstruct(np.ma.masked_invalid(Wm), 2)
    np.testing.assert_allclose(r2.shapes, res.shapes)
    np.testing.assert_allclose(r3.shapes, res.shapes)


def test_reconstruct_missing_error_and_sparse_point(seq):
    Wm, _ = dt.drop_tracks(seq.W, 0.2, seed=0)
    with pytest.raises(ValueError, match="missing='error'"):
        nrsfm.reconstruct(Wm, 2, missing="error")
    with pytest.raises(ValueError, match="missing must be"):
        nrsfm.reconstruct(seq.W, 2, missing="drop")
    W = seq.W.copy()
    W[2:, 7] = np.nan
    with pytest.raises(ValueError, match="point 7"):
        nrsfm.reconstruct(W, 2)
    res = nrsfm.reconstruct(seq.W, 2, missing="error")  # complete input: fine
    assert res.observed is None and res.W_completed is None


def test_drop_tracks_patterns():
    W = _low_rank(F=200, P=40)
    _, m = dt.drop_tracks(W, 0.3, seed=0)
    assert abs((1 - m.mean()) - 0.3) < 0.02
    Wt, mt = dt.drop_tracks(W, 0.5, seed=0, pattern="tracking")
    assert np.all(mt[:2])  # every track seen twice
    for p in range(40):  # lost until the end
        col = mt[:, p]
        if not col.all():
            first = int(np.argmin(col))
            assert not col[first:].any() and col[:first].all()
    assert 0 < (~mt).any(axis=0).mean() < 1
    np.testing.assert_array_equal(np.isnan(Wt), np.repeat(~mt, 2, axis=0))
    with pytest.raises(ValueError, match="pattern"):
        dt.drop_tracks(W, 0.3, pattern="burst")
    with pytest.raises(ValueError, match="fraction"):
        dt.drop_tracks(W, 1.0)


def test_temporal_lags_help_on_smooth_sequences_and_are_validated():
    seq = dt.make_synthetic(F=80, P=20, K=3, seed=5)
    Wm, mask = dt.drop_tracks(seq.W, 0.4, seed=3)
    miss = np.repeat(~mask, 2, axis=0)
    err = {
        lags: np.linalg.norm((complete_measurements(Wm, lags=lags).W - seq.W)[miss])
        for lags in [(0,), (-1, 0, 1)]
    }
    assert err[(-1, 0, 1)] < err[(0,)]
    with pytest.raises(ValueError, match="lags"):
        complete_measurements(Wm, lags=(1, 2))
