"""Shape stage (paper Sec. 3.2): per-frame shapes X from W and the cameras R.

:func:`solve_shape` runs one of two solvers of the weighted nuclear norm problem (Eq. 8,
10): ``bilinear`` (:mod:`.bilinear`, the default) or ``admm`` (:mod:`.admm`, the paper's);
:func:`solve_pseudo_inverse` is the ``pseudo_inverse`` method (Table 1). Why the bilinear
solver is the default: ``docs/studies/shape.md``.
"""

from __future__ import annotations

import numpy as np

from ...validation import check_shape_inputs
from .admm import AdmmSettings
from .bilinear import BilinearSettings
from .common import PRIORS, ShapeResult, check_prior, phi, phi_inv, pseudo_inverse_shapes
from .common import truncate_rank

__all__ = ["PRIORS", "SOLVERS", "ShapeResult", "solve_pseudo_inverse", "solve_shape"]

#: name -> settings class of the two shape solvers
SOLVERS = {"bilinear": BilinearSettings, "admm": AdmmSettings}


def solve_shape(W, R, K, prior="organic", settings=None, progress=None):
    """Run the shape stage.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements, any units (the shapes come back in W's units).
    R : (F, 3, 3) or (F, 2, 3) ndarray
    K : int
    prior : {"organic", "weighted", "nuclear"}
        Eq. 10 (N = 1), Eq. 8 or Eq. 7 (:data:`PRIORS`).
    settings : BilinearSettings or AdmmSettings, optional
        The solver and its settings; default ``BilinearSettings()``.
    progress : callable(str) or None

    Returns
    -------
    ShapeResult

    Raises
    ------
    ValueError
        Unknown prior, settings of another type, bad shapes of W or R.
    """
    settings = BilinearSettings() if settings is None else settings
    if not isinstance(settings, tuple(SOLVERS.values())):
        raise ValueError(f"settings must be a BilinearSettings or AdmmSettings: {settings!r}")
    return settings.solve(W, R, K, check_prior(prior), progress)


def solve_pseudo_inverse(W, R, K):
    """The ``pseudo_inverse`` method: ``X = P_K[pinv(R) W]``, the minimum-norm shapes that
    reproduce W projected onto the top-K singular vectors of ``X#`` (a ShapeResult whose
    ``objective`` is the data term ``1/2 ||W - R X||_F^2``)."""
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    X_init = pseudo_inverse_shapes(W, R)
    shapes = truncate_rank(X_init, K)
    data = 0.5 * float(np.sum((W.reshape(F, 2, P) - Rf @ shapes) ** 2))
    sigma = np.linalg.svd(phi(X_init), compute_uv=False)
    result = ShapeResult(shapes, X_init, sigma, None, K, "none", "pseudo_inverse", {}, 0, True)
    result.objective, result.optimality = data, 0.0
    return result
