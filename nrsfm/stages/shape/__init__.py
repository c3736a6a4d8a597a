"""Shape stage (paper Sec. 3.2): per-frame shapes X from W and the cameras R.

:func:`solve_shape` runs one of two solvers of the same weighted nuclear norm problem
(Eq. 8, 10), each with its settings class, and returns one result type,
:class:`ShapeResult`:

* ``bilinear`` (:mod:`.bilinear`, :class:`BilinearSettings`, the default): the factored
  weighted nuclear norm minimised to a verified stationary point;
* ``admm`` (:mod:`.admm`, :class:`AdmmSettings`): the paper's continuation ADMM.

The ``pseudo_inverse`` method's rank-K truncation of ``pinv(R) W`` (Table 1) is
:func:`solve_pseudo_inverse`. Why the bilinear solver is the default:
``docs/studies/shape.md``.
"""

from __future__ import annotations

import numpy as np

from .admm import AdmmSettings
from .bilinear import BilinearSettings
from .common import (PRIORS, ShapeResult, check_prior, check_shape_inputs, phi, phi_inv,
                     pseudo_inverse_shapes, truncate_rank)

__all__ = ["PRIORS", "SOLVERS", "AdmmSettings", "BilinearSettings", "ShapeResult", "phi",
           "phi_inv", "pseudo_inverse_shapes", "solve_pseudo_inverse", "solve_shape",
           "truncate_rank"]

#: name -> settings class of the two shape solvers
SOLVERS = {"bilinear": BilinearSettings, "admm": AdmmSettings}


def solve_shape(W, R, K, prior="organic", settings=None, progress=None):
    """Run the shape stage.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements (any units: the solvers return shapes in W's units).
    R : (F, 3, 3) or (F, 2, 3) ndarray
    K : int
    prior : {"organic", "weighted", "nuclear"}
        The regulariser (:data:`PRIORS`): the partial sum of the weighted singular values
        (Eq. 10, N = 1), all of them weighted (Eq. 8), or the plain nuclear norm (Eq. 7).
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
        raise ValueError(f"settings must be a BilinearSettings or an AdmmSettings; got "
                         f"{settings!r}")
    return settings.solve(W, R, K, check_prior(prior), progress)


def solve_pseudo_inverse(W, R, K):
    """The ``pseudo_inverse`` method's shapes: ``X = P_K[pinv(R) W]``, the shape of every
    frame that reproduces W exactly (minimum norm, planar per frame) projected onto the top-K
    singular vectors of ``X#``. No prior, no iterations.

    Returns
    -------
    ShapeResult
        ``objective`` is the data term ``1/2 ||W - R X||_F^2``; an empty ``history``.
    """
    W, Rf, F, P, K = check_shape_inputs(W, R, K)
    X_init = pseudo_inverse_shapes(W, R)
    shapes = truncate_rank(X_init, K)
    data = 0.5 * float(np.sum((W.reshape(F, 2, P) - Rf @ shapes) ** 2))
    return ShapeResult(shapes=shapes, X_init=X_init,
                       X_init_singular_values=np.linalg.svd(phi(X_init), compute_uv=False),
                       theta=None, N=K, prior="none", solver="pseudo_inverse",
                       converged=True, objective=data, optimality=0.0,
                       optimality_kind="exact", params=dict(K=K))
