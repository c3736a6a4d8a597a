"""Tests of the shape stage (nrsfm.stages.shape): PSVT, weights, ADMM of Eq. (10)-(13)."""

import warnings

import numpy as np
import pytest

import data_tools
import nrsfm
from nrsfm.metrics import e3d
from nrsfm.stages.shape import (
    PRIORS,
    SOLVERS,
    BilinearSettings,
    ShapeResult,
    phi,
    phi_inv,
    pseudo_inverse_shapes,
    truncate_rank,
)
from nrsfm.stages.shape.bilinear import solve_bilinear
from nrsfm.stages.shape.admm import (
    AdmmSettings,
    admm_iterations,
    normalization_scale,
    psvt,
    shape_weights,
)


def optimize_shapes(W, R, K, prior="organic", progress=None, **options):
    """The ADMM's iterations on W as given (no normalisation), options as keywords."""
    return admm_iterations(W, R, K, prior, AdmmSettings(**options), progress)


def optimize_shapes_bilinear(W, R, K, prior="organic", **options):
    return solve_bilinear(W, R, K, prior, BilinearSettings(**options))


@pytest.fixture(scope="module")
def seq():
    return data_tools.make_synthetic(F=60, P=20, K=3, motion="random", seed=1)


def _partial_objective(P, Q, N, tau):
    s = np.linalg.svd(P, compute_uv=False)
    return float(np.sum(tau[N:] * s[N:]) + 0.5 * np.sum((P - Q) ** 2))


