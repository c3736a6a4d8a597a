"""Rank-K truncation of the pseudo-inverse shape (the ``pseudo_inverse`` method, Table 1).

``X = P_K[pinv(R) W]``: the shape of every frame that reproduces W exactly (minimum norm,
planar per frame), projected onto the top-K singular vectors of ``X#``. No prior, no
iterations.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .base import SolverSettings
from .common import ShapeResult, check_shape_inputs, phi, pseudo_inverse_shapes, truncate_rank

__all__ = ["PseudoInverseSettings", "solve_pseudo_inverse"]


@dataclass(frozen=True)
class PseudoInverseSettings(SolverSettings):
    """Rank-K truncation of ``pinv(R) W`` (the ``pseudo_inverse`` method; no options)."""

    name: ClassVar[str] = "pseudo_inverse"
    uses_prior: ClassVar[bool] = False
    estimates_depth: ClassVar[bool] = False

    def solve(self, W, R, K, prior=None, progress=None, observed=None):
        self.check_observed(observed, W)
        return solve_pseudo_inverse(W, R, K)


def solve_pseudo_inverse(W, R, K):
    """The shape stage's rank-K pseudo-inverse (no prior, no options).

    Returns
    -------
    ShapeResult
        ``objective`` is the data term ``1/2 ||W - R X||_F^2``; no iterations, so an
        empty ``history``.
    """
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    X_init = pseudo_inverse_shapes(W, R)
    shapes = truncate_rank(X_init, K)
    data = 0.5 * float(np.sum((W.reshape(F, 2, P) - Rf @ shapes) ** 2))
    return ShapeResult(shapes=shapes, X_init=X_init,
                       X_init_singular_values=np.linalg.svd(phi(X_init), compute_uv=False),
                       theta=None, N=K, prior="none", solver="pseudo_inverse",
                       converged=True, objective=data,
                       optimality=0.0, optimality_kind="exact", params=dict(K=K))
