"""The fill of the points not seen from their neighbours (nrsfm.stages.fill, issue 24)."""

import numpy as np
import pytest

import data_tools
import nrsfm
from nrsfm.settings import Settings
from nrsfm.stages.completion import MeasurementSettings
from nrsfm.stages.fill import fill_unseen
from nrsfm.geometry import project_to_so3


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
    obs[12:, 3] = False                     # lost to the end
    obs[:9, 10] = False                     # late start
    obs[5:20, 17] = False                   # a block
    model = X.copy()
    model[~np.broadcast_to(obs[:, None, :], X.shape)] = 0.0      # a wrong model fill
    filled, spread = fill_unseen(model, obs)
    # rigid and template fills are exact; the median is off by the affine ridge's bias
    err = np.linalg.norm(filled - X, axis=1)
    assert err.max() < 1e-2                 # bodies 20 apart, of radius ~1.7
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
    res = nrsfm.reconstruct(W, 2, settings=Settings(
        measurement=MeasurementSettings(fill="neighbours")))
    model = nrsfm.reconstruct(W, 2)                 # the default: the shape stage's fill
    assert model.fill_spread is None and "fill" in res.timings
    seen = np.broadcast_to(obs[:, None, :], res.shapes.shape)
    np.testing.assert_array_equal(res.shapes[seen], model.shapes[seen])
    assert not np.allclose(res.shapes[~seen], model.shapes[~seen])
    filled = res.undetermined                       # the points the data leave undetermined
    assert filled.any()
    assert np.isfinite(res.fill_spread[filled]).all()
    assert np.isnan(res.fill_spread[~filled]).all()
    kept = np.broadcast_to(~filled[None, None, :], res.shapes.shape)
    np.testing.assert_array_equal(res.shapes[kept], model.shapes[kept])
    complete = nrsfm.reconstruct(seq.W, 2, settings=Settings(
        measurement=MeasurementSettings(fill="neighbours")))
    assert complete.fill_spread is None