# ------------------------------------------------------------------ PSVT
@pytest.mark.parametrize("N", [0, 1, 2])
def test_psvt_is_the_proximal_point(N):
    """P_{N,tau}[Q] beats random perturbations and a local optimiser on a tiny matrix."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(N)
    Q = rng.standard_normal((5, 4))
    s = np.linalg.svd(Q, compute_uv=False)
    tau = np.full(4, 0.6 * s[N])  # thresholds some, keeps others
    P = psvt(Q, N, tau)
    best = _partial_objective(P, Q, N, tau)
    for _ in range(300):
        E = rng.standard_normal(Q.shape) * rng.choice([1e-3, 1e-2, 1e-1])
        assert _partial_objective(P + E, Q, N, tau) >= best - 1e-12
    for start in (Q, np.zeros_like(Q), rng.standard_normal(Q.shape)):
        res = minimize(
            lambda p: _partial_objective(p.reshape(Q.shape), Q, N, tau),
            start.ravel(),
            method="Powell",
            options=dict(xtol=1e-9, ftol=1e-12, maxfev=8000),
        )
        assert res.fun >= best - 1e-7


def test_psvt_keeps_leading_and_soft_thresholds_rest():
    rng = np.random.default_rng(0)
    U, _ = np.linalg.qr(rng.standard_normal((6, 4)))
    V, _ = np.linalg.qr(rng.standard_normal((4, 4)))
    sig = np.array([5.0, 3.0, 1.0, 0.2])
    Q = (U * sig) @ V.T
    P, s_new = psvt(Q, 1, 0.5, return_singular_values=True)
    np.testing.assert_allclose(s_new, [5.0, 2.5, 0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(P, (U * [5.0, 2.5, 0.5, 0.0]) @ V.T, atol=1e-12)
    # per-singular-value tau; N = 0 is plain (weighted) singular value thresholding
    _, s0 = psvt(Q, 0, [1.0, 1.0, 0.5, 0.5], return_singular_values=True)
    np.testing.assert_allclose(s0, [4.0, 2.0, 0.5, 0.0], atol=1e-12)
    # tau = 0 and N >= rank give Q back
    np.testing.assert_allclose(psvt(Q, 0, 0.0), Q, atol=1e-12)
    np.testing.assert_allclose(psvt(Q, 4, 10.0), Q, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(Q=np.ones(3), N=1, tau=0.1),
        dict(Q=np.ones((3, 3)), N=-1, tau=0.1),
        dict(Q=np.ones((3, 3)), N=1.5, tau=0.1),
        dict(Q=np.ones((3, 3)), N=1, tau=-0.1),
        dict(Q=np.ones((3, 3)), N=1, tau=[0.1, 0.2]),
        dict(Q=np.full((3, 3), np.nan), N=1, tau=0.1),
    ],
)
def test_psvt_bad_input(kwargs):
    with pytest.raises(ValueError):
        psvt(**kwargs)


def test_shape_weights_eq9():
    sigma = np.array([4.0, 1.0, 0.25, 0.0])
    theta = shape_weights(sigma)
    xi = 5e-3 * 2.0
    np.testing.assert_allclose(theta, xi / (sigma + 1e-6))
    assert np.all(np.diff(theta) > 0)  # smaller sigma, larger weight
    np.testing.assert_allclose(shape_weights(sigma, xi=1.0, gamma=0.5), 1.0 / (sigma + 0.5))
    for bad in (
        dict(sigma=[]),
        dict(sigma=[1.0, -1.0]),
        dict(sigma=[1.0], gamma=0.0),
        dict(sigma=[0.0, 0.0]),
        dict(sigma=[1.0], xi=-1.0),
    ):
        with pytest.raises(ValueError):
            shape_weights(**bad)


# ------------------------------------------------------------------ ADMM
def test_admm_converges_and_recovers_low_rank_shape(seq):
    W = seq.W / normalization_scale(seq.W)
    res = optimize_shapes(W, seq.rotations, seq.K)
    assert isinstance(res, ShapeResult)
    assert res.converged and res.history["residual"][-1] < res.params["eps"]
    assert res.prior == "organic" and res.N == 1
    assert e3d(res.X_init, seq.shapes) > 0.3  # the planar start is poor
    assert e3d(res.shapes, seq.shapes) < 1e-3  # the low-rank shape is recovered
    # the final shape reproduces the measurements
    proj = (seq.rotations[:, :2] @ res.shapes).reshape(W.shape)
    assert np.abs(proj - W).max() < 1e-3 * np.abs(W).max()


def test_x_step_matches_general_solve(seq):
    """One iteration of the closed form equals (R'R + rho I)^-1 (R'W + rho Z) per frame."""
    W = seq.W / normalization_scale(seq.W)
    res = optimize_shapes(W, seq.rotations, seq.K, max_iter=1)
    F, P = seq.shapes.shape[0], seq.shapes.shape[2]
    R = seq.rotations[:, :2]
    rho = 1e-4
    Z = truncate_rank(res.X_init, seq.K)  # X# = P_K[X_init], Y = 0 at the start
    A = R.transpose(0, 2, 1) @ R + rho * np.eye(3)
    X = np.linalg.solve(A, R.transpose(0, 2, 1) @ W.reshape(F, 2, P) + rho * Z)
    data = 0.5 * np.sum((W.reshape(F, 2, P) - R @ X) ** 2)
    np.testing.assert_allclose(res.history["data_term"][0], data, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("prior", sorted(PRIORS))
def test_three_priors_run(seq, prior):
    W = seq.W / normalization_scale(seq.W)
    res = optimize_shapes(W, seq.rotations, seq.K, prior=prior)
    assert res.prior == prior and res.N == PRIORS[prior]
    assert res.shapes.shape == seq.shapes.shape
    assert np.all(np.isfinite(res.shapes))
    assert e3d(res.shapes, seq.shapes) < e3d(res.X_init, seq.shapes)
    if prior == "nuclear":
        assert np.all(res.theta == res.theta[0])
    else:
        np.testing.assert_allclose(
            res.theta,
            shape_weights(res.X_init_singular_values, res.params["xi"], res.params["gamma"]),
        )


def test_history_and_params(seq):
    msgs = []
    res = optimize_shapes(seq.W, seq.rotations, seq.K, progress=msgs.append)
    lengths = {k: len(v) for k, v in res.history.items()}
    assert set(lengths) == {"cost", "data_term", "residual", "rho"}
    assert set(lengths.values()) == {res.n_iter}
    assert np.all(res.history["cost"] >= res.history["data_term"] - 1e-12)
    assert np.all(np.diff(res.history["rho"]) > 0)
    for key in ("mu", "rho0", "lam", "rho_max", "eps", "xi", "gamma", "N", "K", "max_iter"):
        assert key in res.params
    assert msgs and "stopped" in msgs[-1]


def test_partial_sum_leaves_leading_values(seq):
    """N larger than the rank leaves everything unpenalised: X = X# is a data fit."""
    W = seq.W / normalization_scale(seq.W)
    res = optimize_shapes(W, seq.rotations, seq.K, N=3 * seq.W.shape[1])
    assert res.history["cost"][-1] == pytest.approx(res.history["data_term"][-1])
    assert res.history["data_term"][-1] < 1e-8 * 0.5 * np.sum(W**2)
    sv = np.linalg.svd(phi(res.shapes), compute_uv=False)
    assert sv[seq.K] > 1e-3 * sv[0]  # not of rank K: nothing penalised


