"""What every shape solver declares: the priors, the base of the solvers' settings and the
registry the settings fill.

A solver is one module holding a frozen dataclass deriving from :class:`SolverSettings`
with a ``name`` and a ``solve`` method; defining the class registers it in
:data:`SOLVERS` (``reconstruct(shape_solver=name)`` then runs it). The modules of this
package are imported by :mod:`nrsfm.stages.shape`, so a solver written there is found
without any list to edit; a solver written elsewhere registers when its module is imported.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from ...validation import check_choice

__all__ = ["PRIORS", "SOLVERS", "SolverSettings", "check_prior"]

#: Shape priors: prior -> N, the leading singular values left unpenalised. ``organic``:
#: the partial sum of the weighted singular values (paper Eq. 10, N = 1); ``weighted``:
#: every singular value weighted (Eq. 8); ``nuclear``: the plain nuclear norm (Eq. 7).
PRIORS = {"organic": 1, "weighted": 0, "nuclear": 0}

#: name -> settings class of every registered shape solver (filled by the subclasses of
#: :class:`SolverSettings`).
SOLVERS: dict = {}


def check_prior(prior):
    """``prior`` if it is one of :data:`PRIORS`; ValueError naming the choices otherwise."""
    return check_choice("shape prior", prior, PRIORS)


class SolverSettings:
    """Base of the shape solvers' settings.

    A subclass sets the class attributes ``name`` (its registered name), ``uses_prior``
    (False for the solvers that take no prior: their :class:`ShapeSettings` prior is None)
    and ``masked`` (True for a solver whose data term can leave out unobserved entries), and
    implements ``solve``. Defining the subclass registers it in :data:`SOLVERS`.
    """

    name: ClassVar[str] = ""
    uses_prior: ClassVar[bool] = True
    masked: ClassVar[bool] = False
    #: False for a solver that does not estimate the depth (the pseudo-inverse keeps
    #: ``R_f[:2]' W_f``): the diagnostics' depth signal is not read from its shapes
    estimates_depth: ClassVar[bool] = True
    #: True for a solver whose ``solve`` takes ``start``: its own result on the same W with
    #: nearby cameras, as its starting point (``solve_shape(..., start=)``)
    warm_start: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        name = cls.__dict__.get("name")
        if not name:
            return
        old = SOLVERS.get(name)
        if old is not None and (old.__module__, old.__qualname__) != \
                (cls.__module__, cls.__qualname__):
            raise ValueError(f"shape solver {name!r} is registered already "
                             f"({old.__module__}.{old.__qualname__})")
        SOLVERS[name] = cls

    def solve(self, W, R, K, prior, progress=None, observed=None):
        """Solve the shape stage for row-centred W (2F, P), cameras R (F, 2 or 3, 3) and K
        bases, with ``prior`` one of :data:`PRIORS` (None for a solver with
        ``uses_prior = False``), ``progress`` a callable(str) or None and ``observed``
        (F, P) bool or None (the data term on the observed entries only, for a solver with
        ``masked = True``; see :func:`check_observed`); returns a
        :class:`nrsfm.stages.shape.ShapeResult` (:func:`nrsfm.stages.shape.solve_shape`)."""
        raise NotImplementedError(f"{type(self).__name__} does not implement solve")

    def check_observed(self, observed, W):
        """``observed`` as a (F, P) bool array, or None when every entry is observed;
        ValueError when this solver has no masked data term and some entry is not."""
        if observed is None:
            return None
        obs = np.asarray(observed, bool)
        F, P = W.shape[0] // 2, W.shape[1]
        if obs.shape != (F, P):
            raise ValueError(f"observed must have shape (F, P) = ({F}, {P}); got {obs.shape}")
        if obs.all():
            return None
        if not self.masked:
            raise ValueError(f"the {self.name} shape solver has no masked data term; "
                             f"{int((~obs).sum())} (frame, point) entries are not observed "
                             f"(solvers with one: "
                             f"{[n for n, c in SOLVERS.items() if c.masked]})")
        return obs
