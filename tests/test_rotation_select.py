"""W of numerical rank below 3K: rotations from the determined subspace."""

import warnings

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import data_tools
import nrsfm
from nrsfm.metrics import e3d, rotation_error
from nrsfm.stages.rotations.subspace import determined_subspace, effective_K, lift_triplets


@pytest.fixture(autouse=True)
def _one_thread():
    with threadpool_limits(limits=1):
        yield


def _rigid_plus_planar(F=60, P=24, seed=0):
    """Rigid body plus one planar deformation mode (z = 0): W of rank 5."""
    seq = data_tools.make_synthetic(F=F, P=P, K=2, seed=seed)
    B = seq.extra["basis"].copy()
    B[1, 2] = 0.0
    cam = seq.rotations @ np.einsum("fk,kip->fip", seq.extra["coefficients"], B)
    return cam[:, :2].reshape(2 * F, P), cam, seq.rotations


def _run(W, K):
    """reconstruct(W, K) of a W of rank below 3K; its NRSfMWarnings. Nothing else may warn
    (the shape stage's closed form works in W's column space, where the rank-K fit is
    unique)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = nrsfm.reconstruct(W, K)
    flags = [w for w in caught if issubclass(w.category, nrsfm.NRSfMWarning)]
    other = [(w.category, str(w.message)[:40]) for w in caught if w not in flags]
    assert not other, other
    return res, flags


def test_subspace_reproduces_the_motion_factor():
    rng = np.random.default_rng(0)
    M = np.hstack([rng.standard_normal((40, 5)), np.zeros((40, 4))])
    M[:, 5:] = 1e-12 * rng.standard_normal((40, 4))  # rounding-level columns
    sub = determined_subspace(M)
    assert sub.rank == 5 and sub.deficient and sub.M.shape == (40, 5)
    G_r = rng.standard_normal((5, 3))
    np.testing.assert_allclose(M @ lift_triplets(G_r, sub), sub.M @ G_r, atol=1e-10)
    assert effective_K(5, 3) == 1 and effective_K(6, 4) == 2 and effective_K(9, 3) == 3


def test_subspace_is_gauge_and_unit_invariant():
    rng = np.random.default_rng(1)
    M = rng.standard_normal((30, 6)) @ np.diag([5, 3, 2, 1, 0.5, 0.0])
    a, b = determined_subspace(M), determined_subspace(M * 3.0)
    np.testing.assert_allclose(b.M, 3.0 * a.M, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(b.V, a.V, atol=1e-12)


@pytest.mark.parametrize("K", [2, 3])
@pytest.mark.parametrize("units", [0.7, 3.0])
def test_rigid_plus_planar_exact_in_any_units(K, units):
    W, cam, R = _rigid_plus_planar()
    res, caught = _run(W * units, K)
    assert rotation_error(res.rotations, R) <= 1e-5
    assert e3d(res.shapes, cam) <= 1e-3
    d = res.diagnostics
    assert d.signals["numerical_rank"] == 5 and not caught
    assert any(n.startswith("N-rank-deficient-subspace: W has only 5 ") for n in d.notes)
    assert "  notes (no action needed): N-rank-deficient-subspace\n" in res.summary()


@pytest.mark.parametrize("K_true,extra", [(1, 2), (2, 2), (3, 1)])
def test_K_above_the_true_K_is_exact(K_true, extra):
    seq = data_tools.make_synthetic(F=50, P=30, K=K_true, seed=K_true)
    res, caught = _run(seq.W * 0.7, K_true + extra)
    assert rotation_error(res.rotations, seq.rotations) <= 1e-5
    assert e3d(res.shapes, seq.shapes) <= 1e-3
    assert res.rotation_stage.determined_rank == 3 * K_true
    assert not caught


def test_lower_minimum_separates_a_failed_search_from_an_inexact_model():
    from nrsfm.stages.corrective import triplet_cost
    from nrsfm.stages.measurement import factorize
    from nrsfm.stages.rotations.subspace import lower_minimum
    from nrsfm.stages.rotations import estimate_rotations

    seq = data_tools.make_synthetic(F=60, P=30, K=2, noise=0.02, seed=5)
    f = factorize(seq.W, 2)
    best = estimate_rotations(f.M_hat, 2, single=True).search.costs[0]
    assert not lower_minimum(f.M_hat, 2, best)[0]
    bad = triplet_cost(np.random.default_rng(0).standard_normal((6, 3)), f.M_hat)
    lower, other = lower_minimum(f.M_hat, 2, bad)
    assert lower and other < bad


def test_shape_for_the_stage_rotations_in_one_solve(monkeypatch):
    """One shape solve, for the rotation stage's rotations; the diagnostics read the depth
    amplification of that answer (no second solve)."""
    from nrsfm.stages.shape import bilinear

    seq = data_tools.make_synthetic(F=60, P=30, K=2, noise=0.02, seed=3)
    calls = []
    solve = bilinear.solve_bilinear
    monkeypatch.setattr(
        bilinear, "solve_bilinear", lambda *a, **k: calls.append(1) or solve(*a, **k)
    )
    res = nrsfm.reconstruct(seq.W, 2)
    assert len(calls) == 1
    np.testing.assert_allclose(res.rotations, res.rotation_stage.rotations)
    given = nrsfm.reconstruct(seq.W, 2, rotations=res.rotations)  # one answer for R
    np.testing.assert_allclose(given.shapes, res.shapes, atol=1e-9 * np.abs(res.shapes).max())
    amp = res.diagnostics.signals["depth_amplification"]
    assert amp == given.diagnostics.signals["depth_amplification"]
    assert 0.9 < amp < 2.0


def test_rank_below_three_is_refused_naming_the_rank_and_what_to_try():
    """A rigid planar object (W of rank 2): no camera is determined by the images; the error
    says so, and the same W with the rotations given reconstructs it."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    X = np.vstack([rng.standard_normal((2, 25)), np.zeros((1, 25))])
    R = Rotation.from_rotvec(np.linspace(0, 1, 30)[:, None] * [0.3, 1, 0.2]).as_matrix()
    W = (R[:, :2] @ X).reshape(60, 25)
    with pytest.raises(ValueError, match=r"^W has numerical rank 2 < 3: .* rotations=R"):
        nrsfm.reconstruct(W, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", nrsfm.NRSfMWarning)  # rank 2 < 3K: flagged, as it is
        res = nrsfm.reconstruct(W, 1, rotations=R)
    assert res.reprojection_error() < 1e-6 * np.abs(W).max()
