"""Rotation stage (paper Sec. 3.1): triplets -> per-triplet rotations -> registration ->
filtering -> per-frame L1 single rotation averaging -> depth signs.

Conventions
-----------
* A triplet G (3K x 3) maps frame f's 2 x 3K block to ``M_f G = c_f R_f[:2]`` (a scaled
  orthographic camera).  Lifting it to SO(3) (:func:`rotations_from_triplets`) gives
  ``R_f`` when ``c_f > 0`` and ``diag(-1, -1, 1) R_f`` ("depth reversal" of frame f: the
  same image with the shape negated) when ``c_f < 0``; a triplet may also come out with
  the opposite handedness (``diag(1, 1, -1) R_f D``, D = diag(1, 1, -1)), which equals the
  depth reversal of every frame times a fixed rotation, so the per-frame flips absorb it.
* Registration (:func:`register_rotations`) solves Eq. 3 with one R_reg in SO(3) per
  triplet plus a per-frame choice of I or diag(-1, -1, 1).
* The final per-frame depth sign is chosen by motion smoothness (Dai's rule, see
  :func:`resolve_depth_signs`); ``sign_from_smoothness`` flags the frames it changed.

The K triplets (the paper says only "using Dai et al." for every k): the best one of the
search and K - 1 refined on temporal windows. W of numerical rank r < 3K: the stage runs in
the determined r-dimensional subspace of ``M_hat`` (:mod:`.subspace`). Why this default:
``docs/studies/rotations.md``.
"""

from __future__ import annotations

from .lifting import (FLIP, MIRROR, filter_rotations, register_rotations,
                      resolve_depth_signs, rotations_from_triplets)
from .stage import (RotationResult, RotationSettings, estimate_rotations, register_triplets,
                    triplets_on_subsets, window_weights)
from .subspace import DETERMINED_RTOL, determined_subspace, effective_K, lower_minimum

__all__ = ["DETERMINED_RTOL", "FLIP", "MIRROR", "RotationResult", "RotationSettings",
           "determined_subspace", "effective_K", "estimate_rotations", "filter_rotations",
           "lower_minimum", "register_rotations", "register_triplets", "resolve_depth_signs",
           "rotations_from_triplets", "triplets_on_subsets", "window_weights"]
