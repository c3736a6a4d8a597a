"""The fill of the points not seen from their neighbours (nrsfm.stages.fill)."""

import numpy as np
import pytest

import data_tools
import nrsfm
from nrsfm.settings import Settings
from nrsfm.stages.completion import MeasurementSettings
from nrsfm.stages import fill
from nrsfm.stages.fill import fill_unseen
from nrsfm.geometry import project_to_so3
from nrsfm.warnings_catalog import UNRELIABLE, ids_in


def _rigid_parts(F=30, parts=3, size=8, seed=0):
    """(F, 3, P) shapes of ``parts`` rigid bodies far apart, each moving on its own."""
    rng = np.random.default_rng(seed)
    out = []
    for b in range(parts):
        body = rng.standard_normal((3, size))
        axis = rng.standard_normal(3)
        frames = []
        for f in range(F):
            w = 0.05 * f * axis
            W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
            R = project_to_so3(np.eye(3) + W + W @ W / 2)
            frames.append(R @ body + np.array([20.0 * b, 0.1 * f, 0])[:, None])
        out.append(np.stack(frames))
    return np.concatenate(out, axis=2)


def test_rigid_parts_are_filled_exactly_whatever_the_model_says():
    X = _rigid_parts()
    obs = np.ones((X.shape[0], X.shape[2]), bool)
    obs[12:, 3] = False  # lost to the end
    obs[:9, 10] = False  # late start
    obs[5:20, 17] = False  # a block
    model = X.copy()
    model[~np.broadcast_to(obs[:, None, :], X.shape)] = 0.0  # a wrong model fill
    filled, spread = fill_unseen(model, obs)
    # rigid and template fills are exact; the median is off by the affine ridge's bias
    err = np.linalg.norm(filled - X, axis=1)
    assert err.max() < 1e-2  # bodies 20 apart, of radius ~1.7
    assert np.all(spread[[3, 10, 17]] < 1e-2)
    assert np.isnan(np.delete(spread, [3, 10, 17])).all()
    only, spread = fill_unseen(model, obs, points=np.arange(X.shape[2]) == 3)
    np.testing.assert_array_equal(np.delete(only, 3, axis=2), np.delete(model, 3, axis=2))
    assert np.isfinite(spread).sum() == 1


def test_fill_checks_the_mask():
    X = _rigid_parts(F=5)
    with pytest.raises(ValueError, match="observed"):
        fill_unseen(X, np.ones((5, 3), bool))
    with pytest.raises(ValueError, match="fill"):
        MeasurementSettings(fill="magic")


def test_reconstruct_fills_the_lost_points_and_keeps_the_seen():
    seq = data_tools.make_synthetic(F=40, P=20, K=2, seed=3)
    W, obs = data_tools.drop_tracks(seq.W, 0.3, seed=31, pattern="lost")
    with pytest.warns(nrsfm.NRSfMWarning, match="W-fills-unreliable: "):
        res = nrsfm.reconstruct(W, 2)  # the default: fill="neighbours"
    with pytest.warns(nrsfm.NRSfMWarning, match="W-fills-unreliable: .*fill='model'"):
        model = nrsfm.reconstruct(
            W, 2, settings=Settings(measurement=MeasurementSettings(fill="model"))
        )  # the shape stage's fill
    assert res.settings.measurement.fill == "neighbours"
    assert model.fill_spread is None and "fill" in res.timings
    seen = np.broadcast_to(obs[:, None, :], res.shapes.shape)
    np.testing.assert_array_equal(res.shapes[seen], model.shapes[seen])
    assert not np.allclose(res.shapes[~seen], model.shapes[~seen])
    filled = res.undetermined  # the points the data leave undetermined
    assert filled.any()
    assert np.isfinite(res.fill_spread[filled]).all()
    assert np.isnan(res.fill_spread[~filled]).all()
    kept = np.broadcast_to(~filled[None, None, :], res.shapes.shape)
    np.testing.assert_array_equal(res.shapes[kept], model.shapes[kept])
    from nrsfm.stages.fill import SPREAD_MAX

    np.testing.assert_array_equal(res.unreliable, filled & (res.fill_spread > SPREAD_MAX))
    np.testing.assert_array_equal(model.unreliable, model.undetermined)  # no spread: all
    complete = nrsfm.reconstruct(seq.W, 2)
    assert complete.fill_spread is None and not complete.unreliable.any()


