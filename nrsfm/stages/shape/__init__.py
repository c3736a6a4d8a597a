"""Shape stage (paper Sec. 3.2): per-frame shapes X from W and the cameras R.

One interface for every solver: :func:`solve_shape` with a :class:`ShapeSettings` returns
one result type, :class:`ShapeResult`.

Solvers (one module each; each holds its settings class, which registers it in
:data:`SOLVERS`):

* ``bilinear`` (:mod:`.bilinear`, default): the factored weighted nuclear norm minimised
  to a verified stationary point;
* ``admm`` (:mod:`.admm`): the paper's continuation ADMM;
* ``closed_form`` (:mod:`.bilinear`, from :mod:`.closed_form`): the exact rank-K solution,
  no prior;
* ``constrained`` (:mod:`.constrained`, optional): the organic norm with W fitted to within
  its noise (exact on rank-K and rank-deficient data; worse under noise and slower);
* ``pseudo_inverse`` (:mod:`.pseudo_inverse`): rank-K truncation of ``pinv(R) W``.

A new solver is one module: a frozen dataclass deriving from
:class:`~nrsfm.stages.shape.base.SolverSettings` with a ``name`` and a ``solve`` method
(:mod:`.base`). Every module of this package is imported here, so a module added to the
package is registered without editing any list.
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from dataclasses import dataclass

from ...validation import check_choice, check_flag
from .base import PRIORS, SOLVERS, SolverSettings
from .bilinear import BilinearSettings
from .common import ShapeResult, phi, phi_inv, pseudo_inverse_shapes, truncate_rank

for _module in pkgutil.iter_modules(__path__):          # registers every solver module
    importlib.import_module(f"{__name__}.{_module.name}")

__all__ = ["PRIORS", "SOLVERS", "ShapeResult", "ShapeSettings", "SolverSettings", "phi",
           "phi_inv", "pseudo_inverse_shapes", "solve_shape", "solve_shapes",
           "solver_settings", "truncate_rank"]


@dataclass(frozen=True)
class ShapeSettings:
    """Shape stage settings: the prior and one solver's settings.

    Attributes
    ----------
    prior : {"organic", "weighted", "nuclear"} or None
        The regulariser (:data:`~nrsfm.stages.shape.base.PRIORS`); None exactly for the
        solvers that take no prior (``closed_form``, ``pseudo_inverse``).
    solver : SolverSettings
        The solver and its typed settings (any registered in :data:`SOLVERS`).
    select_rotations : bool
        When the rotation stage ran: solve the shape in full for each of the stage's
        rotation candidates (its rotations and its best single triplet's) and keep the lower
        shape objective (:mod:`nrsfm.stages.selection`). False (default): one solve, for
        the stage's rotations.
    """

    prior: str = "organic"
    solver: SolverSettings = BilinearSettings()
    select_rotations: bool = False

    def __post_init__(self):
        if not isinstance(self.solver, SolverSettings) or not self.solver.name:
            raise ValueError(f"solver must be the settings of a registered shape solver "
                             f"(e.g. BilinearSettings()); got {self.solver!r}")
        if self.solver.uses_prior:
            check_choice("shape prior", self.prior, PRIORS)
        elif self.prior is not None:
            raise ValueError(f"the {self.solver.name} solver takes no prior; got "
                             f"prior={self.prior!r} (use prior=None)")
        check_flag("select_rotations", self.select_rotations)


def solver_settings(name, options=None):
    """Settings of a registered shape solver from a dict of options.

    Raises
    ------
    ValueError
        Unknown solver (the registered ones are named), or an option the solver does not
        take (its options are named).
    """
    cls = SOLVERS[check_choice("shape_solver", name, SOLVERS)]
    options = dict(options or {})
    fields = {f.name for f in dataclasses.fields(cls)}
    unknown = set(options) - fields
    if unknown:
        raise ValueError(f"unknown options {sorted(unknown)} for shape_solver {name!r}; "
                         f"it takes {sorted(fields)}")
    return cls(**options)


def solve_shape(W, R, K, settings=None, progress=None, observed=None, start=None):
    """Run the shape stage.

    Parameters
    ----------
    W : (2F, P) ndarray
        Row-centred measurements (any units: the solvers return shapes in W's units).
    R : (F, 3, 3) or (F, 2, 3) ndarray
    K : int
    settings : ShapeSettings, optional
        Prior and solver settings; default ``ShapeSettings()`` (organic, bilinear).
    progress : callable(str) or None
    observed : (F, P) bool ndarray, optional
        Fit the data term on these entries only (W still finite elsewhere, e.g. completed).
        Only a solver with ``masked = True`` (the ADMM) takes a partial mask; the others
        raise a ValueError rather than ignore it.
    start : ShapeResult, optional
        The same solver's result on the same W with nearby cameras: the starting point of a
        solver with ``warm_start = True``. Only for a solver that takes one (ValueError
        otherwise); it changes where the solver starts, not the problem.

    Returns
    -------
    ShapeResult
    """
    settings = ShapeSettings() if settings is None else settings
    if not isinstance(settings, ShapeSettings):
        raise ValueError(f"settings must be a ShapeSettings; got {settings!r}")
    if start is None:
        return settings.solver.solve(W, R, K, settings.prior, progress, observed=observed)
    if not settings.solver.warm_start:
        raise ValueError(f"the {settings.solver.name} shape solver takes no start")
    return settings.solver.solve(W, R, K, settings.prior, progress, observed=observed,
                                 start=start)


def solve_shapes(W, R, K, prior=None, solver="bilinear", progress=None, **options):
    """:func:`solve_shape` with the solver named and its options as keywords (converted
    into the solver's settings type by :func:`solver_settings`). ``prior`` defaults to
    ``organic`` for the solvers that take one; giving a prior to a solver that takes none
    is a ValueError."""
    settings = solver_settings(solver, options)
    if prior is None and settings.uses_prior:
        prior = "organic"
    return solve_shape(W, R, K, ShapeSettings(prior=prior, solver=settings), progress)