def test_max_iter_and_rho_max_stop(seq):
    res = optimize_shapes(seq.W, seq.rotations, seq.K, max_iter=5)
    assert res.n_iter == 5 and not res.converged
    res = optimize_shapes(seq.W, seq.rotations, seq.K, rho0=1.0, rho_max=2.0, eps=0.0)
    assert res.history["rho"][-1] <= 2.0 and not res.converged


def test_scale_invariance_through_reconstruct(seq):
    out, shapes = [], []
    for c in (1e-3, 1.0, 1e3):
        rec = nrsfm.reconstruct(seq.W * c, seq.K, rotations=seq.rotations)
        out.append(e3d(rec.shapes, seq.shapes))
        shapes.append(rec.shapes / c)
    assert max(out) - min(out) < 1e-6
    for X in shapes[1:]:
        np.testing.assert_allclose(X, shapes[0], atol=1e-6 * np.abs(shapes[0]).max())


def test_existing_helpers(seq):
    X = seq.shapes
    np.testing.assert_array_equal(phi_inv(phi(X), X.shape[2]), X)
    Xi = pseudo_inverse_shapes(seq.W, seq.rotations)
    res = optimize_shapes(seq.W, seq.rotations, seq.K, max_iter=1)
    np.testing.assert_allclose(res.X_init, Xi, atol=1e-12)
    assert np.linalg.matrix_rank(phi(truncate_rank(Xi, 2))) == 2


@pytest.mark.parametrize(
    "change",
    [
        dict(W=np.ones((5, 10))),  # odd number of rows
        dict(W=np.full((6, 10), np.nan)),
        dict(R=np.ones((3, 3, 3))),  # not orthonormal
        dict(R=np.broadcast_to(np.eye(3), (4, 3, 3))),  # wrong frame count
        dict(R=np.ones((3, 4, 3))),
        dict(K=0),
        dict(prior="bogus"),
        dict(N=-1),
        dict(mu=-1.0),
        dict(lam=1.0),
        dict(rho0=0.0),
        dict(max_iter=0),
        dict(gamma=0.0),
        dict(xi=-1.0),
    ],
)
def test_optimize_shapes_bad_input(change):
    rng = np.random.default_rng(0)
    args = dict(W=rng.standard_normal((6, 10)), R=np.broadcast_to(np.eye(3), (3, 3, 3)), K=1)
    args.update(change)
    W, R, K = args.pop("W"), args.pop("R"), args.pop("K")
    with pytest.raises(ValueError):
        optimize_shapes(W, R, K, **args)


# ------------------------------------------------------------------ bilinear solver, closed form
from nrsfm.noise import noise_level  # noqa: E402
from nrsfm.stages.shape.bilinear import bilinear_weights  # noqa: E402
from nrsfm.stages.shape.factors import objective as _objective  # noqa: E402
from nrsfm.stages.shape.closed_form import closed_form_coefficients  # noqa: E402
from nrsfm.stages.shape.closed_form import closed_form_shapes  # noqa: E402


