"""The rotations that serve the shape: the shape stage solved for the rotation stage's
candidates, the one with the lower shape objective kept, and whether the camera motion
determines the depth (the measure of how much the shapes follow the rotations).

The one home of the choice between rotation candidates (``ShapeSettings.select_rotations``):
it uses the rotation stage's result and the shape stage, and neither of them uses it.
"""

from __future__ import annotations

import numpy as np

from ..metrics import e3d, rotation_error
from .rotations import resolve_depth_signs
from .shape import solve_shape

__all__ = ["depth_sensitivity", "rotation_candidates", "select_by_shape_objective",
           "shape_for_rotations", "shape_objective"]


def shape_for_rotations(W, rotations, K, rotation_stage, settings, say):
    """The shape stage; with ``settings.select_rotations`` and a rotation stage that ran,
    solved for the stage's rotations and its best single triplet's, keeping the lower
    shape objective (recorded in
    ``rotation_stage.info["shape_selection"]``).

    Returns
    -------
    rotations : (F, 3, 3) ndarray
        The rotations the shapes were solved with.
    shape_stage : ShapeResult
    """
    select = rotation_stage is not None and settings.select_rotations
    cands = rotation_candidates(rotation_stage) if select else [("given", rotations)]
    results = [solve_shape(W, R, K, settings, say) for _, R in cands]
    if not select:
        return rotations, results[0]
    pick, objectives = select_by_shape_objective(results)
    names = [name for name, _ in cands]
    rotation_stage.info["shape_selection"] = dict(
        candidates=names, objectives=objectives, chosen=names[pick],
        depth=depth_sensitivity(cands, results))
    say(f"rotations for the shape: {names[pick]} (objectives " + ", ".join(
        f"{n} {v:.6g}" if v is not None else f"{n} -" for n, v in zip(names, objectives))
        + ")")
    return cands[pick][1], results[pick]


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


def select_by_shape_objective(results):
    """The index of the shape result with the lowest shape objective (deterministic).

    Parameters
    ----------
    results : list of shape results
        One per rotation candidate (:func:`rotation_candidates`; the same W, K, prior and
        solver for each); ties keep the earlier entry.

    Returns
    -------
    index : int
        0 when a result has no objective.
    objectives : list of float or None
    """
    objectives = [shape_objective(r) for r in results]
    index = 0
    if all(v is not None for v in objectives):
        index = int(np.argmin(objectives))         # first minimum on ties
    return index, objectives


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
    if len(candidates) < 2:
        return None
    dR = rotation_error(candidates[0][1], candidates[1][1])
    dX = e3d(results[1].shapes, results[0].shapes)
    if not dR > 1e-12:
        return None
    return dict(shape_change=float(dX), rotation_change=float(dR), ratio=float(dX / dR))
