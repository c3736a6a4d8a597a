"""The determined subspace of the motion factor: what makes the rotation stage one answer
when W has numerical rank r below 3K (a rigid or planar part, K larger than the data need).

The trailing columns of ``M_hat = U_3K S_3K^1/2`` are then rounding noise: a triplet search
over all 3K rows of G mixes them in, and which mixture it picks depends on the units of W.
Solving in the r-dimensional subspace removes them (``M_hat G = M_r G_r`` for
``G = V_r G_r``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..corrective import search_triplet

__all__ = ["determined_subspace", "effective_K", "lower_minimum", "transposed_cost"]

#: singular values of W below ``DETERMINED_RTOL * s_1`` count as zero (float64 rounding
#: leaves about 1e-16 s_1, perturbations of 1e-7 of W's entries about 1e-8 s_1)
DETERMINED_RTOL = 1e-6


@dataclass(frozen=True)
class Subspace:
    """The determined part of a motion factor: ``M`` (2F, r) = ``M_hat V``, the orthonormal
    basis ``V`` (3K, r) of the determined rows of G, the rank r and ``full`` = 3K."""

    M: np.ndarray
    V: np.ndarray
    rank: int
    full: int

    @property
    def deficient(self):
        return self.rank < self.full


def determined_subspace(M_hat, rtol=DETERMINED_RTOL):
    """The :class:`Subspace` of ``M_hat`` (2F, 3K) that W determines: the singular values of
    W (those of M_hat squared) above ``rtol`` times the largest."""
    M = np.asarray(M_hat, float)
    if M.ndim != 2:
        raise ValueError(f"M_hat must be a 2-D (2F, 3K) matrix; got shape {M.shape}")
    U, s, Vt = np.linalg.svd(M, full_matrices=False)
    r = int(np.sum(s**2 > rtol * s[0] ** 2)) if s.size and s[0] > 0 else 0
    r = max(r, 1)
    # a deterministic sign per direction (largest entry of V positive): one answer
    V = Vt[:r].T
    sign = np.sign(V[np.argmax(np.abs(V), axis=0), np.arange(r)])
    sign = np.where(sign == 0, 1.0, sign)
    return Subspace(M=U[:, :r] * (s[:r] * sign), V=V * sign, rank=r, full=M.shape[1])


def effective_K(rank, K):
    """Shape bases whose cameras a rank-r motion factor holds, ``min(K, max(1, r // 3))``: a
    basis of full rank takes three columns of M_hat (Eq. 1); rigid plus planar (r = 5): 1."""
    return int(min(K, max(1, rank // 3)))


def lift_triplets(G_r, sub):
    """Triplets (..., r, 3) of the subspace as triplets (..., 3K, 3) of M_hat: ``V G_r``."""
    G_r = np.asarray(G_r, float)
    if G_r.shape[-2] != sub.rank:
        raise ValueError(
            f"G_r must have {sub.rank} rows (the subspace's rank); got shape {G_r.shape}"
        )
    return np.einsum("ir,...rj->...ij", sub.V, G_r)


def lower_minimum(M_hat, K, cost, seed=0, n_starts=4, rtol=1e-3):
    """(lower, best): whether ``n_starts`` random starts (``default_rng(seed + 1)``, not the
    search's own) reach a Dai cost below ``cost (1 - rtol)``, and the lowest they reach.

    Separates a failed search (another start finds a lower minimum) from a model that does
    not fit exactly (real shapes are not of rank K: no start does better).
    """
    sub = determined_subspace(M_hat)
    k, hits = effective_K(sub.rank, K), n_starts + 1
    search = search_triplet(sub.M, k, seed=seed + 1, hits=hits, max_starts=n_starts, lams=())
    best = float(search.costs[0])
    return bool(best < cost * (1.0 - rtol)), best


def transposed_cost(W, K, seed=0):
    """The best Dai cost per frame of W read the other way round (``W.T``, centred: P / 2
    frames of 2F points) from six starts: far below W's own where W was transposed."""
    Wt = W.T - W.T.mean(axis=1, keepdims=True)
    U, s, _ = np.linalg.svd(Wt / max(np.linalg.norm(Wt), 1e-300), full_matrices=False)
    M_hat = U[:, : 3 * K] * np.sqrt(s[: 3 * K])  # rank-3K factor (Eq. 1)
    search = search_triplet(M_hat, K, seed=seed, max_starts=6)
    return float(search.costs[0]) / (Wt.shape[0] // 2)