@pytest.mark.parametrize("K", range(1, 9))
@pytest.mark.parametrize("motion", ["smooth", "fast", "random"])
def test_exact_on_noise_free_rank_k(K, motion):
    """Noise-free, exactly rank K, ground-truth rotations, scales 1e-3 / 1 / 1e3: the
    bilinear solver (via reconstruct) and the closed form recover the shape (e3d <= 1e-4)."""
    seq = data_tools.make_synthetic(F=50, P=3 * K + 2, K=K, motion=motion, seed=20 + K)
    for c in (1e-3, 1.0, 1e3):
        rec = nrsfm.reconstruct(c * seq.W, K, rotations=seq.rotations, shape_solver="bilinear")
        assert e3d(rec.shapes, seq.shapes) <= 1e-4
        assert rec.shape_stage.converged
        assert e3d(closed_form_shapes(c * seq.W, seq.rotations, K), seq.shapes) <= 1e-4


def test_closed_form_nullspace_has_dimension_k():
    seq = data_tools.make_synthetic(F=50, P=20, K=3, motion="smooth", seed=2)
    B, ev = closed_form_coefficients(seq.W, seq.rotations, 3)
    assert B.shape == (50, 3)
    assert np.all(ev[:3] < 1e-12) and ev[3] > 1e-6  # K zero eigenvalues, then a gap
    # B spans the true coefficients' column space
    Bt = seq.extra["coefficients"]
    Q, _ = np.linalg.qr(B)
    assert np.linalg.norm(Bt - Q @ (Q.T @ Bt)) < 1e-8 * np.linalg.norm(Bt)


@pytest.mark.parametrize("r", [2, 3])  # 3P = 21: factored form (r = 2), X# formed (3)
def test_bilinear_gradient_matches_finite_differences(r):
    rng = np.random.default_rng(0)
    seq = data_tools.make_synthetic(F=8, P=7, K=2, motion="random", seed=4)
    F, P = 8, 7
    Rf = seq.rotations[:, :2]
    Pi = Rf.transpose(0, 2, 1) @ Rf
    Xi = (Rf.transpose(0, 2, 1) @ seq.W.reshape(F, 2, P)).reshape(F, 3 * P)
    w2 = float(np.sum(seq.W**2))
    reg = np.array([0.0, 0.3, 0.7])[:r]
    B, C = rng.standard_normal((F, r)), rng.standard_normal((3 * P, r))
    E, data, gB, gC = _objective(B, C, Pi, Xi, w2, reg)
    X = (B @ C.T).reshape(F, 3, P)
    assert data == pytest.approx(0.5 * np.sum((seq.W.reshape(F, 2, P) - Rf @ X) ** 2))
    h = 1e-6
    for M, g in ((B, gB), (C, gC)):
        for idx in [(0, 0), (3, 1), (M.shape[0] - 1, 1)]:
            Mp, Mm = M.copy(), M.copy()
            Mp[idx] += h
            Mm[idx] -= h
            args = (Mp, C) if M is B else (B, Mp)
            argm = (Mm, C) if M is B else (B, Mm)
            fd = (_objective(*args, Pi, Xi, w2, reg)[0] - _objective(*argm, Pi, Xi, w2, reg)[0]) / (
                2 * h
            )
            assert fd == pytest.approx(g[idx], rel=1e-5, abs=1e-6)


def test_bilinear_noisy_stationary_scale_free_and_wnn_identity():
    seq = data_tools.make_synthetic(F=50, P=20, K=3, motion="smooth", noise=0.05, seed=3)
    res = optimize_shapes_bilinear(seq.W, seq.rotations, 3)
    assert res.converged and res.grad_norm <= 1e-8  # BilinearSettings().gtol
    assert res.mu > 0 and res.noise > 0
    # at a balanced stationary point the factored regulariser is the weighted nuclear norm
    assert res.objective == pytest.approx(res.wnn_objective, rel=1e-5)
    assert e3d(res.shapes, seq.shapes) < 0.5 * e3d(res.X_init, seq.shapes)
    big = optimize_shapes_bilinear(1e3 * seq.W, seq.rotations, 3)
    assert big.mu == pytest.approx(1e3 * res.mu, rel=1e-10)
    np.testing.assert_allclose(big.shapes / 1e3, res.shapes, atol=1e-4 * np.abs(res.shapes).max())