def test_unreliable_tracks_warn_once_with_the_runs_other_flags():
    """Tracks lost early whose neighbour fills disagree: one NRSfMWarning that counts them,
    the summary's WARNING line; a run flagged for other reasons too still warns once."""
    seq = data_tools.make_synthetic(F=40, P=20, K=2, seed=3)
    W, _ = data_tools.drop_tracks(seq.W, 0.3, seed=31, pattern="lost")
    with pytest.warns(nrsfm.NRSfMWarning, match="W-fills-unreliable: ") as caught:
        res = nrsfm.reconstruct(W, 2)
    (w,) = caught
    assert ids_in(w.message) == ["W-fills-unreliable"]
    assert res.unreliable.sum() == 4 == res.diagnostics.signals["unreliable_tracks"]
    assert str(w.message) == UNRELIABLE + res.diagnostics.flags[0]
    assert "4 of 20 tracks were seen in too few frames" in str(w.message)
    assert "  WARNING: W-fills-unreliable: tracks seen too rarely: 4 of 20" in res.summary()
    static = data_tools.make_synthetic(F=40, P=20, K=2, seed=3, motion="static")
    W, _ = data_tools.drop_tracks(static.W, 0.3, seed=31, pattern="lost")
    with pytest.warns(nrsfm.NRSfMWarning, match="W-fills-unreliable: ") as caught:
        res = nrsfm.reconstruct(W, 2)
    (w,) = caught
    assert ids_in(w.message)[-2:] == ["W-static-camera", "W-fills-unreliable"]
    assert ids_in(w.message) == [f.split(":")[0] for f in res.diagnostics.flags]


def test_no_warning_where_every_track_is_determined_or_filled_alike():
    """Uniform scattered missing entries (50 %): every track determined, every entry filled,
    no warning. Tracks of a rigid body lost early: undetermined, but their four fills agree,
    so none is unreliable and the run does not warn either."""
    seq = data_tools.make_synthetic(F=60, P=30, K=2, seed=0)
    W, obs = data_tools.drop_tracks(seq.W, 0.5, seed=0)
    assert 0.4 < 1 - obs.mean() < 0.6
    res = nrsfm.reconstruct(W, 2)  # warnings are errors in the tests
    assert not res.undetermined.any() and np.isfinite(res.shapes).all()
    assert res.diagnostics.signals["unreliable_tracks"] == 0 and not res.diagnostics.flags
    assert "WARNING" not in res.summary()
    rigid = data_tools.make_synthetic(F=40, P=20, K=1, seed=0)
    W, _ = data_tools.drop_tracks(rigid.W, 0.3, seed=31, pattern="lost")
    res = nrsfm.reconstruct(W, 1)
    assert res.undetermined.sum() == 2 and not res.unreliable.any()
    assert res.diagnostics.signals["unreliable_tracks"] == 0


# the definition: the per-point loop the batched fill replaced (kept here to test it)


def _ref_kabsch(A, B):
    """(n, 3, 3) rotations (no reflection) with ``R (A - mean A) ~ B - mean B``; A, B (n, 3, k)."""
    A = A - A.mean(axis=2, keepdims=True)
    B = B - B.mean(axis=2, keepdims=True)
    U, _, Vt = np.linalg.svd(B @ A.transpose(0, 2, 1))
    U = U.copy()
    U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]
    return U @ Vt


def _ref_candidates(X, observed, p):
    """p's candidate neighbours ranked by mean distance over the frames both are seen
    (nearest first; only those seen with p in 3 frames or more), from the ``fill._POOL``
    nearest by mean distance over p's sampled frames among the ``fill._POOL + 1``
    points nearest to p in each of them."""
    seen = np.flatnonzero(observed[:, p])
    sample = seen[np.linspace(0, seen.size - 1, min(fill._SAMPLE, seen.size)).astype(int)]
    d = np.linalg.norm(X[sample] - X[sample][:, :, p : p + 1], axis=1)
    near = set()
    for i, f in enumerate(sample):
        ids = np.flatnonzero(observed[f])
        near.update(ids[np.argsort(d[i, ids], kind="stable")[: fill._POOL + 1]].tolist())
    near = np.array(sorted(near - {p}), int)
    both = observed[sample][:, near]
    coarse = np.where(both, d[:, near], 0).sum(0) / np.maximum(both.sum(0), 1)
    coarse[both.sum(0) == 0] = np.inf
    first = np.argsort(coarse, kind="stable")[: fill._POOL]
    pool = near[first[np.isfinite(coarse[first])]]
    both = observed[seen][:, pool]
    d = np.linalg.norm(X[seen][:, :, pool] - X[seen][:, :, p : p + 1], axis=1)
    n = both.sum(0)
    mean = np.where(both, d, 0).sum(0) / np.maximum(n, 1)
    keep = n >= 3
    return pool[keep][np.argsort(mean[keep], kind="stable")]


