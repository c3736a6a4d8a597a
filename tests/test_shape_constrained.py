"""Tests of nrsfm/stages/shape/constrained.py and constrained_polish.py."""

import numpy as np
import pytest

import data_tools
from nrsfm.metrics import e3d
from nrsfm.stages.shape import constrained as of
from nrsfm.stages.shape import fit_set
from nrsfm.stages.shape.constrained import ConstrainedSettings


def organic_fit_shapes(W, R, K, **options):
    return of.organic_fit(W, R, K, ConstrainedSettings(**options))


def _rank_deficient(F=40, P=16, seed=0):
    """Rigid body plus a planar deformation: rank(W) = 5 (true K = 2)."""
    seq = data_tools.make_rank_deficient(F, P, seed=seed)
    return seq.W, seq.rotations, seq.shapes


@pytest.mark.parametrize("K", [1, 2, 3, 5, 8])
@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_exact_on_noise_free_rank_k(K, scale):
    seq = data_tools.make_synthetic(F=40, P=3 * K + 2, K=K, motion="random", seed=K)
    res = organic_fit_shapes(scale * seq.W, seq.rotations, K)
    assert e3d(res.shapes, seq.shapes) < 1e-8
    assert res.residual <= res.eps * (1 + 1e-9) + 1e-12 * scale


@pytest.mark.parametrize("K", [2, 3])
@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_exact_on_rank_deficient_shapes(K, scale):
    """W of rank 5 < 3K: the answer is the shape (the closed form, which works in W's
    rank-5 column space, is exact here too)."""
    W, R, gt = _rank_deficient()
    res = organic_fit_shapes(scale * W, R, K)
    assert res.chosen in ("admm", "closed_form", "kkt")
    assert e3d(res.shapes, gt) < 1e-6


def test_noisy_scale_free_feasible_and_deterministic():
    seq = data_tools.make_synthetic(F=50, P=20, K=3, motion="smooth", noise=0.02, seed=4)
    a = organic_fit_shapes(seq.W, seq.rotations, 3)
    b = organic_fit_shapes(1e3 * seq.W, seq.rotations, 3)
    c = organic_fit_shapes(seq.W, seq.rotations, 3)
    np.testing.assert_allclose(b.shapes, 1e3 * a.shapes, rtol=0, atol=1e-6 * np.abs(b.shapes).max())
    np.testing.assert_array_equal(a.shapes, c.shapes)
    assert a.eps == pytest.approx(of.residual_bound(seq.W, 3))
    assert a.residual <= a.eps * (1 + 1e-9)
    assert a.converged and a.optimality < 1e-8
    assert a.objective == pytest.approx(of.organic_objective(a.shapes, a.weights))
    assert e3d(a.shapes, seq.shapes) < 0.05
    assert len(a.history["objective"]) == a.n_iter
    # the answer is the polished KKT point, certified to the stated tolerances
    assert a.chosen == "kkt" and a.certified
    assert a.kkt["grad_norm"] <= 1e-8 and a.kkt["residual_gap"] <= 1e-5
    assert a.kkt["rank"] >= 9 and a.kkt["mu"] > 0
    assert b.kkt["mu"] == pytest.approx(1e3 * a.kkt["mu"], rel=1e-4)
    assert a.objective <= a.candidate_objectives["admm"] * (1 + 1e-9)


def test_kkt_point_does_not_depend_on_rounding():
    """1e-7 relative perturbations of W move the certified answer by O(1e-7) (measured
    3.7e-8), and every answer is certified."""
    seq = data_tools.make_synthetic(F=60, P=25, K=3, motion="random", noise=0.03, seed=7)
    rms = np.sqrt(np.mean(seq.W ** 2))
    ref = organic_fit_shapes(seq.W, seq.rotations, 3)
    for d in (1, 2):
        W = seq.W + 1e-7 * rms * np.random.default_rng(d).standard_normal(seq.W.shape)
        res = organic_fit_shapes(W, seq.rotations, 3)
        assert res.certified
        assert np.linalg.norm(res.shapes - ref.shapes) < 1e-4 * np.linalg.norm(ref.shapes)


def test_residual_bound_estimates_the_noise_norm():
    rng = np.random.default_rng(0)
    F, P, K = 100, 30, 2
    L = rng.standard_normal((2 * F, 3 * K)) @ rng.standard_normal((3 * K, P))
    E = 0.01 * rng.standard_normal((2 * F, P))
    assert of.residual_bound(L + E, K) == pytest.approx(np.linalg.norm(E), rel=0.05)
    assert of.residual_bound(L, K) < 1e-12 * np.linalg.norm(L)
    U, s, Vt = np.linalg.svd(L + E, full_matrices=False)
    tail = np.linalg.norm(s[3 * K:])
    assert of.residual_bound(L + E, K) == pytest.approx(
        tail * np.sqrt(2 * F * P / ((2 * F - 3 * K) * (P - 3 * K))))


