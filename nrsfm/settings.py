"""Typed settings of every stage, and the presets of the four methods.

One frozen dataclass per stage, each validated when it is built (a bad value raises a
ValueError naming it), so that a parameter can be followed from ``reconstruct`` into the
solver that uses it:

* :class:`MeasurementSettings`: what to do with missing observations, and how to complete
  them.
* :class:`RotationSettings`: the production rotation stage (``organic`` and ``bmm``);
  :class:`RotationAblationSettings` adds the research variants run by
  :mod:`nrsfm.ablation`.
* :class:`ShapeSettings`: the prior and one solver settings object,
  :class:`AdmmSettings`, :class:`BilinearSettings`, :class:`ClosedFormSettings`,
  :class:`ConstrainedSettings` or :class:`PseudoInverseSettings` (the solvers are
  registered in :mod:`nrsfm.stages.shape`).
* :class:`Settings`: the three together, :func:`method_settings` the presets
  (``organic``, ``bmm``, ``wnn``, ``pseudo_inverse``) with dict options converted.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar, Optional

from .validation import check_integer, check_positive

__all__ = ["AdmmSettings", "BilinearSettings", "ClosedFormSettings", "ConstrainedSettings",
           "METHODS",
           "MeasurementSettings", "PRIORS", "PseudoInverseSettings",
           "RotationAblationSettings", "RotationSettings", "Settings", "ShapeSettings",
           "SolverSettings", "method_settings", "rotation_settings"]

#: method -> (rotation strategy, shape prior). ``None`` prior: rank-K pseudo-inverse shape.
METHODS = {
    "organic": ("organic", "organic"),        # all K triplets, averaged; partial-sum WNN
    "bmm": ("bmm", "nuclear"),                 # Dai et al.: first triplet, nuclear norm
    "wnn": ("organic", "weighted"),           # weighted nuclear norm over all singular values
    "pseudo_inverse": ("organic", None),      # rank-K truncated pinv(R) W
}

#: Shape priors: prior -> N, the leading singular values left unpenalised (Eq. 10).
PRIORS = {"organic": 1, "weighted": 0, "nuclear": 0}


def _one_of(name, value, allowed):
    if value not in allowed:
        raise ValueError(f"{name} must be one of {list(allowed)}; got {value!r}")


def _flag(name, value):
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be True or False; got {value!r}")


def _fraction(name, value):
    if not (check_positive(name, value) <= 1.0):
        raise ValueError(f"{name} must be in (0, 1]; got {value!r}")


# ----------------------------------------------------------------------------- measurement
# the completion stage's own settings, in its package (one table of allowed values there)
from .stages.completion.settings import MeasurementSettings  # noqa: E402


# ----------------------------------------------------------------------------- rotations
@dataclass(frozen=True)
class RotationSettings:
    """Rotation stage of the ``organic`` and ``bmm`` methods (:mod:`nrsfm.stages.rotations`).

    Attributes
    ----------
    strategy : {"organic", "bmm"}
        ``organic``: the best triplet plus K - 1 triplets refined on temporal windows,
        registered, filtered, L1-averaged (the paper's averaging). ``bmm``: the best
        triplet only (Dai et al.).
    n_triplets : int or None
        Triplets averaged (default K).
    window : float
        Window length of the K - 1 window triplets, a fraction of F.
    delta : float
        Filter threshold (rad, geodesic angle; paper: 0.05).
    filter_against : {"average", "reference"} or None
        Filter the samples against their L1 average, the reference triplet (paper), or not.
    determined : bool
        W of numerical rank r < 3K (singular values below 1e-6 s_1): solve the triplets in
        the determined r-dimensional subspace of the motion factor
        (:mod:`nrsfm.stages.rotation_select`); False: search all 3K rows of G.
    max_iter, eps : int, float
        Weiszfeld iterations and step tolerance of the L1 average (Alg. 1).
    hits, max_starts : int
        Stopping rule of the triplet search (:func:`nrsfm.stages.corrective.search_triplet`).
    sdp_solver : {"admm", "cvxpy"}
        Solver of the relaxation that gives the first starts.
    refine : {"lm", "minpack", "lbfgs"}
        Refinement of the triplets.
    """

    STRATEGIES: ClassVar[tuple] = ("organic", "bmm")
    FILTERS: ClassVar[tuple] = ("average", "reference", None)

    strategy: str = "organic"
    n_triplets: Optional[int] = None
    window: float = 0.9
    delta: float = 0.05
    filter_against: Optional[str] = "average"
    determined: bool = True
    max_iter: int = 50
    eps: float = 1e-3
    hits: int = 2
    max_starts: int = 40
    sdp_solver: str = "admm"
    refine: str = "lm"

    def __post_init__(self):
        _one_of("rotation strategy", self.strategy, self.STRATEGIES)
        if self.n_triplets is not None:
            check_integer(self.n_triplets, "n_triplets", minimum=1)
        _fraction("window", self.window)
        check_positive("delta", self.delta)
        _one_of("filter_against", self.filter_against, self.FILTERS)
        _flag("determined", self.determined)
        check_integer(self.max_iter, "max_iter", minimum=1)
        check_positive("eps", self.eps, strict=False)
        check_integer(self.hits, "hits", minimum=1)
        check_integer(self.max_starts, "max_starts", minimum=1)
        _one_of("sdp_solver", self.sdp_solver, ("admm", "cvxpy"))
        _one_of("refine", self.refine, ("lm", "minpack", "lbfgs"))

    @classmethod
    def preset(cls, strategy="organic"):
        """The settings of a strategy (chosen by the measurements in
        ``docs/rotation_stage.md``)."""
        if strategy == "bmm":
            return cls(strategy="bmm", window=0.5, filter_against="reference")
        return cls(strategy=strategy)


@dataclass(frozen=True)
class RotationAblationSettings(RotationSettings):
    """The rotation stage with the research variants no method uses by default
    (run by :func:`nrsfm.ablation.estimate_rotations_ablation`).

    Attributes
    ----------
    strategy : {"organic", "family", "bmm", "literal", "multistart", "windows",
                "bootstrap"}
        See :data:`nrsfm.ablation.STRATEGIES`.
    combine : {"family"} or None
        Maximum-ratio combination of the triplet family consistent with the average
        (:mod:`nrsfm.ablation_family`).
    combine_iter, combine_tol : int, float
        At most ``combine_iter`` family <-> rotation alternations, stopped when the
        median per-frame change (rad) is below ``combine_tol``.
    filter_metric : {"angle", "chordal"}
    coef_gate : float
        Drop samples with ``|c_fk| < coef_gate * median_f |c_fk|``.
    coef_weights : bool
        Weight samples by ``|c_fk| / median_f |c_fk|`` in the average.
    subsets : {"windows", "bootstrap", "random"}
        Frame subsets of the K - 1 extra triplets.
    starts : {"search", "relaxed", "dai", "columns", "multistart"}
        Starts of the triplet refinement (:func:`nrsfm.ablation.corrective_triplets_from`).
    lam : float
        Penalty of :func:`nrsfm.stages.corrective.penalized_gram` (non-search starts).
    gram : {"penalized", "nuclear"}
        Relaxation whose column blocks ``starts="columns"`` refines.
    n_random, n_full, screen_frames, screen_iter : int
        The ``multistart`` starts.
    average : {"l1", "chordal"}
    refit : bool
        Project the average back onto the single triplet that fits it best.
    """

    STRATEGIES: ClassVar[tuple] = ("organic", "family", "bmm", "literal", "multistart",
                                   "windows", "bootstrap")
    combine: Optional[str] = None
    combine_iter: int = 5
    combine_tol: float = 1e-3
    filter_metric: str = "angle"
    coef_gate: float = 0.0
    coef_weights: bool = False
    subsets: str = "windows"
    starts: str = "search"
    lam: float = 1e2
    gram: str = "penalized"
    n_random: int = 32
    n_full: int = 4
    screen_frames: int = 80
    screen_iter: int = 30
    average: str = "l1"
    refit: bool = False

    def __post_init__(self):
        super().__post_init__()
        _one_of("combine", self.combine, ("family", None))
        check_integer(self.combine_iter, "combine_iter", minimum=1)
        check_positive("combine_tol", self.combine_tol, strict=False)
        _one_of("filter_metric", self.filter_metric, ("angle", "chordal"))
        check_positive("coef_gate", self.coef_gate, strict=False)
        _one_of("subsets", self.subsets, ("windows", "bootstrap", "random"))
        _one_of("starts", self.starts, ("search", "relaxed", "dai", "columns", "multistart"))
        check_positive("lam", self.lam)
        _one_of("gram", self.gram, ("penalized", "nuclear"))
        for name in ("n_random", "n_full", "screen_frames", "screen_iter"):
            check_integer(getattr(self, name), name, minimum=1)
        _one_of("average", self.average, ("l1", "chordal"))

    @classmethod
    def preset(cls, strategy="organic"):
        """Research strategies' settings (``docs/rotation_stage.md``)."""
        variants = {
            "organic": dict(window=0.9, filter_against="average"),
            "family": dict(window=0.9, filter_against="average", combine="family"),
            "bmm": dict(window=0.5, filter_against="reference"),
            "windows": dict(window=0.5, filter_against=None),
            "bootstrap": dict(subsets="bootstrap", window=0.5, filter_against="average"),
            "literal": dict(filter_against="reference", gram="nuclear"),
            "multistart": dict(filter_against="reference", starts="multistart"),
        }
        _one_of("rotation strategy", strategy, cls.STRATEGIES)
        return cls(strategy=strategy, **dict(dict(combine=None, window=0.5),
                                             **variants[strategy]))


def _field_names(cls):
    return {f.name for f in dataclasses.fields(cls)}


def rotation_settings(strategy="organic", **options):
    """Rotation settings from a strategy and option values (the dict form).

    The production :class:`RotationSettings` when the strategy and every option are
    production ones, :class:`RotationAblationSettings` otherwise.

    Raises
    ------
    ValueError
        Unknown option (the known ones are named) or bad value.
    """
    unknown = set(options) - _field_names(RotationAblationSettings)
    if unknown:
        raise ValueError(f"unknown rotation options {sorted(unknown)}; expected some of "
                         f"{sorted(_field_names(RotationAblationSettings))}")
    production = strategy in RotationSettings.STRATEGIES and \
        set(options) <= _field_names(RotationSettings)
    cls = RotationSettings if production else RotationAblationSettings
    return dataclasses.replace(cls.preset(strategy), **options)


# ----------------------------------------------------------------------------- shape
class SolverSettings:
    """Base of the shape solvers' settings; ``name`` is the solver's registered name."""

    name: ClassVar[str] = ""


@dataclass(frozen=True)
class AdmmSettings(SolverSettings):
    """The paper's continuation ADMM (:mod:`nrsfm.stages.shape.admm`).

    Attributes
    ----------
    N : int or None
        Leading singular values left unpenalised; default from the prior (:data:`PRIORS`).
    mu : float
        Weight of the regulariser (paper: 1).
    rho0, lam, rho_max : float
        Initial penalty, its growth per iteration (> 1) and its cap (paper: 1e-4, 1.1, 1e10).
    eps : float
        Stop when ``max |X# - Phi(X)| < eps`` (paper: 1e-10).
    xi, gamma : float
        Eq. (9); ``xi`` defaults to ``5e-3 sqrt(sigma_1(X_init#))``.
    max_iter : int
    init : {"rank_k", "full"}
    output : {"X", "X_sharp"}
    """

    name: ClassVar[str] = "admm"
    N: Optional[int] = None
    mu: float = 1.0
    rho0: float = 1e-4
    lam: float = 1.1
    rho_max: float = 1e10
    eps: float = 1e-10
    xi: Optional[float] = None
    gamma: float = 1e-6
    max_iter: int = 1000
    init: str = "rank_k"
    output: str = "X"

    def __post_init__(self):
        if self.N is not None:
            check_integer(self.N, "N", minimum=0)
        check_positive("mu", self.mu, strict=False)
        for name in ("rho0", "rho_max", "lam", "gamma"):
            check_positive(name, getattr(self, name))
        check_positive("eps", self.eps, strict=False)
        if self.lam <= 1:
            raise ValueError(f"lam must be > 1 (rho grows each iteration); got {self.lam}")
        if self.xi is not None:
            check_positive("xi", self.xi)
        check_integer(self.max_iter, "max_iter", minimum=1)
        _one_of("init", self.init, ("full", "rank_k"))
        _one_of("output", self.output, ("X", "X_sharp"))


@dataclass(frozen=True)
class BilinearSettings(SolverSettings):
    """The factored weighted nuclear norm (:mod:`nrsfm.stages.shape.bilinear`).

    Attributes
    ----------
    rank : int or None
        Factor rank r (default K).
    mu_factor : float
        ``mu = mu_factor * noise_level(W, K) * (sqrt(F) + sqrt(3P))`` (measured: 0.03).
    mu : float or None
        Override ``mu`` (W's units).
    min_mu : float
        ``mu`` floor, relative to ``||W||_F``, when the rank-K fit is not unique.
    init : {"closed_form", "rank_k"}
    gtol : float
        Stop when the relative gradient norm is at most gtol.
    max_iter : int
        Cap on L-BFGS iterations (0: the start only).
    """

    name: ClassVar[str] = "bilinear"
    rank: Optional[int] = None
    mu_factor: float = 0.03
    mu: Optional[float] = None
    min_mu: float = 1e-5
    init: str = "closed_form"
    gtol: float = 1e-6
    max_iter: int = 3000

    def __post_init__(self):
        if self.rank is not None:
            check_integer(self.rank, "rank", minimum=1)
        for name in ("mu_factor", "min_mu", "gtol"):
            check_positive(name, getattr(self, name), strict=False)
        if self.mu is not None:
            check_positive("mu", self.mu, strict=False)
        _one_of("init", self.init, ("closed_form", "rank_k"))
        check_integer(self.max_iter, "max_iter", minimum=0)


@dataclass(frozen=True)
class ClosedFormSettings(SolverSettings):
    """The exact rank-K solution (no prior), reported with the bilinear solver's measures.

    Attributes
    ----------
    gtol : float
        Tolerance for ``converged`` (relative gradient norm of the plain rank-K fit).
    """

    name: ClassVar[str] = "closed_form"
    gtol: float = 1e-6

    def __post_init__(self):
        check_positive("gtol", self.gtol, strict=False)


@dataclass(frozen=True)
class PseudoInverseSettings(SolverSettings):
    """Rank-K truncation of ``pinv(R) W`` (paper Table 1; no options)."""

    name: ClassVar[str] = "pseudo_inverse"


@dataclass(frozen=True)
class ConstrainedSettings(SolverSettings):
    """Organic norm, W fitted to within its noise (:mod:`nrsfm.stages.shape.constrained`).

    Attributes
    ----------
    eps : float or None
        Residual bound ``||W - R X||_F <= eps`` in W's units (default: the noise norm of W,
        :func:`nrsfm.stages.shape.constrained.residual_bound`).
    rho0, lam, rho_max : float
        Initial ADMM penalty (times ``1 / sigma_1(X_init#)``), its growth per iteration
        (> 1), its cap.
    tol : float
        Stop the ADMM when ``||Y - X#||_F < tol sigma_1(X_init#)``.
    max_iter : int
        Cap on ADMM iterations.
    polish : bool
        Polish the ADMM's end point into a KKT point of the constrained problem.
    gtol, rtol : float
        The polish's tolerances: relative gradient norm and ``|log(residual / eps)|``.
    polish_max_iter : int
        Cap on the polish's L-BFGS iterations.
    rank : int or None
        Factor rank of the polish (default: the larger of 3K and the ADMM point's rank).
    """

    name: ClassVar[str] = "constrained"
    eps: Optional[float] = None
    rho0: float = 1.0
    lam: float = 1.1
    rho_max: float = 1e10
    tol: float = 1e-8
    max_iter: int = 1000
    polish: bool = True
    gtol: float = 1e-8
    rtol: float = 1e-5
    polish_max_iter: int = 20000
    rank: Optional[int] = None

    def __post_init__(self):
        if self.eps is not None:
            check_positive("eps", self.eps, strict=False)
        for name in ("rho0", "rho_max", "tol", "gtol", "rtol"):
            check_positive(name, getattr(self, name))
        if not self.lam > 1:
            raise ValueError(f"lam must be > 1 (rho grows each iteration); got {self.lam!r}")
        check_integer(self.max_iter, "max_iter", minimum=1)
        check_integer(self.polish_max_iter, "polish_max_iter", minimum=1)
        _flag("polish", self.polish)
        if self.rank is not None:
            check_integer(self.rank, "rank", minimum=1)


@dataclass(frozen=True)
class ShapeSettings:
    """Shape stage (:mod:`nrsfm.stages.shape`).

    Attributes
    ----------
    prior : {"organic", "weighted", "nuclear"} or None
        None only with :class:`PseudoInverseSettings` or :class:`ClosedFormSettings`.
    solver : SolverSettings
        The solver and its typed settings.
    select_rotations : bool
        When the rotation stage ran: solve the shape with the stage's rotations and with
        its best single triplet's, and keep the lower shape objective
        (:func:`nrsfm.stages.rotation_select.select_by_shape_objective`; issue 18). False:
        the stage's rotations only.
    """

    prior: Optional[str] = "organic"
    solver: SolverSettings = BilinearSettings()
    select_rotations: bool = True

    def __post_init__(self):
        _one_of("shape prior", self.prior, tuple(PRIORS) + (None,))
        _flag("select_rotations", self.select_rotations)
        if not isinstance(self.solver, SolverSettings):
            raise ValueError(f"solver must be a SolverSettings (e.g. BilinearSettings()); "
                             f"got {self.solver!r}")
        if self.prior is None and self.solver.name not in ("pseudo_inverse", "closed_form"):
            raise ValueError(f"the {self.solver.name} solver needs a prior; got None")


# ----------------------------------------------------------------------------- methods
@dataclass(frozen=True)
class Settings:
    """Every setting of one ``reconstruct`` run."""

    method: str = "organic"
    measurement: MeasurementSettings = MeasurementSettings()
    rotation: RotationSettings = RotationSettings()
    shape: ShapeSettings = ShapeSettings()

    def __post_init__(self):
        _one_of("method", self.method, tuple(METHODS))


def solver_settings(name, options=None):
    """Settings of a registered shape solver from a dict of options.

    Raises
    ------
    ValueError
        Unknown solver, or an option the solver does not take (its options are named).
    """
    from .stages.shape import SOLVERS

    if name not in SOLVERS:
        raise ValueError(f"unknown shape_solver {name!r}; expected one of {list(SOLVERS)}")
    cls = SOLVERS[name].settings
    options = dict(options or {})
    unknown = set(options) - _field_names(cls)
    if unknown:
        raise ValueError(f"unknown options {sorted(unknown)} for shape_solver {name!r}; "
                         f"it takes {sorted(_field_names(cls))}")
    return cls(**options)


def method_settings(method="organic", shape_solver="bilinear", rotation_options=None,
                    shape_options=None, missing="complete"):
    """The preset of a method, with dict options converted into the typed settings.

    Parameters
    ----------
    method : {"organic", "bmm", "wnn", "pseudo_inverse"}
    shape_solver : str
        A solver registered in :data:`nrsfm.stages.shape.SOLVERS` (ignored by
        ``pseudo_inverse``, whose shape is the rank-K truncation).
    rotation_options : dict, optional
        Fields of :class:`RotationSettings` (or :class:`RotationAblationSettings`),
        ``strategy`` included; they override the method's preset.
    shape_options : dict, optional
        Fields of the solver's settings type.
    missing : {"complete", "error"}

    Returns
    -------
    Settings
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {sorted(METHODS)}")
    strategy, prior = METHODS[method]
    options = dict(rotation_options or {})
    rotation = rotation_settings(options.pop("strategy", strategy), **options)
    if prior is None:
        solver_settings(shape_solver)                   # still a known solver name
        if shape_options:
            raise ValueError(f"method 'pseudo_inverse' takes no shape options; got "
                             f"{sorted(shape_options)}")
        shape = ShapeSettings(prior=None, solver=PseudoInverseSettings())
    else:
        solver = solver_settings(shape_solver, shape_options)
        shape = ShapeSettings(prior=None if solver.name == "closed_form" else prior,
                              solver=solver)
    return Settings(method=method, measurement=MeasurementSettings(missing=missing),
                    rotation=rotation, shape=shape)