def _ref_neighbour_sets(observed, frames, ranked, n):
    """[(neighbours, frames)]: in each of ``frames``, the first ``n`` of ``ranked`` seen
    there; frames with fewer than 3 are left out."""
    avail = observed[np.ix_(frames, ranked)]
    sel = avail & (np.cumsum(avail, axis=1) <= n)
    ok = sel.sum(axis=1) >= 3
    if not ok.any():
        return []
    patterns, inverse = np.unique(sel[ok], axis=0, return_inverse=True)
    inverse = np.ravel(inverse)
    return [(ranked[pat], frames[ok][inverse == i]) for i, pat in enumerate(patterns)]


def _ref_nearest_seen(seen, frames):
    """(len(frames),) for each frame, the frame of ``seen`` (sorted) nearest in time."""
    if seen.size == 1:
        return np.full(frames.size, seen[0])
    i = np.clip(np.searchsorted(seen, frames), 1, seen.size - 1)
    return np.where(np.abs(seen[i - 1] - frames) <= np.abs(seen[i] - frames), seen[i - 1], seen[i])


def _ref_rigid(X, observed, p, ranked, unseen):
    """(F, 3) the rigid fill (NaN where not made): from the frame r seen nearest in time,
    the ``fill.RIGID_NEIGHBOURS`` candidates nearest to p in r among those seen in r and f."""
    out = np.full(X[:, :, p].shape, np.nan)
    refs = _ref_nearest_seen(np.flatnonzero(observed[:, p]), unseen)
    for r in np.unique(refs):
        d = np.linalg.norm(X[r][:, ranked] - X[r][:, p : p + 1], axis=0)
        order = ranked[np.argsort(np.where(observed[r, ranked], d, np.inf), kind="stable")]
        order = order[observed[r, order]]
        for nb, frames in _ref_neighbour_sets(
            observed, unseen[refs == r], order, fill.RIGID_NEIGHBOURS
        ):
            A, B = X[r][:, nb], X[frames][:, :, nb]
            R = _ref_kabsch(np.broadcast_to(A, B.shape), B)
            out[frames] = np.einsum("fij,j->fi", R, X[r][:, p] - A.mean(axis=1)) + B.mean(axis=2)
    return out


def _ref_template(X, p, nb, both, frames, iters=3):
    """The point in its neighbours' frame averaged over ``both`` (GPA), carried."""
    A = X[both][:, :, nb]
    a = X[both][:, :, p] - A.mean(axis=2)
    A = A - A.mean(axis=2, keepdims=True)
    Z = A[-1]
    for _ in range(iters):
        R = _ref_kabsch(A, np.broadcast_to(Z, A.shape))
        Z = (R @ A).mean(axis=0)
    z = np.einsum("nij,nj->ni", R, a).mean(axis=0)
    B = X[frames][:, :, nb]
    R = _ref_kabsch(np.broadcast_to(Z, B.shape), B)
    return np.einsum("fij,j->fi", R, z) + B.mean(axis=2)


def _ref_affine(X, p, nb, both, frames):
    """``mean_N + sum_j b_j (x_j - mean_N)``, b fitted (ridge) on ``both``."""
    A = X[both][:, :, nb]
    c = A.mean(axis=2, keepdims=True)
    D = (A - c).reshape(-1, len(nb))
    y = (X[both][:, :, p] - c[:, :, 0]).reshape(-1)
    G = D.T @ D
    b = np.linalg.solve(G + fill.RIDGE * np.trace(G) / len(nb) * np.eye(len(nb)), D.T @ y)
    B = X[frames][:, :, nb]
    c = B.mean(axis=2)
    return c + np.einsum("fik,k->fi", B - c[:, :, None], b)


