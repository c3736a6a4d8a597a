"""Corrective triplets (Dai's constraints, relaxation, refinement) on small synthetic data."""

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import data_tools
from nrsfm.research import triplets as AB
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
    np.testing.assert_allclose(RX.gram_from_vech(Q[RX.vech_index(3 * K)], 3 * K), Q)


@pytest.mark.parametrize("K", [1, 2, 3])
def test_solution_space_dimension_noise_free(K):
    M, _ = _M(K)
    A = RX.constraint_matrix(M)
    basis, sv = AB.solution_space(A, K)
    d = 2 * K * K - K
    assert basis.shape == (3 * K * (3 * K + 1) // 2, d)
    np.testing.assert_allclose(basis.T @ basis, np.eye(d), atol=1e-10)
    # A clear gap: the basis is (numerically) in the null space of A.
    assert np.linalg.norm(A @ basis) < 1e-5 * np.linalg.norm(A)
    assert sv[-d - 1] > 1e3 * sv[-d]


def test_relaxed_gram_admm_matches_cvxpy():
    M, _ = _M(2, noise=0.01)
    basis, _ = AB.solution_space(RX.constraint_matrix(M), 2)
    Qa = AB.relaxed_gram(basis, 2, solver="admm", tol=1e-8)
    Qc = AB.relaxed_gram(basis, 2, solver="cvxpy")
    nuc = lambda Q: np.abs(np.linalg.eigvalsh(Q)).sum()
    assert abs(nuc(Qa) - nuc(Qc)) < 1e-4 * nuc(Qc)


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
        Jn[:, i] = (C.triplet_residuals(G + d.reshape(G.shape), M, w)
                    - C.triplet_residuals(G - d.reshape(G.shape), M, w)) / (2 * h)
    np.testing.assert_allclose(J, Jn, rtol=1e-5, atol=1e-6)
    assert C.triplet_cost(G, M, w) == pytest.approx(float(r @ r))
    np.testing.assert_allclose(C.triplet_gradient(G, M, w).ravel(), J.T @ r,
                               rtol=1e-12, atol=1e-12 * np.abs(J.T @ r).max())


def test_reused_jacobian_gram_reaches_the_same_minimum():
    M, _ = _M(2, noise=0.02)
    G0 = np.random.default_rng(3).standard_normal((6, 3))
    G, _ = C.refine_triplet(G0, M, tol=1e-14, max_iter=2000)
    Gr, info = C.refine_triplet(G, M + 1e-3 * M[::-1], tol=1e-14, max_iter=2000, lam0=1e-6,
                                reuse=1e-3)
    Gf, _ = C.refine_triplet(G, M + 1e-3 * M[::-1], tol=1e-14, max_iter=2000, lam0=1e-6)
    Q = C.triplet_cost(Gr, M + 1e-3 * M[::-1]), C.triplet_cost(Gf, M + 1e-3 * M[::-1])
    assert Q[0] == pytest.approx(Q[1], rel=1e-10)


@pytest.mark.parametrize("K", [1, 2, 4])
def test_corrective_triplets_exact_noise_free(K):
    M, _ = _M(K, F=40, P=3 * K + 12)
    res = C.corrective_triplets(M, K, seed=0)
    assert res.G.shape[1:] == (3 * K, 3)
    assert res.costs[0] < 1e-16
    assert np.all(np.diff(res.costs) >= 0)


def test_lm_and_lbfgs_reach_same_minimum_from_the_same_start():
    M, _ = _M(2, noise=0.01, seed=3)
    G0 = C.corrective_triplets(M, 2, seed=0).G[0] + 0.01
    G1, i1 = C.refine_triplet(G0, M, method="lm")
    G2, i2 = C.refine_triplet(G0, M, method="lbfgs")
    assert i1["cost"] <= i2["cost"] * (1 + 1e-6) + 1e-12


def test_corrective_triplets_deterministic():
    M, _ = _M(3, noise=0.02, seed=5)
    a = C.corrective_triplets(M, 3, seed=4)
    b = C.corrective_triplets(M, 3, seed=4)
    np.testing.assert_array_equal(a.G, b.G)
    np.testing.assert_array_equal(a.costs, b.costs)


def test_penalized_gram_admm_matches_cvxpy_and_is_psd():
    M, _ = _M(3, noise=0.01, seed=2)
    Qa = RX.penalized_gram(M, 3, solver="admm", tol=1e-9)
    Qc = RX.penalized_gram(M, 3, solver="cvxpy")
    assert np.linalg.eigvalsh(Qa).min() > -1e-9
    F = M.shape[0] // 2
    assert np.trace(M.T @ M @ Qa) == pytest.approx(2 * F, rel=1e-6)
    np.testing.assert_allclose(Qa, Qc, atol=2e-3 * np.abs(Qc).max())


@pytest.mark.parametrize("starts", ["relaxed", "multistart", "columns"])
def test_all_starts_reach_an_exact_triplet_noise_free(starts):
    M, _ = _M(2, F=40, P=21, seed=6)
    res = AB.corrective_triplets_from(M, 2, starts=starts, seed=1)
    assert res.costs[0] < 1e-16


def test_search_stops_after_two_hits_of_the_best_minimum():
    M, _ = _M(3, noise=0.02, seed=7)
    G, costs, info = C.search_triplet(M, 3, seed=0)
    assert info["stopped"] == "hits" and info["hits"] >= 2
    assert info["n_starts"] == len(info["history"]) <= 40
    assert np.all(np.diff(costs) >= 0)
    assert costs[0] <= min(c for _, c, _ in info["history"]) * (1 + 1e-5)


def test_search_from_random_starts_only_finds_the_relaxations_minimum():
    """The stopping rule, fed only seeded random starts, confirms the same minimum."""
    M, _ = _M(2, noise=0.03, seed=8)
    _, c_relaxed, _ = C.search_triplet(M, 2, seed=0)
    G, c_random, info = C.search_triplet(M, 2, seed=3, lams=())
    assert info["n_random"] == info["n_starts"] >= 2
    assert info["miss_bound"] == pytest.approx(min(1.0, 3.0 / info["n_random"]))
    assert c_random[0] == pytest.approx(c_relaxed[0], rel=1e-4)


def test_search_is_deterministic_and_bounded():
    M, _ = _M(2, noise=0.05, seed=9)
    a = C.search_triplet(M, 2, seed=5, hits=50, max_starts=6)
    b = C.search_triplet(M, 2, seed=5, hits=50, max_starts=6)
    assert a[2]["stopped"] == "max_starts" and a[2]["n_starts"] == 6
    np.testing.assert_array_equal(a[0], b[0])
    assert a[2]["history"] == b[2]["history"]
