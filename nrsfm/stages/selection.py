"""The rotations that serve the shape: the shape stage solved for the rotation stage's
candidates (:meth:`~nrsfm.stages.rotations.RotationResult.candidates`), the one whose
shape has the lower shape objective kept
(:attr:`~nrsfm.stages.shape.ShapeResult.prior_objective`), and whether the camera motion
determines the depth (:func:`nrsfm.metrics.depth_sensitivity`, how much the shapes follow
the rotations).

The one home of the choice between rotation candidates (``ShapeSettings.select_rotations``):
it uses the rotation stage's result and the shape stage, and neither of them uses it.
"""

from __future__ import annotations

import numpy as np

from ..metrics import depth_sensitivity
from .shape import solve_shape

__all__ = ["shape_for_rotations"]


def shape_for_rotations(W, rotations, K, rotation_stage, settings, say):
    """The shape stage; with ``settings.select_rotations`` and a rotation stage that ran,
    solved for the stage's rotation candidates, keeping the one with the lowest shape
    objective (the first on ties, and the first when a result has no objective), recorded
    in ``rotation_stage.info["shape_selection"]`` with the depth sensitivity between the
    first two.

    Returns
    -------
    rotations : (F, 3, 3) ndarray
        The rotations the shapes were solved with.
    shape_stage : ShapeResult
    """
    select = rotation_stage is not None and settings.select_rotations
    cands = rotation_stage.candidates() if select else [("given", rotations)]
    results = [solve_shape(W, R, K, settings, say) for _, R in cands]
    if not select:
        return rotations, results[0]
    objectives = [r.prior_objective for r in results]
    pick = 0
    if all(v is not None for v in objectives):
        pick = int(np.argmin(objectives))          # first minimum on ties
    names = [name for name, _ in cands]
    say(f"rotations for the shape: {names[pick]} (objectives " + ", ".join(
        f"{n} {v:.6g}" if v is not None else f"{n} -" for n, v in zip(names, objectives))
        + ")")
    depth = None if len(cands) < 2 else depth_sensitivity(
        cands[0][1], cands[1][1], results[0].shapes, results[1].shapes)
    rotation_stage.info["shape_selection"] = dict(
        candidates=names, objectives=objectives, chosen=names[pick], depth=depth)
    return cands[pick][1], results[pick]