def _ref_fills(X, observed, p, ranked):
    """(3, F, 3) the rigid, template and affine fills of p (NaN where not made)."""
    unseen = np.flatnonzero(~observed[:, p])
    out = np.full((3,) + X[:, :, p].shape, np.nan)
    out[0] = _ref_rigid(X, observed, p, ranked, unseen)
    for n, k, make in (
        (fill.RIGID_NEIGHBOURS, 1, _ref_template),
        (fill.AFFINE_NEIGHBOURS, 2, _ref_affine),
    ):
        for nb, frames in _ref_neighbour_sets(observed, unseen, ranked, n):
            both = np.flatnonzero(observed[:, p] & observed[:, nb].all(axis=1))
            if both.size >= 2:
                out[k, frames] = make(X, p, nb, both, frames)
    return out


def _ref_fill_unseen(X, observed, points):
    """``fill_unseen`` as a per-point loop (its definition; the
    reliability: the RMS over the unseen frames of the median distance of the four fills
    to their median)."""
    filled, spread = X.copy(), np.full(X.shape[2], np.nan)
    radius = np.sqrt(np.mean(np.sum((X - X.mean(axis=2, keepdims=True)) ** 2, axis=1)))
    todo = ~observed.all(axis=0) & observed.any(axis=0) & points
    for p in np.flatnonzero(todo):
        S = _ref_fills(X, observed, p, _ref_candidates(X, observed, p))
        made = np.isfinite(S).all(axis=(0, 2))
        if not made.any():
            continue
        S, frames = S[:, made], np.flatnonzero(made)
        four = np.concatenate([S, X[frames, :, p][None]])  # (4, frames, 3)
        filled[frames, :, p] = np.median(four, axis=0)
        stray = np.median(np.linalg.norm(four - filled[frames, :, p], axis=2), axis=0)
        spread[p] = np.sqrt(np.mean(stray**2)) / radius
    return filled, spread


def _deforming_parts(seed):
    """Shapes of rigid parts with a smooth deformation, and a mask of lost, late and
    blocked tracks (some seen in 1 - 3 frames only)."""
    rng = np.random.default_rng(seed)
    X = _rigid_parts(F=30, parts=4, size=10, seed=seed)
    t = np.linspace(0, 1, X.shape[0])[:, None, None]
    X = X + 0.3 * np.sin(3 * t + rng.uniform(0, 6, (1, 3, X.shape[2])))
    obs = np.ones((X.shape[0], X.shape[2]), bool)
    for p in rng.choice(X.shape[2], 20, replace=False):
        a, b = np.sort(rng.integers(0, X.shape[0] + 1, 2))
        kind = rng.integers(3)
        obs[:, p] = (
            (np.arange(X.shape[0]) < a)
            if kind == 0
            else (np.arange(X.shape[0]) >= b - 3)
            if kind == 1
            else ~((np.arange(X.shape[0]) >= a) & (np.arange(X.shape[0]) < b))
        )
    obs[:, 0] = np.arange(X.shape[0]) == 4  # seen once
    return X, obs


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_batched_fill_equals_the_per_point_definition(seed):
    X, obs = _deforming_parts(seed)
    points = np.random.default_rng(seed).random(X.shape[2]) < 0.8
    filled, spread = fill_unseen(X, obs, points)
    ref, ref_spread = _ref_fill_unseen(X, obs, points)
    assert np.isfinite(spread).sum() > 10
    np.testing.assert_allclose(filled, ref, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(np.isnan(spread), np.isnan(ref_spread))
    np.testing.assert_allclose(spread, ref_spread, rtol=1e-10)


def test_batched_fill_equals_the_definition_on_a_cloud_whose_neighbours_change():
    # points that wander far relative to their spacing: a point's nearest by mean
    # distance are often not among its 17 nearest in any one frame (the definition of
    # the candidates' pool, which the batched search must follow exactly)
    rng = np.random.default_rng(5)
    F, P = 12, 150
    X = rng.standard_normal((1, 3, P)) + 0.6 * np.cumsum(rng.standard_normal((F, 3, P)), axis=0)
    obs = np.ones((F, P), bool)
    lost = rng.choice(P, 30, replace=False)
    obs[:, lost] = np.arange(F)[:, None] < rng.integers(4, F, lost.size)[None, :]
    filled, spread = fill_unseen(X, obs)
    ref, ref_spread = _ref_fill_unseen(X, obs, np.ones(P, bool))
    assert np.isfinite(spread).sum() == 30
    np.testing.assert_allclose(filled, ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(spread, ref_spread, rtol=1e-10)