def test_bilinear_rank_from_W_and_the_prior():
    """rank=None: K where W is itself of rank <= 3K (a rank-K shape under noise), else the
    prior's rank: from 3K, a column added while the rank certificate wants one (a rank-6
    shape solved at K = 1)."""
    from nrsfm.stages.shape.bilinear import CERTIFICATE_SLACK, prior_rank

    low = data_tools.make_synthetic(F=60, P=20, K=2, motion="random", seed=3)
    W = data_tools.add_noise(low.W, 0.05, seed=0)
    res = optimize_shapes_bilinear(W, low.rotations, 2)
    assert res.params["rank_rule"] == "W of rank <= 3K" and res.params["ranks"] == [2]
    high = data_tools.make_synthetic(F=60, P=20, K=6, motion="random", seed=3)
    res = optimize_shapes_bilinear(high.W, high.rotations, 1)  # the prior keeps rank 3
    assert res.params["rank_rule"] == "prior" and res.params["ranks"] == [3]
    assert res.params["rank_certificate"] <= 1 + CERTIFICATE_SLACK
    six = optimize_shapes_bilinear(high.W, high.rotations, 1, rank=6)
    np.testing.assert_allclose(six.shapes, res.shapes, atol=1e-6 * np.abs(res.shapes).max())
    light = optimize_shapes_bilinear(
        high.W,
        high.rotations,
        1,  # it wants rank 6
        mu=1e-6 * np.linalg.norm(high.W),
    )
    assert light.params["ranks"] == [3, 6] and light.params["live_rank"] == 6
    # the history holds both fits: each one's start and its iterations
    assert len(light.history["cost"]) == light.n_iter + len(light.params["ranks"])
    assert light.params["rank_certificate"] <= 1 + CERTIFICATE_SLACK
    assert e3d(light.shapes, high.shapes) < 1e-4
    given = optimize_shapes_bilinear(high.W, high.rotations, 1, rank=3)
    assert given.params["rank_rule"] == "given" and given.params["ranks"] == [3]
    # the rule itself: numerical rank below 3K, a gap at 3K, or neither
    assert prior_rank(np.r_[1.0, 0.5, 1e-12, 1e-13], 1, 10, 10) == (1, "W of rank <= 3K")
    assert prior_rank(np.r_[1.0, 0.9, 0.8, 0.1], 1, 10, 10) == (1, "W of rank <= 3K")
    assert prior_rank(np.r_[1.0, 0.9, 0.8, 0.7], 1, 10, 10) == (3, "prior")


def test_bilinear_weight_follows_the_square_of_the_noise():
    """mu = max(mu_factor noise (sqrt(F) + sqrt(3P)), mu_noise noise^2 (F + 2P) / sigma_1):
    the clean-data term on nearly clean W, the noise term (the shrinkage form) once that is
    larger; the ratio of the two is free of W's units."""
    seq = data_tools.make_synthetic(F=50, P=20, K=3, motion="smooth", seed=3)
    F, P = 50, 20
    ratios = []
    for sigma in (0.005, 0.1):
        W = data_tools.add_noise(seq.W, sigma, seed=1)
        for scale in (1.0, 1e3):
            res = optimize_shapes_bilinear(scale * W, seq.rotations, 3)
            flat = optimize_shapes_bilinear(scale * W, seq.rotations, 3, mu_noise=0.0)
            shrink = 5.0 * res.noise**2 * (F + 2 * P) / res.X_init_singular_values[0]
            clean = 0.01 * res.noise * (np.sqrt(F) + np.sqrt(3 * P))
            assert flat.mu == pytest.approx(clean, rel=1e-9)
            assert res.mu == pytest.approx(max(clean, shrink), rel=1e-9)
            ratios.append(res.mu / flat.mu)
    assert ratios[0] == pytest.approx(1.0) and ratios[1] == pytest.approx(ratios[0])
    assert ratios[2] > 2 and ratios[3] == pytest.approx(ratios[2], rel=1e-9)


