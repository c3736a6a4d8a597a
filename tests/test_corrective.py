"""Corrective triplets (Dai's constraints, relaxation, refinement) on small synthetic data."""

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import data_tools
from nrsfm.stages import corrective as C
from nrsfm.stages import relaxation as RX
from nrsfm.stages.measurement import factorize


@pytest.fixture(autouse=True)
def _one_thread():
    with threadpool_limits(limits=1):
        yield


def _M(K, motion="smooth", noise=0.0, seed=0, F=50, P=30):
    seq = data_tools.make_synthetic(F=F, P=P, K=K, motion=motion, noise=noise, seed=seed)
    return factorize(seq.W, K).M_hat, seq


def test_constraint_matrix_matches_definition():
    rng = np.random.default_rng(0)
    K, F = 2, 7
    M = rng.standard_normal((2 * F, 3 * K))
    Q = rng.standard_normal((3 * K, 3 * K))
    Q = Q + Q.T
    A = RX.constraint_matrix(M)
    got = A @ Q[RX.vech_index(3 * K)]
    m1, m2 = M[0::2], M[1::2]
    want = np.empty(2 * F)
    want[0::2] = np.einsum("fi,ij,fj->f", m1, Q, m1) - np.einsum("fi,ij,fj->f", m2, Q, m2)
    want[1::2] = np.einsum("fi,ij,fj->f", m1, Q, m2)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(1)
    M, _ = _M(2, noise=0.02)
    G = rng.standard_normal((6, 3))
    w = rng.uniform(0.5, 1.5, M.shape[0] // 2)
    r, J = C.triplet_residuals(G, M, w, jac=True)
    h = 1e-6
    Jn = np.empty_like(J)
    for i in range(G.size):
        d = np.zeros(G.size)
        d[i] = h
        Jn[:, i] = (
            C.triplet_residuals(G + d.reshape(G.shape), M, w)
            - C.triplet_residuals(G - d.reshape(G.shape), M, w)
        ) / (2 * h)
    np.testing.assert_allclose(J, Jn, rtol=1e-5, atol=1e-6)
    assert C.triplet_cost(G, M, w) == pytest.approx(float(r @ r))
    frames = C._Frames(M, w)
    np.testing.assert_allclose(
        frames.gradient(frames.products(G)).ravel(),
        J.T @ r,
        rtol=1e-12,
        atol=1e-12 * np.abs(J.T @ r).max(),
    )


def test_reused_jacobian_gram_reaches_the_same_minimum():
    M, _ = _M(2, noise=0.02)
    G0 = np.random.default_rng(3).standard_normal((6, 3))
    G, _, _ = C.refine_triplet(G0, M, tol=1e-14, max_iter=2000)
    Gr, _, _ = C.refine_triplet(
        G, M + 1e-3 * M[::-1], tol=1e-14, max_iter=2000, lam0=1e-6, reuse=1e-3
    )
    Gf, _, _ = C.refine_triplet(G, M + 1e-3 * M[::-1], tol=1e-14, max_iter=2000, lam0=1e-6)
    Q = C.triplet_cost(Gr, M + 1e-3 * M[::-1]), C.triplet_cost(Gf, M + 1e-3 * M[::-1])
    assert Q[0] == pytest.approx(Q[1], rel=1e-10)


@pytest.mark.parametrize("K", [1, 2, 4])
def test_search_exact_noise_free(K):
    M, _ = _M(K, F=40, P=3 * K + 12)
    res = C.search_triplet(M, K, seed=0)
    assert res.G.shape[1:] == (3 * K, 3)
    assert res.costs[0] < 1e-16
    assert np.all(np.diff(res.costs) >= 0)


def test_search_deterministic():
    M, _ = _M(3, noise=0.02, seed=5)
    a = C.search_triplet(M, 3, seed=4)
    b = C.search_triplet(M, 3, seed=4)
    np.testing.assert_array_equal(a.G, b.G)
    np.testing.assert_array_equal(a.costs, b.costs)


def test_penalized_gram_is_psd_normalised_and_converged():
    M, _ = _M(3, noise=0.01, seed=2)
    Qa = RX.penalized_gram(M, 3, tol=1e-9)
    Qb = RX.penalized_gram(M, 3, tol=1e-11, max_iter=20000)
    assert np.linalg.eigvalsh(Qa).min() > -1e-9
    F = M.shape[0] // 2
    assert np.trace(M.T @ M @ Qa) == pytest.approx(2 * F, rel=1e-6)
    np.testing.assert_allclose(Qa, Qb, atol=1e-6 * np.abs(Qb).max())


def test_the_relaxation_starts_an_exact_triplet_noise_free():
    M, _ = _M(2, F=40, P=21, seed=6)
    G0 = RX.triplets_from_gram(RX.penalized_gram(M, 2))
    assert G0.shape == (6, 3)
    assert C.refine_triplet(G0, M)[1] < 1e-16


def test_search_stops_after_two_hits_of_the_best_minimum():
    M, _ = _M(3, noise=0.02, seed=7)
    res = C.search_triplet(M, 3, seed=0)
    assert res.stopped == "hits" and res.hits >= 2
    assert res.n_starts == len(res.history) <= 40
    assert np.all(np.diff(res.costs) >= 0)
    assert res.costs[0] <= min(c for _, c, _ in res.history) * (1 + 1e-5)


def test_search_from_random_starts_only_finds_the_relaxations_minimum():
    """The stopping rule, fed only seeded random starts, confirms the same minimum."""
    M, _ = _M(2, noise=0.03, seed=8)
    relaxed = C.search_triplet(M, 2, seed=0)
    res = C.search_triplet(M, 2, seed=3, lams=())
    assert res.n_random == res.n_starts >= 2
    assert res.miss_bound == pytest.approx(min(1.0, 3.0 / res.n_random))
    assert res.costs[0] == pytest.approx(relaxed.costs[0], rel=1e-4)


def test_search_is_deterministic_and_bounded():
    M, _ = _M(2, noise=0.05, seed=9)
    a = C.search_triplet(M, 2, seed=5, hits=50, max_starts=6)
    b = C.search_triplet(M, 2, seed=5, hits=50, max_starts=6)
    assert a.stopped == "max_starts" and a.n_starts == 6
    np.testing.assert_array_equal(a.G, b.G)
    assert a.history == b.history
