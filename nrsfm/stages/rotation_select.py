"""Rotation-stage rules that make the result one answer (issue 18).

* :func:`determined_subspace`: the part of the motion factor that W determines. When W has
  numerical rank r below 3K (a rigid or planar part, K larger than the data needs, shark),
  the trailing columns of ``M_hat = U_3K S_3K^1/2`` are rounding noise: a triplet search over
  all 3K rows of G then mixes them in, and which mixture it picks depends on the units of W.
  Solving in the r-dimensional subspace removes them (``M_hat G = M_r G_r`` for
  ``G = V_r G_r``).
* :func:`effective_K`: the number of shape bases whose cameras the subspace can hold.
* :func:`in_determined_subspace` / :func:`lift_result`: the rotation stage's entry and exit
  (both rotation entry points, :mod:`nrsfm.stages.rotations` and :mod:`nrsfm.ablation`).
* :func:`lower_minimum`: a failed triplet search against a model that does not fit exactly.
* :func:`rotation_candidates`, :func:`select_by_shape_objective`,
  :func:`depth_sensitivity`: the rotations that serve the shape, and whether the camera
  motion determines the depth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["DETERMINED_RTOL", "Subspace", "depth_sensitivity", "determined_subspace",
           "effective_K", "in_determined_subspace", "lift_result", "lift_triplets",
           "lower_minimum", "rotation_candidates", "select_by_shape_objective",
           "shape_objective"]

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


def in_determined_subspace(M, K, enabled=True, say=None):
    """The rotation stage's motion factor and K: the determined subspace when W's rank r is
    below 3K (``enabled``), ``M`` and K unchanged otherwise.

    Parameters
    ----------
    M : (2F, 3K) ndarray
    K : int
    enabled : bool
        ``RotationSettings.determined``.
    say : callable(str) or None

    Returns
    -------
    M_used : (2F, r) or (2F, 3K) ndarray
    K_used : int
        ``effective_K(r, K)`` or K.
    sub : Subspace or None
        None when not enabled.
    info : dict
        ``determined_rank``, ``effective_K``.
    """
    sub = determined_subspace(M) if enabled else None
    rank = sub.rank if sub is not None else M.shape[1]
    if sub is None or not sub.deficient:
        return M, K, sub, dict(determined_rank=rank, effective_K=K)
    k = effective_K(sub.rank, K)
    if say is not None:
        say(f"W has numerical rank {sub.rank} < 3K = {3 * K}: rotations from the "
            f"determined {sub.rank}-dimensional subspace, {k} triplet(s)")
    return sub.M, k, sub, dict(determined_rank=rank, effective_K=k)


def lift_result(result, sub, K):
    """A rotation result of the subspace as one of the full motion factor (in place).

    ``G`` and the triplets in ``info`` (``G_refit``, ``G_family``) become (m, 3K, 3)
    (:func:`lift_triplets`); ``params["K"]`` becomes K. Nothing is done when ``sub`` is
    None or of full rank.

    Returns
    -------
    RotationResult
    """
    if sub is None or not sub.deficient:
        return result
    result.G = lift_triplets(result.G, sub)
    for key in ("G_refit", "G_family"):
        if key in result.info:
            result.info[key] = lift_triplets(result.info[key], sub)
    result.params["K"] = K
    return result


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
    from .corrective import search_triplet

    sub = determined_subspace(M_hat)
    _, costs, _ = search_triplet(sub.M, effective_K(sub.rank, K), seed=seed + 1,
                                 hits=n_starts + 1, max_starts=n_starts, lams=())
    best = float(costs[0])
    return bool(best < cost * (1.0 - rtol)), best


def rotation_candidates(rotation_stage):
    """Rotation sets the shape stage may use: the stage's own result, then the best triplet's.

    The averaged rotations (paper Sec. 3.1) are closer to the truth on the benchmark, but
    the shapes they give are not always better (stretch: e3d 1.07 x that of the best single
    triplet's rotations, ground-truth rotations 1.02 x): the shape is chosen by its own
    objective instead (:func:`select_by_shape_objective`).

    Parameters
    ----------
    rotation_stage : RotationResult

    Returns
    -------
    list of (name, (F, 3, 3) ndarray)
        One entry when the stage used a single triplet.
    """
    from .rotations import resolve_depth_signs

    out = [(rotation_stage.strategy, rotation_stage.rotations)]
    if rotation_stage.G.shape[0] > 1:
        single, _ = resolve_depth_signs(rotation_stage.per_triplet[0])
        out.append(("single_triplet", single))
    return out


def shape_objective(shape_result):
    """The shape prior's objective at a shape stage's result (None if it has none).

    ``1/2 ||W - R X||^2 + sum_i theta_i sigma_i(X#)`` (Eq. 10 with the weighted nuclear
    norm) for the bilinear solver; the last ``cost`` of the ADMM's history otherwise.
    """
    value = getattr(shape_result, "wnn_objective", None)
    if value is None:
        history = getattr(shape_result, "history", None) or {}
        cost = history.get("cost") if isinstance(history, dict) else None
        value = None if cost is None or len(cost) == 0 else cost[-1]
    return None if value is None or not np.isfinite(value) else float(value)


def select_by_shape_objective(candidates, solve):
    """The rotations whose shapes reach the lowest shape objective (deterministic).

    Parameters
    ----------
    candidates : list of (name, (F, 3, 3) ndarray)
        From :func:`rotation_candidates`; ties keep the earlier entry.
    solve : callable
        ``solve(R)`` -> a shape result (same W, K, prior and solver for every candidate).

    Returns
    -------
    index : int
    results : list
        The shape result of each candidate.
    objectives : list of float or None
    """
    results = [solve(R) for _, R in candidates]
    objectives = [shape_objective(r) for r in results]
    index = 0
    if all(v is not None for v in objectives):
        index = int(np.argmin(objectives))         # first minimum on ties
    return index, results, objectives


def depth_sensitivity(candidates, results):
    """How much the shapes move per unit of rotation change between two rotation sets.

    ``e3d(X_a, X_b) / e_R(R_a, R_b)`` for the first two candidates (per-frame similarity
    alignment of the shapes, one global alignment of the rotations). Where the camera
    motion determines depth, two nearby rotation estimates give nearly the same shapes
    (original cameras: pickup 0.0021 / 0.0227 = 0.09, stretch 0.018 / 0.046 = 0.38);
    where it does not, the shapes follow the rotations (the same shapes re-projected by a
    camera turning 62 degrees: pickup 0.062 / 0.030 = 2.1, stretch 0.36 / 0.072 = 5.0;
    e3d 0.18 and 0.25 even with the exact rotations). Measured with the family-combined
    rotations as the first candidate.

    Parameters
    ----------
    candidates : list of (name, (F, 3, 3) ndarray)
    results : list of shape results (``.shapes`` (F, 3, P))

    Returns
    -------
    dict or None
        ``shape_change``, ``rotation_change``, ``ratio``; None with fewer than two
        candidates or identical rotations.
    """
    from ..metrics import e3d, rotation_error

    if len(candidates) < 2:
        return None
    dR = rotation_error(candidates[0][1], candidates[1][1])
    dX = e3d(results[1].shapes, results[0].shapes)
    if not dR > 1e-12:
        return None
    return dict(shape_change=float(dX), rotation_change=float(dR), ratio=float(dX / dR))
