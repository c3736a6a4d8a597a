"""The rotations that serve the shape.

The shape stage is solved once, for the rotation stage's rotations, the first of its
candidates (:meth:`~nrsfm.stages.rotations.RotationResult.candidates`: the stage's
rotations and its best single triplet's). ``ShapeSettings(select_rotations=True)`` instead
solves every candidate in full and keeps the one with the lowest shape objective
(:attr:`~nrsfm.stages.shape.ShapeResult.prior_objective`); measured in
``docs/shape_stage.md``, the choice is no better on average and costs a second full solve.
(Until issue 23 the second candidate was also solved by default, warm-started, only to read
the depth sensitivity between the two, :func:`nrsfm.metrics.depth_sensitivity`, for the
diagnostics; they now read :func:`nrsfm.metrics.depth_amplification`, which needs no
solve, and the sensitivity, which overlapped between good and bad runs, is no longer
recorded.)

The one home of the choice between rotation candidates: it uses the rotation stage's
result and the shape stage, and neither of them uses it.
"""

from __future__ import annotations

import numpy as np

from .shape import solve_shape

__all__ = ["shape_for_rotations"]


def shape_for_rotations(W, rotations, K, rotation_stage, settings, say):
    """The shape stage for the rotation stage's rotations, or for the best of its
    candidates.

    Without ``settings.select_rotations`` (the default) one solve, for the rotation stage's
    rotations. With it every candidate is solved in full and the one with the lowest shape
    objective kept (the first on ties, and the first when a result has no objective).
    Recorded in ``rotation_stage.info["shape_selection"]`` (candidates, objectives of the
    candidates solved, the one chosen).

    Returns
    -------
    rotations : (F, 3, 3) ndarray
        The rotations the shapes were solved with.
    shape_stage : ShapeResult
    """
    if rotation_stage is None:
        return rotations, solve_shape(W, rotations, K, settings, say)
    cands = rotation_stage.candidates()
    names = [name for name, _ in cands]
    solved = cands if settings.select_rotations else cands[:1]
    results = [solve_shape(W, R, K, settings, say) for _, R in solved]
    objectives = [r.prior_objective for r in results]
    pick = 0
    if len(results) > 1 and all(v is not None for v in objectives):
        pick = int(np.argmin(objectives))          # first minimum on ties
        say(f"rotations for the shape: {names[pick]} (objectives " + ", ".join(
            f"{n} {v:.6g}" for n, v in zip(names, objectives)) + ")")
    rotation_stage.info["shape_selection"] = dict(candidates=names, objectives=objectives,
                                                  chosen=names[pick])
    return cands[pick][1], results[pick]
