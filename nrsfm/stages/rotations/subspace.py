"""The determined subspace of the motion factor: the rotation-stage rule that makes the
result one answer when W has numerical rank below 3K.

* :func:`determined_subspace`: the part of the motion factor that W determines. When W has
  numerical rank r below 3K (a rigid or planar part, K larger than the data needs, shark),
  the trailing columns of ``M_hat = U_3K S_3K^1/2`` are rounding noise: a triplet search over
  all 3K rows of G then mixes them in, and which mixture it picks depends on the units of W.
  Solving in the r-dimensional subspace removes them (``M_hat G = M_r G_r`` for
  ``G = V_r G_r``).
* :func:`effective_K`: the number of shape bases whose cameras the subspace can hold.
* :func:`lift_triplets`: the triplets of the subspace as triplets of the full factor.
* :func:`lower_minimum`: a failed triplet search against a model that does not fit exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..corrective import search_triplet

__all__ = ["DETERMINED_RTOL", "Subspace", "determined_subspace", "effective_K",
           "lift_triplets", "lower_minimum"]

#: singular values of W below ``DETERMINED_RTOL * s_1`` count as zero (a numerical
#: tolerance: float64 rounding leaves about 1e-16 s_1, perturbations of 1e-7 of W's entries
#: about 1e-8 s_1; any measured track noise is far above it)
DETERMINED_RTOL = 1e-6


@dataclass(frozen=True)
class Subspace:
    """The determined part of a motion factor.

    Attributes
    ----------
    M : (2F, r) ndarray
        ``U_r S_r`` from the SVD of ``M_hat``; ``M_hat V_r = M``.
    V : (3K, r) ndarray
        Orthonormal basis of the determined rows of G: ``G = V G_r``.
    rank : int
        r, the numerical rank of ``M_hat`` (of W).
    full : int
        3K, the number of columns of ``M_hat``.
    """

    M: np.ndarray
    V: np.ndarray
    rank: int
    full: int

    @property
    def deficient(self):
        return self.rank < self.full


def determined_subspace(M_hat, rtol=DETERMINED_RTOL):
    """The subspace of the motion factor that W determines.

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    rtol : float
        Relative tolerance on the singular values of W (those of ``M_hat`` squared, as
        ``M_hat = U S^1/2``).

    Returns
    -------
    Subspace
    """
    M = np.asarray(M_hat, float)
    if M.ndim != 2:
        raise ValueError(f"M_hat must be a 2-D (2F, 3K) matrix; got shape {M.shape}")
    U, s, Vt = np.linalg.svd(M, full_matrices=False)
    r = int(np.sum(s ** 2 > rtol * s[0] ** 2)) if s.size and s[0] > 0 else 0
    r = max(r, 1)
    # a deterministic sign per direction (largest entry of V positive): one answer
    V = Vt[:r].T
    sign = np.sign(V[np.argmax(np.abs(V), axis=0), np.arange(r)])
    sign = np.where(sign == 0, 1.0, sign)
    return Subspace(M=U[:, :r] * (s[:r] * sign), V=V * sign, rank=r, full=M.shape[1])


def effective_K(rank, K):
    """Shape bases whose cameras a rank-r motion factor can hold: ``min(K, max(1, r // 3))``.

    A basis shape of full rank 3 takes three columns of ``M_hat`` (Eq. 1); a planar or
    rigid part fewer. Rigid plus planar deformation (r = 5) gives 1: one corrective
    triplet, the rigid camera.
    """
    return int(min(K, max(1, rank // 3)))


def lift_triplets(G_r, sub):
    """Triplets of the subspace as triplets of the full motion factor: ``G = V G_r``.

    Parameters
    ----------
    G_r : (m, r, 3) or (r, 3) ndarray
    sub : Subspace

    Returns
    -------
    G : (m, 3K, 3) or (3K, 3) ndarray
    """
    G_r = np.asarray(G_r, float)
    if G_r.shape[-2] != sub.rank:
        raise ValueError(f"G_r must have {sub.rank} rows (the subspace's rank); "
                         f"got shape {G_r.shape}")
    return np.einsum("ir,...rj->...ij", sub.V, G_r)


def lower_minimum(M_hat, K, cost, seed=0, n_starts=4, rtol=1e-3):
    """Whether seeded random starts reach a lower Dai cost than ``cost`` (a failed search).

    Separates "the search failed" (another start finds a lower minimum) from "the model
    does not fit exactly" (real shapes are not of rank K: the best minimum's cost exceeds
    what the noise level predicts, and no start does better).

    Parameters
    ----------
    M_hat : (2F, 3K) ndarray
    K : int
    cost : float
        Dai's cost of the triplet the rotation stage used.
    seed : int
    n_starts : int
        Random starts, refined on all frames (from ``default_rng(seed + 1)``: not the
        search's own starts).
    rtol : float
        Relative margin below ``cost`` that counts as lower.

    Returns
    -------
    lower : bool
    best : float
        The lowest cost the extra starts reached.
    """
    sub = determined_subspace(M_hat)
    search = search_triplet(sub.M, effective_K(sub.rank, K), seed=seed + 1,
                            hits=n_starts + 1, max_starts=n_starts, lams=())
    best = float(search.costs[0])
    return bool(best < cost * (1.0 - rtol)), best
