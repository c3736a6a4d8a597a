"""The rotations that serve the shape, and whether the camera motion determines the depth.

The shape stage is solved for the rotation stage's rotations, the first of its candidates
(:meth:`~nrsfm.stages.rotations.RotationResult.candidates`: the stage's rotations and its
best single triplet's). The second candidate is solved as a probe, from the first one's
answer, for the depth sensitivity (:func:`nrsfm.metrics.depth_sensitivity`, how much the
shapes follow the rotations). ``ShapeSettings(select_rotations=True)`` instead solves every
candidate in full and keeps the one with the lowest shape objective
(:attr:`~nrsfm.stages.shape.ShapeResult.prior_objective`); measured in
``docs/shape_stage.md``, it is no better on average and costs a second full solve.

The one home of the choice between rotation candidates: it uses the rotation stage's
result and the shape stage, and neither of them uses it.
"""

from __future__ import annotations

import numpy as np

from ..metrics import depth_sensitivity
from .shape import solve_shape

__all__ = ["shape_for_rotations"]


def shape_for_rotations(W, rotations, K, rotation_stage, settings, say):
    """The shape stage, and the depth sensitivity between the rotation stage's candidates.

    Solved for the rotation stage's first candidate (its rotations). With
    ``settings.select_rotations`` every candidate is solved in full and the one with the
    lowest shape objective kept (the first on ties, and the first when a result has no
    objective); without, the second candidate is solved only as a probe, from the first
    one's answer where the solver takes a start, for the depth sensitivity. Recorded in
    ``rotation_stage.info["shape_selection"]`` (candidates, objectives, the one chosen,
    ``depth``, and ``probe``: whether the second solve was a probe).

    Returns
    -------
    rotations : (F, 3, 3) ndarray
        The rotations the shapes were solved with.
    shape_stage : ShapeResult
    """
    if rotation_stage is None:
        return rotations, solve_shape(W, rotations, K, settings, say)
    cands = rotation_stage.candidates()
    first = solve_shape(W, cands[0][1], K, settings, say)
    select = settings.select_rotations
    probe_start = None if select or not settings.solver.warm_start else first
    results = [first]
    for i, (_, R) in enumerate(cands[1:]):      # the second: the probe, from the first answer
        results.append(solve_shape(W, R, K, settings, say,
                                   start=probe_start if i == 0 else None))
    names = [name for name, _ in cands]
    objectives = [r.prior_objective for r in results]
    pick = 0
    if select and all(v is not None for v in objectives):
        pick = int(np.argmin(objectives))          # first minimum on ties
    if len(cands) > 1:
        say(f"rotations for the shape: {names[pick]} (objectives " + ", ".join(
            f"{n} {v:.6g}" if v is not None else f"{n} -" for n, v in zip(names, objectives))
            + ("" if select else f"; {names[1]} solved as a probe of the depth") + ")")
    depth = None if len(cands) < 2 else depth_sensitivity(
        cands[0][1], cands[1][1], results[0].shapes, results[1].shapes)
    rotation_stage.info["shape_selection"] = dict(
        candidates=names, objectives=objectives, chosen=names[pick], depth=depth,
        probe=not select and len(cands) > 1)
    return cands[pick][1], results[pick]