def test_projection_onto_the_fit_set():
    seq = data_tools.make_synthetic(F=10, P=8, K=1, seed=2)
    rng = np.random.default_rng(1)
    X = rng.standard_normal((10, 3, 8))
    Rf = seq.rotations[:, :2]
    for eps in (0.0, 0.5, 1e3):
        Y = fit_set.project_to_fit(X, seq.W, seq.rotations, eps)
        res = np.linalg.norm(Rf @ Y - seq.W.reshape(10, 2, 8))
        assert res <= eps + 1e-12
        n = np.cross(Rf[:, 0], Rf[:, 1])
        # depth (along n_f) unchanged, and idempotent
        np.testing.assert_allclose(np.einsum("fc,fcp->fp", n, Y), np.einsum("fc,fcp->fp", n, X),
                                   atol=1e-12)
        np.testing.assert_allclose(fit_set.project_to_fit(Y, seq.W, seq.rotations, eps), Y, atol=1e-12)
    np.testing.assert_allclose(fit_set.project_to_fit(X, seq.W, seq.rotations, 1e3), X)


def test_exact_fit_shapes_fit_W():
    seq = data_tools.make_synthetic(F=12, P=9, K=2, seed=3)
    Z = np.random.default_rng(0).standard_normal((12, 9))
    X = fit_set.exact_fit_shapes(seq.W, seq.rotations, Z)
    np.testing.assert_allclose((seq.rotations[:, :2] @ X).reshape(seq.W.shape), seq.W,
                               atol=1e-12)


def test_weighted_svt_is_the_prox_for_nondecreasing_thresholds():
    rng = np.random.default_rng(0)
    for shape in ((9, 5), (5, 9)):
        M = rng.standard_normal(shape)
        t = np.array([0.0, 0.3, 0.5, 0.9, 2.0])
        Y, s = fit_set.weighted_svt(M, t)
        U, sv, Vt = np.linalg.svd(M, full_matrices=False)
        np.testing.assert_allclose(Y, (U * np.maximum(sv - t, 0)) @ Vt, atol=1e-10)
        np.testing.assert_allclose(s, np.maximum(sv - t, 0), atol=1e-10)


def test_organic_weights():
    a = of.organic_weights(np.array([4.0, 2.0, 1.0, 0.0]))
    np.testing.assert_allclose(a[:3], [0.0, 2.0, 4.0])
    assert a[3] == pytest.approx(1e12)
    assert np.all(np.diff(a) >= 0)


@pytest.mark.parametrize("change, match", [
    (dict(W=np.zeros((7, 5))), "2F, P"),
    (dict(R=np.zeros((3, 3, 3))), "R has 3 frames"),
    (dict(K=0), "K must be"),
    (dict(K=4), "K=4 is too large"),
    (dict(lam=1.0), "lam"),
    (dict(rho0=-1.0), "rho0"),
])
def test_bad_input(change, match):
    seq = data_tools.make_synthetic(F=10, P=10, K=1, seed=0)
    args = dict(W=seq.W, R=seq.rotations, K=1)
    kw = {k: change.pop(k) for k in list(change) if k not in args}
    args.update(change)
    with pytest.raises(ValueError, match=match):
        organic_fit_shapes(args["W"], args["R"], args["K"], **kw)


def test_non_orthonormal_cameras_rejected():
    seq = data_tools.make_synthetic(F=10, P=10, K=1, seed=0)
    with pytest.raises(ValueError, match="orthonormal"):
        organic_fit_shapes(seq.W, 2 * seq.rotations, 1)
    with pytest.raises(ValueError, match="zero"):
        organic_fit_shapes(0 * seq.W, seq.rotations, 1)


def test_through_reconstruct_with_given_rotations():
    """The registered solver: ``reconstruct(shape_solver="constrained")`` recovers a
    noise-free rank-K shape from the true cameras, in the input's units."""
    import nrsfm

    seq = data_tools.make_synthetic(F=30, P=12, K=2, motion="random", seed=3)
    rec = nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations,
                            shape_solver="constrained")
    assert rec.params["shape_solver"] == "constrained"
    assert rec.shapes.shape == seq.shapes.shape
    assert e3d(rec.shapes, seq.shapes) < 1e-6
    stage = rec.shape_stage                              # in the working units of W
    assert stage.solver == "constrained" and stage.prior == "organic"
    assert stage.params["residual"] <= stage.params["eps"] * (1 + 1e-9) + 1e-12
    assert stage.history["cost"].size == stage.n_iter


def test_settings_validated():
    from nrsfm.stages.shape import solver_settings

    assert solver_settings("constrained", dict(lam=1.2)).lam == 1.2
    for bad in (dict(lam=1.0), dict(rho0=0.0), dict(tol=-1.0), dict(max_iter=0),
                dict(eps=-1.0), dict(polish=1), dict(rank=0), dict(gtol=float("nan"))):
        with pytest.raises(ValueError):
            ConstrainedSettings(**bad)
    with pytest.raises(ValueError, match="unknown options"):
        solver_settings("constrained", dict(mu=1.0))


def test_pipeline_selects_rotations_by_the_constrained_objective():
    """Without given rotations the pipeline compares the candidates' weighted norms of (C)
    (``wnn_objective``), and keeps the lower."""
    import nrsfm

    seq = data_tools.make_synthetic(F=30, P=12, K=1, motion="smooth", seed=5)
    rec = nrsfm.reconstruct(seq.W, seq.K, shape_solver="constrained")
    sel = rec.rotation_stage.info["shape_selection"]
    assert all(v is not None for v in sel["objectives"])
    assert min(sel["objectives"]) == pytest.approx(rec.shape_stage.wnn_objective)
    assert rec.shape_stage.wnn_objective == rec.shape_stage.objective
