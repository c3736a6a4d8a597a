"""Low-rank factorisation of the observed entries (nrsfm/stages/completion/solvers.py), the
fill gain, and the completion stage's settings through ``reconstruct``."""

import numpy as np
import pytest

from nrsfm.stages.completion import MAX_GAIN, complete_low_rank, fill_gain, observed_entries
from nrsfm.stages.completion.solvers import _solve_structure, _truncated_svd, mask_groups


def _tracks(F=40, P=60, r=4, lost=0.3, late=0.1, noise=0.0, seed=0):
    """Rank-r W plus per-row offsets; lost tracks (to the end) and late ones (from a frame)."""
    rng = np.random.default_rng(seed)
    t = np.arange(F)[:, None] / F
    M = np.concatenate(
        [np.sin(2 * np.pi * (k + 1) * t + rng.uniform(0, 6, (1, 2))) for k in range(r)], axis=1
    ).reshape(2 * F, r)
    W = M @ rng.standard_normal((r, P)) + 5.0 * rng.standard_normal((2 * F, 1))
    W += noise * rng.standard_normal(W.shape)
    obs = np.ones((F, P), bool)
    n_lost, n_late = int(lost * P), int(late * P)
    frames = np.arange(F)[:, None]
    obs[:, :n_lost] = frames < rng.integers(F // 4, F, n_lost)
    obs[:, n_lost : n_lost + n_late] = frames >= rng.integers(0, 3 * F // 4, n_late)
    return W, obs


def _nan(W, obs):
    return np.where(np.repeat(obs, 2, axis=0), W, np.nan)


def test_noise_free_low_rank_tracks_are_filled_exactly():
    W, obs = _tracks()
    res = complete_low_rank(_nan(W, obs), 4, lags=(0,), tol=1e-12, max_iter=500)
    miss = np.repeat(~obs, 2, axis=0)
    assert np.abs(res.W - W)[miss].max() < 1e-2 * W.std()
    np.testing.assert_array_equal(res.W[~miss], W[~miss])  # observed entries kept
    np.testing.assert_array_equal(res.observed, obs)
    assert res.rank == 4 and res.M.shape == (80, 4) and res.B.shape == (4, 60)
    fit = res.M @ res.B + res.t[:, None]
    assert np.sqrt(np.mean((W - fit)[~miss] ** 2)) < 1e-3 * W.std()


def test_noisy_fill_error_is_at_the_noise_level_and_beats_mean_fill():
    W, obs = _tracks(noise=0.01, seed=1)
    res = complete_low_rank(_nan(W, obs), 4)
    assert res.converged and res.n_iter < 300
    miss = np.repeat(~obs, 2, axis=0)
    det = np.repeat((res.fill_gain <= MAX_GAIN)[None], 2 * obs.shape[0], axis=0) & miss
    assert det.sum() > 0.5 * miss.sum()
    rms = np.sqrt(np.mean((res.W - W)[det] ** 2))
    assert rms < 0.05, rms  # noise 0.01, W std ~ 5
    mean_fill = np.nanmean(_nan(W, obs), axis=1, keepdims=True)
    assert rms < 0.05 * np.sqrt(np.mean((mean_fill - W)[miss] ** 2))


def test_completion_is_scale_and_offset_equivariant():
    W, obs = _tracks(noise=0.01, seed=2)
    a = complete_low_rank(_nan(W, obs), 4)
    b = complete_low_rank(_nan(1000.0 * W, obs), 4)
    np.testing.assert_allclose(b.W, 1000.0 * a.W, rtol=1e-6, atol=1e-6 * np.abs(b.W).max())
    shift = np.random.default_rng(0).standard_normal((W.shape[0], 1)) * 50
    c = complete_low_rank(_nan(W + shift, obs), 4)
    np.testing.assert_allclose(c.W, a.W + shift, atol=1e-5 * np.abs(c.W).max())


def test_structure_step_matches_per_point_least_squares():
    W, obs = _tracks(F=12, P=15, r=3, seed=3)
    Wz, obs = observed_entries(_nan(W, obs))
    rng = np.random.default_rng(0)
    M, t = rng.standard_normal((24, 3)), rng.standard_normal(24)
    B, data = _solve_structure(Wz, mask_groups(obs), M, t, 0.5)
    for p in range(15):
        rows = np.repeat(obs[:, p], 2)
        A = M[rows].T @ M[rows] + 0.5 * np.eye(3)
        np.testing.assert_allclose(B[:, p], np.linalg.solve(A, M[rows].T @ (W[rows, p] - t[rows])))
    rows = np.repeat(obs, 2, axis=0)
    assert np.isclose(data, np.sum((W - M @ B - t[:, None])[rows] ** 2))


def test_fill_gain_is_small_for_long_tracks_and_infinite_for_undetermined_ones():
    W, _ = _tracks(F=30, P=8, r=4)
    M = _truncated_svd(W - W.mean(axis=1, keepdims=True), 4)[0]  # smooth motion
    obs = np.ones((30, 4), bool)
    obs[20:, 1] = False  # lost late: a short gap
    obs[3:, 2] = False  # lost early: extrapolated
    obs[1:, 3] = False  # one frame: 2 rows < r
    g = fill_gain(M, obs)
    assert g[0] <= 1.0 + 1e-9
    assert g[0] < g[1] < MAX_GAIN < g[2] < np.inf
    assert g[3] == np.inf


def test_observed_entries_pair_coordinates_and_name_sparse_frames_and_points():
    W, obs = _tracks(F=10, P=8, lost=0, late=0)
    W[0, 3] = np.nan  # x only: the point is missing
    Wz, o = observed_entries(W)
    assert not o[0, 3] and o.sum() == o.size - 1 and Wz[1, 3] == 0.0
    W2 = W.copy()
    W2[4:6, :6] = np.nan
    with pytest.raises(ValueError, match="frame 2 observes 2 points"):
        observed_entries(W2)
    W3 = W.copy()
    W3[2:, 5] = np.nan
    with pytest.raises(ValueError, match="point 5 is observed in 1 frames"):
        observed_entries(W3)
    with pytest.raises(ValueError, match="rank must be"):
        complete_low_rank(W, 8)


def test_lags_tie_a_missing_entry_to_its_own_smooth_trajectory():
    W, _ = _tracks(F=120, P=12, r=8, noise=0.01, seed=5)  # rank 8 of 12: weak
    obs = np.random.default_rng(1).random((120, 12)) > 0.3  # uniform missing
    miss = np.repeat(~obs, 2, axis=0)
    err = {}
    for lags in ((0,), (-1, 0, 1)):
        res = complete_low_rank(_nan(W, obs), 8, lags=lags)
        assert res.B.shape == (8, 12 * len(lags))
        err[lags] = np.sqrt(np.mean((res.W - W)[miss] ** 2))
    assert err[(-1, 0, 1)] < 0.3 * err[(0,)], err


def test_a_track_seen_in_two_frames_is_filled_better_under_the_tracks_prior():
    for seed in (6, 7):
        W, obs = _tracks(F=40, P=60, r=4, noise=0.01, seed=seed)
        obs[2:, 0] = False  # 2 frames: b_0 undetermined
        res = complete_low_rank(_nan(W, obs), 4)
        determined = res.fill_gain <= MAX_GAIN
        assert not determined[0] and determined[1:].mean() > 0.5
        Wz, o = observed_entries(_nan(W, obs))
        B = _solve_structure(Wz, mask_groups(o), res.M, res.t, res.lam)[0]
        ridge = res.M @ B[:, 0] + res.t  # without the prior
        err = lambda x: np.sqrt(np.mean((x - W[:, 0])[4:] ** 2))  # noqa: E731
        assert err(res.W[:, 0]) < 0.6 * err(ridge)
        assert err(res.W[:, 0]) < 0.1 * np.nanstd(_nan(W, obs), axis=1).mean()


def test_lags_rule_and_completion_setting_through_reconstruct():
    import data_tools as dt
    import nrsfm
    from nrsfm.settings import MeasurementSettings, Settings
    from nrsfm.stages.completion import choose_lags

    obs = np.ones((10, 40), bool)
    assert choose_lags(obs, 20) == (-1, 0, 1) and choose_lags(obs, 6) == (0,)
    obs[4, :30] = False  # one frame sees 10 points
    assert choose_lags(obs, 6) == (-1, 0, 1) and choose_lags(obs, 3) == (0,)
    with pytest.raises(ValueError, match="lags"):
        MeasurementSettings(lags=(1, 2))
    with pytest.raises(ValueError, match="completion"):
        MeasurementSettings(completion="svd")
    seq = dt.make_synthetic(F=40, P=30, K=1, seed=4)
    Wm, _ = dt.drop_tracks(seq.W, 0.3, seed=1, pattern="uniform")
    res = {}
    for name in ("factorisation", "soft_impute"):
        s = Settings(measurement=MeasurementSettings(completion=name, lags=(0,)))
        r = nrsfm.reconstruct(Wm, 1, settings=s)
        res[name] = r
        assert r.completion.lags == (0,) and r.settings.measurement.completion == name
        assert r.completion.converged
    assert res["factorisation"].completion.method == "factorisation"
    assert res["soft_impute"].completion.method == "soft_impute"
    auto = nrsfm.reconstruct(Wm, 1)  # default auto: no lags -> factorisation
    assert auto.completion.lags == choose_lags(auto.observed, 3)
    np.testing.assert_allclose(auto.shapes, res["factorisation"].shapes)


def test_reconstruction_reports_the_undetermined_tracks():
    import data_tools as dt
    import nrsfm

    seq = dt.make_synthetic(F=40, P=40, K=1, seed=5)
    W = seq.W.copy()
    W[4:, 0] = np.nan  # seen in 2 frames
    with pytest.warns(nrsfm.NRSfMWarning, match="W-fills-unreliable: .* 1 of 40 tracks"):
        r = nrsfm.reconstruct(W, 1)  # its fills from the neighbours disagree
    assert r.fill_gain.shape == (40,) and r.undetermined[0] and r.undetermined.sum() == 1
    assert "1 of 40 tracks undetermined" in r.summary() and r.unreliable[0]
    assert "WARNING: W-fills-unreliable: " in r.summary()
    full = nrsfm.reconstruct(seq.W, 1)
    assert full.fill_gain is None and not full.undetermined.any()


def test_auto_completion_follows_the_lags_rule():
    """``completion="auto"``: soft-impute where the lags rule asks for lags (few points per
    frame for the rank), the factorisation elsewhere."""
    import data_tools as dt
    import nrsfm

    small = dt.make_synthetic(F=40, P=15, K=3, seed=2)  # 15 points, rank 9: lags
    Wm, _ = dt.drop_tracks(small.W, 0.2, seed=1, pattern="uniform")
    res = nrsfm.reconstruct(Wm, 3)
    assert res.completion.lags == (-1, 0, 1) and res.completion.converged
    assert res.completion.method == "soft_impute"
    wide = dt.make_synthetic(F=40, P=60, K=1, seed=2)  # 60 points, rank 3: no lags
    Wm, _ = dt.drop_tracks(wide.W, 0.2, seed=1, pattern="uniform")
    res = nrsfm.reconstruct(Wm, 1)
    assert res.completion.lags == (0,)
    assert res.completion.method == "factorisation"


def test_reconstruct_warns_when_the_completion_stops_at_its_cap():
    """Soft-impute extrapolates lost tracks slowly: on this input (half the tracks lost) it
    stops at its cap of 500 iterations, and ``reconstruct`` says so."""
    import data_tools as dt
    import nrsfm
    from nrsfm.settings import MeasurementSettings, Settings

    seq = dt.make_synthetic(F=40, P=30, K=1, seed=4)
    Wm, _ = dt.drop_tracks(seq.W, 0.5, seed=1, pattern="tracking")
    s = Settings(measurement=MeasurementSettings(completion="soft_impute", lags=(0,)))
    with pytest.warns(
        RuntimeWarning, match=r"^W-completion-cap: .* iteration cap \(500\) before converging"
    ):
        r = nrsfm.reconstruct(Wm, 1, settings=s)
    assert not r.completion.converged and r.completion.n_iter == 500


def test_mask_groups_are_numpy_unique_of_the_packed_rows():
    """The observation patterns and their index are those of ``np.unique`` on the packed
    rows (its order, its first occurrences), on masks with repeated patterns and more than
    64 frames (several 8-byte words per row)."""
    rng = np.random.default_rng(4)
    for F, P in ((5, 7), (100, 300), (131, 50)):
        obs = rng.random((F, P)) < 0.9
        obs[:, 1::2] = obs[:, 0 : 2 * (P // 2) : 2]
        patterns, index = mask_groups(obs)
        _, first, inv = np.unique(
            np.packbits(obs.T, axis=1), axis=0, return_index=True, return_inverse=True
        )
        assert np.array_equal(patterns, obs[:, first].T)
        assert np.array_equal(index, inv.ravel()) and np.array_equal(patterns[index], obs.T)