def test_noise_level_from_W_alone():
    clean = data_tools.make_synthetic(F=60, P=30, K=2, seed=5)
    assert noise_level(clean.W, 2) < 1e-12 * np.sqrt(np.mean(clean.W**2))
    rng = np.random.default_rng(0)
    noisy = clean.W + 0.01 * rng.standard_normal(clean.W.shape)
    assert 0.007 < noise_level(noisy, 2) < 0.0105


def test_bilinear_weights():
    sigma = np.array([4.0, 2.0, 1.0, 0.5])
    np.testing.assert_allclose(bilinear_weights(sigma, 3, "organic"), [0.0, 2.0, 4.0])
    np.testing.assert_allclose(bilinear_weights(sigma, 3, "weighted"), [1.0, 2.0, 4.0])
    np.testing.assert_allclose(bilinear_weights(sigma, 3, "nuclear"), [1.0, 1.0, 1.0])
    with pytest.raises(ValueError):
        bilinear_weights(sigma, 3, "bogus")


@pytest.mark.parametrize("method", ["organic", "wnn", "bmm"])
@pytest.mark.parametrize("solver", list(SOLVERS))
def test_every_prior_with_every_solver(seq, method, solver):
    rec = nrsfm.reconstruct(
        seq.W, seq.K, method=method, rotations=seq.rotations, shape_solver=solver
    )
    assert rec.settings.shape_solver == solver == rec.shape_stage.solver
    assert e3d(rec.shapes, seq.shapes) < 1e-3  # noise-free random-motion data
    assert rec.shapes.shape == seq.shapes.shape


def test_solver_dispatch_and_bad_input(seq):
    with pytest.raises(ValueError, match="shape_solver"):
        nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations, shape_solver="bogus")
    for bad in (
        dict(prior="bogus"),
        dict(rank=0),
        dict(mu_factor=-1.0),
        dict(gtol=-1.0),
        dict(max_iter=-1),
        dict(mu=-1.0),
    ):
        with pytest.raises(ValueError):
            optimize_shapes_bilinear(seq.W, seq.rotations, seq.K, **bad)
    with pytest.raises(ValueError):
        optimize_shapes_bilinear(seq.W, seq.rotations, 7)  # 3K > P
    with pytest.raises(ValueError):
        closed_form_shapes(seq.W[:-1], seq.rotations, seq.K)


