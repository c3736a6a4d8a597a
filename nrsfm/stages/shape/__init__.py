"""Shape stage (paper Sec. 3.2): per-frame shapes X from W and the cameras R.

One interface for every solver: :func:`solve_shape` with a
:class:`nrsfm.settings.ShapeSettings` returns one result type, :class:`ShapeResult`.

Solvers (one module each, registered in :data:`SOLVERS`):

* ``bilinear`` (:mod:`.bilinear`, default): the factored weighted nuclear norm minimised
  to a verified stationary point;
* ``admm`` (:mod:`.admm`): the paper's continuation ADMM;
* ``closed_form`` (:mod:`.bilinear`): the exact rank-K solution, no prior;
* ``constrained`` (:mod:`.constrained`, optional): the organic norm with W fitted to within
  its noise (exact on rank-K and rank-deficient data; worse under noise and slower);
* ``pseudo_inverse`` (:mod:`.pseudo_inverse`): rank-K truncation of ``pinv(R) W``.

A new solver is one module with a ``solve(W, R, K, prior, settings, progress)`` function,
one settings type in :mod:`nrsfm.settings` (a frozen dataclass deriving from
``SolverSettings``, with ``name``) and one line in :data:`SOLVERS`.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

from ...settings import (AdmmSettings, BilinearSettings, ClosedFormSettings,
                         ConstrainedSettings, PseudoInverseSettings, ShapeSettings)
from .admm import solve_admm
from .bilinear import solve_bilinear, solve_closed_form
from .common import (ShapeResult, phi, phi_inv, pseudo_inverse_shapes,
                     truncate_rank)
from .constrained import solve_constrained
from .pseudo_inverse import solve_pseudo_inverse

__all__ = ["SHAPE_SOLVERS", "SOLVERS", "ShapeResult", "Solver", "phi", "phi_inv",
           "pseudo_inverse_shapes", "solve_shape", "solve_shapes", "truncate_rank"]


class Solver(NamedTuple):
    """A registered shape solver: its settings type and its function."""

    settings: type
    solve: Callable


#: name -> Solver. ``reconstruct(shape_solver=name)`` picks one (``pseudo_inverse`` is the
#: method of that name).
SOLVERS = {
    "admm": Solver(AdmmSettings, solve_admm),
    "bilinear": Solver(BilinearSettings, solve_bilinear),
    "closed_form": Solver(ClosedFormSettings, solve_closed_form),
    "constrained": Solver(ConstrainedSettings, solve_constrained),
    "pseudo_inverse": Solver(PseudoInverseSettings, solve_pseudo_inverse),
}

#: the solvers ``reconstruct(shape_solver=...)`` offers with a prior-based method
SHAPE_SOLVERS = ("admm", "bilinear", "closed_form", "constrained")


def solve_shape(W, R, K, settings=None, progress=None):
    """Run the shape stage.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements (any units: the solvers return shapes in W's units).
    R : (F, 3, 3) or (F, 2, 3) ndarray
    K : int
    settings : nrsfm.settings.ShapeSettings, optional
        Prior and solver settings; default ``ShapeSettings()`` (organic, bilinear).
    progress : callable(str) or None

    Returns
    -------
    ShapeResult
    """
    settings = ShapeSettings() if settings is None else settings
    solver = SOLVERS.get(settings.solver.name)
    if solver is None or not isinstance(settings.solver, solver.settings):
        raise ValueError(f"no solver registered for {settings.solver!r}; expected one of "
                         f"{list(SOLVERS)}")
    return solver.solve(W, R, K, settings.prior, settings.solver, progress)


def solve_shapes(W, R, K, prior="organic", solver="bilinear", progress=None, **options):
    """:func:`solve_shape` with the solver named and its options as keywords (converted
    into the solver's settings type; an unknown option is a ValueError naming the known
    ones). ``prior`` is ignored by ``closed_form`` and ``pseudo_inverse``."""
    from ...settings import solver_settings

    settings = solver_settings(solver, options)
    no_prior = settings.name in ("closed_form", "pseudo_inverse")
    return solve_shape(W, R, K, ShapeSettings(prior=None if no_prior else prior,
                                              solver=settings), progress)
