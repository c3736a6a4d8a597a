"""Rotation stage (paper Sec. 3.1): triplets -> per-triplet rotations -> registration ->
filtering -> per-frame L1 single rotation averaging -> depth signs (:mod:`.stage`).

A triplet G (3K x 3) maps frame f's 2 x 3K block to ``M_f G = c_f R_f[:2]``. Lifting it
(:mod:`.lifting`) gives ``R_f`` when ``c_f > 0`` and ``diag(-1, -1, 1) R_f`` (the depth
reversal: the same image with the shape negated) when ``c_f < 0``; a triplet may also come
out with the opposite handedness, which equals the depth reversal of every frame times a
fixed rotation. Registration (Eq. 3) therefore solves for one R_reg per triplet plus a
per-frame choice of I or ``diag(-1, -1, 1)``; the final depth sign of each frame follows
motion smoothness (Dai's rule). W of numerical rank r < 3K: the stage runs in the
determined r-dimensional subspace of ``M_hat`` (:mod:`.subspace`). Why this default:
``docs/studies/rotations.md``.
"""

from .lifting import FLIP, MIRROR, filter_rotations, register_rotations
from .lifting import resolve_depth_signs, rotations_from_triplets
from .stage import RotationResult, RotationSettings, estimate_rotations

__all__ = ["RotationResult", "RotationSettings", "estimate_rotations"]