def test_rank_k_fit_of_rank_deficient_W_is_unique_and_exact():
    """Rank-1 data fitted with K = 2 (W of rank 3 < 3K): the closed form works in W's
    rank-3 column space, where the fit is unique (before, the 3K-dimensional space held
    three empty directions, so rounding chose the start), and the answer is exact."""
    seq = data_tools.make_synthetic(F=40, P=12, K=1, motion="smooth", seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = optimize_shapes_bilinear(seq.W, seq.rotations, 2)
    assert res.params["nullspace_gap"] > 1e-6
    assert e3d(res.shapes, seq.shapes) < 1e-10


def test_a_fit_whose_infimum_W_does_not_attain_stops_when_E_stalls():
    """Random W of rank 5 with K = 6: the rotations do not explain W, and the organic
    prior's free first column grows while E creeps down at its rounding level. The solver
    stops at the first segment that does not lower E (it ran its 3,000-iteration cap
    before), and stopping there is repeatable."""
    rng = np.random.default_rng(1)
    W = rng.standard_normal((66, 5)) @ rng.standard_normal((5, 55))
    runs = []
    for _ in range(2):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # W-rank-deficient: the input is what it is
            runs.append(nrsfm.reconstruct(W, 6))
    shape = runs[0].shape_stage
    assert 0 < shape.n_iter < 1000 and not shape.converged
    np.testing.assert_array_equal(runs[0].shapes, runs[1].shapes)


def test_c_step_is_the_minimiser_and_the_frame_factors_invert():
    """The C step (from viewing directions and X_init#, without the 2F x 3r matrix) zeroes
    dE/dC; the per-frame factors satisfy L L' = H and L^-1 L = I, by LAPACK's batch and by
    the floored loop (a singular H_f), which agree where both apply."""
    from nrsfm.stages.shape import factors

    rng = np.random.default_rng(3)
    seq = data_tools.make_synthetic(F=9, P=6, K=2, motion="random", seed=2)
    F, P, r = 9, 6, 4
    Rf = seq.rotations[:, :2]
    Pi = Rf.transpose(0, 2, 1) @ Rf
    Xi = (Rf.transpose(0, 2, 1) @ seq.W.reshape(F, 2, P)).reshape(F, 3 * P)
    reg = np.array([0.0, 0.2, 0.5, 0.9])
    B = rng.standard_normal((F, r))
    C = factors.c_step(B, Rf, seq.W, reg)
    gC = factors.objective(B, C, Pi, Xi, float(np.sum(seq.W**2)), reg)[3]
    assert np.linalg.norm(gC) < 1e-12 * np.linalg.norm(C)
    A = (B[:, None, :, None] * Rf[:, :, None, :]).reshape(2 * F, 3 * r)  # rows B_f kron R_f
    c_ref = np.linalg.solve(A.T @ A + np.diag(np.repeat(reg, 3)), A.T @ seq.W)
    assert np.allclose(C, c_ref.reshape(r, 3 * P).T, rtol=1e-10, atol=1e-12)
    H = factors.frame_hessians(C, Pi, reg)
    L, Linv = factors.frame_preconditioner(C, Pi, reg)
    assert np.allclose(L @ L.transpose(0, 2, 1), H, rtol=1e-10, atol=1e-12)
    assert np.allclose(Linv @ L, np.eye(r), atol=1e-10)
    assert np.allclose(factors._cholesky(H), L, atol=1e-10)  # L: H plus its 1e-12 jitter
    H[0] = np.outer(H[0, 0], H[0, 0])  # rank one: LAPACK fails, the loop floors
    L2 = factors._factor(H)
    assert np.all(np.isfinite(L2)) and np.allclose(L2[1:], L[1:], atol=1e-10)


@pytest.mark.parametrize("P, r", [(6, 4), (40, 2)])  # X# formed; factored (3P > 9r)
def test_reduced_objective_is_the_objective_at_the_c_step(P, r):
    """``reduced_objective`` (the C step, then E and dE/dB alone) gives the
    values of :func:`objective` at the C step's C, in both of its branches, and the
    blocked triangular inverse (r > 8) inverts."""
    from nrsfm.stages.shape import factors

    rng = np.random.default_rng(5)
    F = 9
    seq = data_tools.make_synthetic(F=F, P=P, K=2, motion="random", seed=4)
    Rf = seq.rotations[:, :2]
    Pi = Rf.transpose(0, 2, 1) @ Rf
    Xi = (Rf.transpose(0, 2, 1) @ seq.W.reshape(F, 2, P)).reshape(F, 3 * P)
    w2 = float(np.sum(seq.W**2))
    reg = np.linspace(0.0, 0.9, r) * w2**0.5
    B = rng.standard_normal((F, r))
    C, (E, data, gB, gC) = factors.reduced_objective(
        B, factors.viewing_directions(Rf), Pi, Xi, w2, reg
    )
    assert np.allclose(C, factors.c_step(B, Rf, seq.W, reg), rtol=1e-12, atol=1e-14)
    E_ref, data_ref, gB_ref, _ = factors.objective(B, C, Pi, Xi, w2, reg)
    assert E == pytest.approx(E_ref, rel=1e-12) and data == pytest.approx(data_ref, rel=1e-12)
    assert np.allclose(gB, gB_ref, rtol=1e-10, atol=1e-12 * np.abs(gB_ref).max())
    assert gC == 0.0
    L = np.linalg.cholesky(
        np.eye(13) + (lambda A: A @ A.transpose(0, 2, 1))(rng.standard_normal((5, 13, 13)))
    )
    assert np.allclose(factors._lower_inverse(L) @ L, np.eye(13), atol=1e-10)


def test_alignment_change_of_basis_and_the_minimiser():
    """``factors._aligned`` returns the SVD-aligned factors of the same X# with the change
    of basis that maps the old factors onto them (``B M``) and its inverse transpose (the
    map of gradients); and minimise's L-BFGS reaches the same minimiser with its memory
    carried through the alignments as with scipy's L-BFGS-B on the same reduced objective."""
    import scipy.optimize
    from nrsfm.stages.shape import factors

    rng = np.random.default_rng(11)
    B, C = rng.standard_normal((12, 4)), rng.standard_normal((15, 4))
    Ba, keep, M, Mt = factors._aligned(B, C, None)
    Bs, Cs = factors.svd_align(B, C)
    assert keep == 4 and np.allclose(Ba, Bs, atol=1e-12)
    assert np.allclose(B @ M, Ba, atol=1e-12) and np.allclose(M.T @ Mt, np.eye(4), atol=1e-12)
    seq = data_tools.make_synthetic(F=12, P=8, K=2, motion="random", seed=3)
    Rf = seq.rotations[:, :2]
    Pi = Rf.transpose(0, 2, 1) @ Rf
    n = factors.viewing_directions(Rf)
    Xi = (Rf.transpose(0, 2, 1) @ seq.W.reshape(12, 2, 8)).reshape(12, 24)
    w2 = float(np.sum(seq.W**2))
    reg = np.array([0.0, 0.3, 0.6, 1.0]) * w2**0.5 * 0.05

    def reduced(Bx):
        return factors.reduced_objective(Bx, n, Pi, Xi, w2, reg)

    from types import SimpleNamespace

    problem = SimpleNamespace(
        reduced=reduced, Pi=Pi, reg=reg, gtol=1e-10, max_iter=5000, record=lambda *a: None
    )
    B1, C1, rel, it = factors.minimise(rng.standard_normal((12, 4)), problem)
    assert rel <= 1e-10
    E1 = reduced(B1)[1][0]
    ref = scipy.optimize.minimize(
        lambda z: (lambda v: (v[0], v[2].ravel()))(reduced(z.reshape(12, 4))[1]),
        B1.ravel() + 1e-3 * rng.standard_normal(48),
        jac=True,
        method="L-BFGS-B",
        options=dict(gtol=1e-12, ftol=0, maxiter=5000),
    )
    assert E1 <= ref.fun * (1 + 1e-10)


def test_lbfgs_memory_survives_factors_collapsing_to_zero():
    """With a weight large enough that the answer is X# = 0 the factors shrink towards 0
    and the differences of gradients underflow (pickup under noise with the nuclear prior
    at mu 186 raised ZeroDivisionError): a pair whose y has underflowed is not kept."""
    from nrsfm.stages.shape.factors import _add_pair

    s, y = np.ones((4, 1)), np.full((4, 1), 1e-320)  # s'y > 0, ||y|| underflows to 0
    S, Y = [], []
    _add_pair(S, Y, s, y)
    assert S == [] and Y == []
    _add_pair(S, Y, s, 1e-3 * s)
    assert len(S) == 1


@pytest.mark.parametrize("seed", [0, 3, 7])
def test_no_numpy_warning_escapes_when_the_factors_collapse(seed):
    """Random W (no shape model) with the weighted prior: the factors shrink towards 0 and
    L-BFGS's pairs underflow; the run ends finite and warns only through NRSfMWarning."""
    W = np.random.default_rng(seed).standard_normal((102, 16))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = nrsfm.reconstruct(W, 3, method="wnn")
    assert np.isfinite(res.shapes).all()
    assert all(issubclass(w.category, nrsfm.NRSfMWarning) for w in caught), [
        str(w.message)[:60] for w in caught
    ]
