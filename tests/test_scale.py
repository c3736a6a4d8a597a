"""Tests of the ADMM's scale rule (nrsfm.stages.shape.admm) and the scale invariance."""

import numpy as np
import pytest

import data_tools
import nrsfm
from nrsfm.stages.shape.admm import TARGET_FROBENIUS, normalization_scale


def test_normalised_frobenius_norm():
    W = data_tools.make_synthetic(F=30, P=15, K=2, seed=3).W
    s = normalization_scale(W)
    assert s > 0
    assert np.linalg.norm(W / s) == pytest.approx(TARGET_FROBENIUS)


@pytest.mark.parametrize("c", [1e-6, 1e-3, 7.5, 1e4, -2.0])
def test_homogeneous_of_degree_one(c):
    W = data_tools.make_synthetic(F=30, P=15, K=2, seed=4).W
    assert normalization_scale(c * W) == pytest.approx(abs(c) * normalization_scale(W), rel=1e-12)


def test_uses_W_alone_and_is_independent_of_layout():
    """Only the entries matter: permuting frames or points does not change the scale."""
    rng = np.random.default_rng(0)
    W = data_tools.make_synthetic(F=30, P=15, K=2, seed=5).W
    perm_pts = rng.permutation(W.shape[1])
    assert normalization_scale(W[:, perm_pts]) == pytest.approx(normalization_scale(W))


@pytest.mark.parametrize("solver", ["bilinear", "admm"])
def test_reconstruct_is_scale_invariant(solver):
    seq = data_tools.make_synthetic(F=40, P=16, K=2, motion="random", seed=6)
    recs = [
        nrsfm.reconstruct(seq.W * c, seq.K, rotations=seq.rotations, shape_solver=solver)
        for c in (1e-3, 1.0, 1e3)
    ]
    e = [nrsfm.e3d(r.shapes, seq.shapes) for r in recs]
    assert max(e) - min(e) < 1e-6
    for r, c in zip(recs, (1e-3, 1.0, 1e3)):
        assert r.scale == pytest.approx(c * recs[1].scale)
        np.testing.assert_allclose(
            r.shapes / c, recs[1].shapes, atol=1e-6 * np.abs(recs[1].shapes).max()
        )


@pytest.mark.parametrize("W", [np.zeros((4, 5)), np.ones(6), np.full((4, 5), np.inf)])
def test_bad_input(W):
    with pytest.raises(ValueError):
        normalization_scale(W)
