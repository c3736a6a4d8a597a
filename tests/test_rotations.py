"""Rotation stage: lifting, registration, filtering, L1 averaging, estimate_rotations."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

import data_tools
from nrsfm import rotation_error
from nrsfm.stages.measurement import factorize
from nrsfm import geometry as GEO
from nrsfm.settings import RotationSettings
from nrsfm.stages import rotations as RT

FLIP = np.diag([-1.0, -1.0, 1.0])
MIRROR = np.diag([1.0, 1.0, -1.0])


@pytest.fixture(autouse=True)
def _one_thread():
    with threadpool_limits(limits=1):
        yield


def _seq(K, motion, noise=0.0, seed=0, F=40):
    seq = data_tools.make_synthetic(F=F, P=3 * K + 15, K=K, motion=motion, noise=noise, seed=seed)
    return seq, factorize(seq.W, K).M_hat


@pytest.mark.parametrize("motion", ["smooth", "fast"])
@pytest.mark.parametrize("K", [1, 2, 3, 4])
def test_noise_free_rotations_exact(K, motion):
    seq, M = _seq(K, motion, seed=K)
    for single in (False, True):  # organic, bmm
        res = RT.estimate_rotations(M, K, single=single, seed=0)
        assert res.rotations.shape == (40, 3, 3)
        assert res.n_triplets == (1 if single else K)
        assert np.allclose(np.linalg.det(res.rotations), 1.0)
        assert rotation_error(res.rotations, seq.rotations) < 1e-6, single


def test_random_motion_exact_up_to_depth_reversal():
    seq, M = _seq(2, "random", seed=11)
    res = RT.estimate_rotations(M, 2, seed=0)
    R, Rgt = res.rotations, seq.rotations
    # one global orthogonal alignment from the third rows (unchanged by a depth reversal)
    U, _, Vt = np.linalg.svd(np.einsum("fi,fj->ij", R[:, 2], Rgt[:, 2]))
    Q = U @ Vt
    A = R[:, :2] @ Q
    err = np.minimum(
        np.linalg.norm(Rgt[:, :2] - A, axis=(1, 2)), np.linalg.norm(Rgt[:, :2] + A, axis=(1, 2))
    )
    assert err.max() < 1e-6
    assert res.sign_from_smoothness.dtype == bool
    assert res.sign_from_smoothness.any()
    # with the reversal undone per frame, the sequence is exact
    sign = np.where(
        np.linalg.norm(Rgt[:, :2] - A, axis=(1, 2)) < np.linalg.norm(Rgt[:, :2] + A, axis=(1, 2)),
        1.0,
        -1.0,
    )
    Rfix = np.where(sign[:, None, None] > 0, R, FLIP @ R)
    assert rotation_error(Rfix, Rgt) < 1e-6


def test_closed_form_lift_and_log_match_the_svd_and_scipy():
    rng = np.random.default_rng(4)
    u = rng.standard_normal((2, 200, 3))
    u /= np.linalg.norm(u, axis=2, keepdims=True)
    L = np.stack([u[0], u[1], np.cross(u[0], u[1])], axis=1)
    np.testing.assert_allclose(
        RT.lifting._nearest_rotation(u[0], u[1]), GEO.project_to_so3(L), atol=1e-12
    )
    for angle in (1e-9, 1e-3, 1.0, 3.0, np.pi - 1e-6):
        v = rng.standard_normal((50, 3))
        v *= angle / np.linalg.norm(v, axis=1, keepdims=True)
        R = Rotation.from_rotvec(v).as_matrix()
        np.testing.assert_allclose(GEO._log_so3(R), Rotation.from_matrix(R).as_rotvec(), atol=1e-9)


def test_batched_projection_to_so3_matches_the_svd_on_hard_cases():
    rng = np.random.default_rng(4)
    n = 3000
    rot = Rotation.random(n, random_state=2).as_matrix()
    cases = {
        "random": rng.standard_normal((n, 3, 3)),
        "near rotations": rot + 0.01 * rng.standard_normal((n, 3, 3)),
        "reflections": rot @ np.diag([1.0, 1.0, -1.0]) + 0.3 * rng.standard_normal((n, 3, 3)),
        "units": rng.standard_normal((n, 3, 3)) * 10.0 ** rng.uniform(-200, 200, (n, 1, 1)),
        "rank 2": rng.standard_normal((n, 3, 2)) @ rng.standard_normal((n, 2, 3)),
        "equal singular values": rot * np.array([1.0, -1.0, 1.0])[:, None],
    }
    cases["mixed"] = np.concatenate([c[:200] for c in cases.values()] + [np.zeros((2, 3, 3))])
    for name, A in cases.items():
        R = GEO.project_to_so3_batch(A)
        assert np.isfinite(R).all(), name
        np.testing.assert_allclose(
            R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-13, err_msg=name
        )
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-13, err_msg=name)
        # the SO(3) Procrustes objective trace(R' A) is the SVD's (the maximiser is unique
        # except on "equal singular values", where the objective still is)
        best = GEO.project_to_so3(A)
        np.testing.assert_allclose(
            np.einsum("nij,nij->n", R, A),
            np.einsum("nij,nij->n", best, A),
            rtol=1e-12,
            atol=1e-300,
            err_msg=name,
        )
        if name not in ("equal singular values", "mixed"):
            np.testing.assert_allclose(R, best, atol=1e-12, err_msg=name)
    # one answer per matrix, whatever else is in the batch
    A = np.concatenate(list(cases.values()))
    parts = np.concatenate(
        [GEO.project_to_so3_batch(A[i : i + 777]) for i in range(0, len(A), 777)]
    )
    assert np.array_equal(GEO.project_to_so3_batch(A), parts)


def test_l1_average_robust_to_outliers():
    rng = np.random.default_rng(0)
    F, m = 30, 9
    truth = Rotation.random(F, random_state=1)
    noise = Rotation.from_rotvec(0.01 * rng.standard_normal((m, F, 3)).reshape(-1, 3))
    samples = (noise * Rotation.concatenate([truth] * m)).as_matrix().reshape(m, F, 3, 3)
    samples[:3] = Rotation.random(3 * F, random_state=2).as_matrix().reshape(3, F, 3, 3)
    l1 = GEO.average_rotations(samples)
    l2 = GEO.project_to_so3(samples.mean(axis=0))  # the chordal L2 mean
    e1 = GEO.rotation_angle(l1, truth.as_matrix())
    e2 = GEO.rotation_angle(l2, truth.as_matrix())
    assert e1.mean() < 0.02
    assert e1.mean() < 0.2 * e2.mean()


def test_average_weighted_mask_and_empty_frames():
    R = Rotation.random(4, random_state=3).as_matrix()
    samples = np.stack([R, R])
    mask = np.ones((2, 4), bool)
    mask[:, 2] = False
    out, info = GEO.average_rotations(samples, mask, return_info=True)
    assert np.all(np.isfinite(out))
    assert info["empty"].tolist() == [False, False, True, False]
    np.testing.assert_allclose(out[[0, 1, 3]], R[[0, 1, 3]], atol=1e-12)


@pytest.mark.parametrize("mirrored", [False, True])
def test_registration_recovers_global_rotation(mirrored):
    rng = np.random.default_rng(4)
    F = 50
    R_ref = data_tools.camera_rotations(F, "smooth", rng)
    Rg = Rotation.random(random_state=5).as_matrix()
    flips = rng.random(F) < 0.3
    R_k = R_ref @ Rg
    R_k = np.where(flips[:, None, None], FLIP @ R_k, R_k)
    if mirrored:  # the lift of the mirrored 2 x 3 blocks
        R_k = MIRROR @ R_k @ MIRROR
    reg, R_reg, got_flips, got_mirror, cost = RT.register_rotations(R_ref, R_k)
    np.testing.assert_allclose(reg, R_ref, atol=1e-10)
    # The mirrored lift equals the unmirrored one with every frame reversed and another
    # R_reg (diag(-1,-1,1) diag(1,1,-1) = -I), so the flips come out complemented.
    np.testing.assert_array_equal(got_flips, flips ^ (mirrored and not got_mirror))
    # plain SO(3) registration (Eq. 4 without flips) cannot do this
    plain = GEO.procrustes_so3(np.einsum("fki,fkj->ij", R_k, R_ref).T)
    assert np.linalg.norm(R_k @ plain.T - R_ref, axis=(1, 2)).mean() > 0.1
    assert cost < 1e-18
    assert np.isclose(np.linalg.det(R_reg), 1.0)


def test_filter_by_geodesic_angle():
    R = Rotation.random(5, random_state=6).as_matrix()
    reg = np.stack(
        [
            R,
            Rotation.from_rotvec([0, 0, 0.04]).as_matrix() @ R,
            Rotation.from_rotvec([0, 0.06, 0]).as_matrix() @ R,
        ]
    )
    kept, d = RT.filter_rotations(reg, R, 0.05)
    np.testing.assert_allclose(d[1:], [[0.04] * 5, [0.06] * 5], atol=1e-12)
    assert kept[:2].all() and not kept[2].any()


def test_no_nan_when_a_coefficient_is_zero():
    seq, M = _seq(2, "smooth", noise=0.01, seed=7)
    M = M.copy()
    M[10:12] = 0.0  # frame 5: M_f G = 0 for every triplet
    G = np.random.default_rng(0).standard_normal((3, 6, 3))
    G[1] = 0.0
    R, coef, valid = RT.rotations_from_triplets(M, G)
    assert np.all(np.isfinite(R))
    assert not valid[:, 5].any() and not valid[1].any()
    assert np.all(coef[:, 5] == 0)
    for single in (False, True):
        res = RT.estimate_rotations(M, 2, single=single, seed=0)
        assert np.all(np.isfinite(res.rotations))
        assert np.allclose(np.linalg.det(res.rotations), 1.0)


def test_deterministic_under_seed_and_result_fields():
    seq, M = _seq(3, "smooth", noise=0.03, seed=9)
    a = RT.estimate_rotations(M, 3, seed=2)
    b = RT.estimate_rotations(M, 3, seed=2)
    np.testing.assert_array_equal(a.rotations, b.rotations)
    F = 40
    assert a.G.shape == (3, 9, 3)
    assert a.per_triplet.shape == (3, F, 3, 3) and a.registered.shape == (3, F, 3, 3)
    assert a.coefficients.shape == (3, F) and a.kept.shape == (3, F)
    assert a.registration.shape == (3, 3, 3)
    np.testing.assert_array_equal(a.registration[0], np.eye(3))
    assert a.averaged.shape == (F, 3, 3) and a.sign_from_smoothness.shape == (F,)
    assert a.triplet_costs.shape == (3,) and a.window_spans.shape == (2, 2)
    assert a.search.costs[0] == pytest.approx(a.triplet_costs[0])
    assert a.determined_rank == 9 and a.effective_K == 3
    assert {"registration", "filtering", "averaging"} <= set(a.timings)
    assert rotation_error(a.rotations, seq.rotations) < 0.2  # 3% noise, K = 3: loose


def test_settings_validation_names_the_value():
    with pytest.raises(ValueError, match="delta"):
        RotationSettings(delta=-1)
    with pytest.raises(ValueError, match="max_starts"):
        RotationSettings(max_starts=0)
    with pytest.raises(ValueError, match="RotationSettings"):
        RT.estimate_rotations(_seq(1, "smooth")[1], 1, settings=dict(delta=0.1))


def test_batched_projection_near_ambiguous_reflections_to_the_conditioning():
    # reflections whose two least singular values nearly cancel (0.5 and -0.5 (1 - delta)):
    # the rotation is determined to about eps / delta, by the SVD as by the closed form; the
    # closed form alone (no fallback below its gap threshold) misses this from delta ~ 1e-6
    rng = np.random.default_rng(8)
    n = 4000
    delta = 10.0 ** rng.uniform(-6.5, -1, n)
    U = Rotation.random(n, random_state=4).as_matrix()
    V = Rotation.random(n, random_state=5).as_matrix()
    s = np.stack([np.ones(n), np.full(n, 0.5), -0.5 * (1.0 - delta)], axis=1)
    A = np.einsum("nij,nj,njk->nik", U, s, V)
    for R in (GEO.project_to_so3_batch(A), GEO.project_to_so3(A)):
        err = np.abs(R - U @ V).max(axis=(1, 2))
        assert np.all(err <= 5e-14 / delta), (err * delta).max()


def test_batched_projection_without_iterations_falls_back_to_the_svd():
    # with max_iter = 0 no root I1 has converged: every matrix goes to the SVD
    A = np.random.default_rng(6).standard_normal((50, 3, 3))
    np.testing.assert_allclose(
        GEO.project_to_so3_batch(A, max_iter=0), GEO.project_to_so3(A), atol=1e-13
    )
