"""What every shape solver shares: the reshuffle Phi, the pseudo-inverse shape, the input
check and the one result type, :class:`ShapeResult`.

Notation: ``X`` is the per-frame shape, (F, 3, P); ``X#`` (``X_sharp``) its reshuffle
Phi(X), (F, 3P), whose row f is ``[x-coords, y-coords, z-coords]`` of frame f's P points.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ...validation import check_choice

__all__ = ["PRIORS", "ShapeResult", "phi", "phi_inv", "pseudo_inverse_shapes", "truncate_rank"]

#: Shape priors: prior -> N, the leading singular values left unpenalised. ``organic``:
#: the partial sum of the weighted singular values (paper Eq. 10, N = 1); ``weighted``:
#: every singular value weighted (Eq. 8); ``nuclear``: the plain nuclear norm (Eq. 7).
PRIORS = {"organic": 1, "weighted": 0, "nuclear": 0}


def check_prior(prior):
    """``prior`` if it is one of :data:`PRIORS`; ValueError naming the choices otherwise."""
    return check_choice("shape prior", prior, PRIORS)


def phi(X):
    """Phi: (F, 3, P) shapes -> (F, 3P) X#."""
    X = np.asarray(X)
    return X.reshape(X.shape[0], -1)


def phi_inv(X_sharp, P):
    """Inverse of :func:`phi`: (F, 3P) -> (F, 3, P)."""
    X_sharp = np.asarray(X_sharp)
    return X_sharp.reshape(X_sharp.shape[0], 3, P)


def pseudo_inverse_shapes(W, R):
    """Per-frame pseudo-inverse shape ``X_init = pinv(R) W`` (paper Sec. 3.2).

    Parameters
    ----------
    W : (2F, P) ndarray
    R : (F, 2, 3) or (F, 3, 3) ndarray
        Per-frame cameras; only the first two rows are used.

    Returns
    -------
    X_init : (F, 3, P) ndarray
        The minimum-norm solution of ``R_f X_f = W_f`` per frame (planar for every frame).
    """
    F = W.shape[0] // 2
    Rf = np.asarray(R)[:, :2, :]
    return np.linalg.pinv(Rf) @ W.reshape(F, 2, -1)


def truncate_rank(X, K):
    """Project X# = Phi(X) onto its top-K singular vectors; returns (F, 3, P)."""
    U, s, Vt = np.linalg.svd(phi(X), full_matrices=False)
    return phi_inv((U[:, :K] * s[:K]) @ Vt[:K], X.shape[2])


@dataclass
class ShapeResult:
    """The result of every shape solver (:func:`nrsfm.stages.shape.solve_shape`).

    Attributes
    ----------
    shapes : (F, 3, P) ndarray
        The final shape, in the units of the W given.
    X_init : (F, 3, P) ndarray
        Pseudo-inverse shape ``pinv(R_f) W_f`` (planar per frame), W's units.
    X_init_singular_values : (min(F, 3P),) ndarray
        Singular values of ``X_init# = Phi(X_init)``, W's units.
    theta : ndarray or None
        The prior's weights of the singular values (solver's units; the first N are
        reported but not penalised).
    N, prior, solver : int, str, str
        Leading singular values left unpenalised; ``organic``, ``weighted``, ``nuclear`` or
        ``none``; ``bilinear``, ``admm`` or ``pseudo_inverse``.
    history : dict of ndarrays
        Per iteration (solver-specific keys, always ``cost``).
    n_iter, converged, objective : int, bool, float
    optimality : float
        The solver's measure of optimality at the end: the bilinear solver's relative
        gradient norm (:attr:`grad_norm`), the ADMM's residual ``max |X# - Phi(X)|``, 0 for
        the pseudo-inverse.
    params : dict
        What the solver computed besides (its rank rule, scale, constants).
    mu, noise, wnn_objective : float, optional
        The bilinear solver's balance, the noise level it came from and its weighted
        nuclear norm objective (Eq. 10 at its answer).
    """

    shapes: np.ndarray
    X_init: np.ndarray
    X_init_singular_values: np.ndarray
    theta: Optional[np.ndarray]
    N: int
    prior: str
    solver: str = ""
    history: dict = field(default_factory=dict)
    n_iter: int = 0
    converged: bool = False
    objective: float = float("nan")
    optimality: float = float("nan")
    params: dict = field(default_factory=dict)
    mu: Optional[float] = None
    noise: Optional[float] = None
    wnn_objective: Optional[float] = None

    @property
    def grad_norm(self):
        """The bilinear solver's relative gradient norm (None for the other solvers)."""
        return self.optimality if self.solver == "bilinear" else None
