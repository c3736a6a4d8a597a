"""The public entry point: ``reconstruct(W, K, method=...)``, and its result type.

``reconstruct`` is the composition of the stages (``docs/architecture.md``), each run with
its typed settings (:mod:`nrsfm.settings`):

    W --check--> [completion] --> measure (centre, scale, rank-3K SVD)
      --> rotations (RotationSettings) --> shape (ShapeSettings) --> diagnostics
"""

from __future__ import annotations

import sys
import time
import warnings
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .diagnostics import NRSfMWarning, diagnose
from .metrics import depth_amplification
from .settings import METHODS, Settings, method_settings
from .stages.completion import MAX_GAIN, complete, fill_gain
from .stages.fill import SPREAD_MAX, fill_unseen
from .stages.measurement import Factorization, measure, power_of_two_scale
from .stages.selection import shape_for_rotations
from .stages.shape import ShapeResult
from .validation import blas_threads, check_problem

__all__ = ["METHODS", "Reconstruction", "reconstruct"]


@dataclass
class Reconstruction:
    """Result of :func:`reconstruct`, with the intermediates of every stage.

    Attributes
    ----------
    rotations : (F, 3, 3) ndarray
        Camera rotation per frame (world to camera).
    shapes : (F, 3, P) ndarray
        3D shape X_f per frame in the world frame of the recovered cameras, in the input's
        units: ``rotations[f, :2] @ shapes[f]`` approximates the centred ``W_f`` (the
        factorisation's X, as in BMM). :attr:`camera_shapes` gives ``R_f X_f``.
    method, K : str, int
    W : (2F, P) ndarray
        The row-centred input, in the input's units.
    row_means : (2F,) ndarray
        What centring removed (per-frame translation).
    scale : float
        ``||W||_F / 170``: the stages ran on ``W / scale`` (:mod:`nrsfm.stages.measurement`).
    factorization : Factorization
        Rank-3K SVD of ``W / scale`` (``M_hat``, ``B_hat``, singular values).
    rotation_stage : object or None
        The rotation stage's result (triplets G^k, per-triplet rotations R^k,
        registration, filtering, averaging), None when rotations were given.
    shape_stage : ShapeResult
        The shape stage's result (X_init, weights, history, objective, optimality), in the
        units of ``W / scale``.
    X_init : (F, 3, P) ndarray
        Pseudo-inverse shape ``pinv(R) W`` in the input's units.
    params : dict
        Every setting used (``params["settings"]``: the typed :class:`nrsfm.settings.Settings`).
    timings : dict
        Seconds per stage.
    diagnostics : nrsfm.diagnostics.Diagnostics or None
        Measured quality signals and the flags raised (see :mod:`nrsfm.diagnostics`).
    observed : (F, P) bool ndarray or None
        Where the input had missing observations: True where a point was observed in a
        frame (None for complete input).
    W_completed : (2F, P) ndarray or None
        Where the input had missing observations: the completed W (input units, before
        centring) that the pipeline ran on.
    completion : nrsfm.stages.completion.Completion or None
        Where the input had missing observations: the completion stage's result
        (:func:`nrsfm.stages.completion.complete`: the method that ran, lags, iterations).
    fill_spread : (P,) ndarray or None
        Where the :attr:`undetermined` points were filled from their neighbours
        (``MeasurementSettings.fill = "neighbours"``;
        :func:`nrsfm.stages.fill.fill_unseen`): each one's fill reliability, how far its
        four fills stray from their median in units of the shapes' RMS radius (larger:
        less reliable; NaN for the points not filled so). :attr:`shape_stage` keeps the
        shape stage's own fill.
    """

    rotations: np.ndarray
    shapes: np.ndarray
    method: str
    K: int
    W: np.ndarray
    row_means: np.ndarray
    scale: float
    factorization: Factorization
    X_init: np.ndarray
    rotation_stage: object = None
    shape_stage: ShapeResult = None
    params: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    diagnostics: object = None
    observed: np.ndarray = None
    W_completed: np.ndarray = None
    completion: object = None
    fill_spread: np.ndarray = None

    @cached_property
    def fill_gain(self):
        """(P,) ndarray or None: where the input had missing observations, how much each
        track's filled entries amplify measurement noise under the rank-3K motion
        ``M_hat`` that the later stages used
        (:func:`nrsfm.stages.completion.fill_gain`); see :attr:`undetermined`."""
        if self.observed is None:
            return None
        return fill_gain(self.factorization.M_hat, self.observed)

    @property
    def undetermined(self):
        """(P,) bool: tracks seen in too few frames for the data to pin down their 3D
        (fill gain above :data:`nrsfm.stages.completion.MAX_GAIN`); all False for
        complete input. Their shapes are filled, but are an extrapolation."""
        if self.fill_gain is None:
            return np.zeros(self.n_points, bool)
        return self.fill_gain > MAX_GAIN

    @property
    def unreliable(self):
        """(P,) bool: tracks whose 3D in the frames they were not seen in may be far off:
        :attr:`undetermined` ones, except those filled from their neighbours
        (``MeasurementSettings.fill = "neighbours"``, the default) whose fills agree (stray
        from their median by at most :data:`nrsfm.stages.fill.SPREAD_MAX` of the shapes'
        RMS radius, :attr:`fill_spread`); all False for complete input."""
        if self.fill_spread is None:
            return self.undetermined
        return self.undetermined & ~(self.fill_spread <= SPREAD_MAX)

    @property
    def n_frames(self):
        return self.shapes.shape[0]

    @property
    def n_points(self):
        return self.shapes.shape[2]

    @property
    def camera_shapes(self):
        """(F, 3, P) shapes in each frame's camera frame, ``R_f X_f`` (x, y match W_f)."""
        return self.rotations @ self.shapes

    def reprojection_error(self):
        """RMS of ``W_f - R_f X_f`` over all entries, in the input's units."""
        proj = (self.rotations[:, :2] @ self.shapes).reshape(self.W.shape)
        p2 = power_of_two_scale(self.W)         # exact rescaling: no overflow/underflow
        d = self.W / p2 - proj / p2
        return float(np.sqrt(np.mean(d ** 2)) * p2)

    def errors(self, shapes_gt=None, rotations_gt=None, world_shapes_gt=None):
        """Benchmark errors against ground truth.

        Parameters
        ----------
        shapes_gt : (F, 3, P) ndarray, optional
            Ground truth in the camera frame (``Sequence.shapes``).
        rotations_gt : (F, 3, 3) ndarray, optional
            Ground-truth cameras (``Sequence.rotations``).
        world_shapes_gt : (F, 3, P) ndarray, optional
            Ground truth in its world frame; by default ``R_gt' shapes_gt``.

        Returns
        -------
        dict
            ``e3d`` (per-frame similarity alignment, frame-independent), ``e3d_akhter``
            and ``e_R`` where rotations are given.

        Notes
        -----
        ``e3d_akhter`` uses one global alignment, so the frame matters. Where the
        ground-truth cameras move (the Akhter sequences) the world-frame shapes are
        compared, as Akhter's and Dai's code do. Where the ground-truth camera is fixed
        (dance; face, walking and shark, whose rigid motion is inside the shape) the
        factorisation puts the object's rigid motion into the estimated cameras, so the
        camera-frame shapes ``R_f X_f`` are compared with the camera-frame ground truth.
        With this rule our BMM lands next to Dai's own code (``peer_bmm_octave``) on
        both kinds of sequence.
        """
        from .metrics import e3d, e3d_akhter, rotation_error

        out = {}
        if shapes_gt is not None:
            out["e3d"] = e3d(self.shapes, shapes_gt)
            fixed = rotations_gt is None or np.allclose(rotations_gt, rotations_gt[:1],
                                                        atol=1e-12)
            if world_shapes_gt is not None:
                out["e3d_akhter"] = e3d_akhter(self.shapes, world_shapes_gt)
            elif fixed:
                out["e3d_akhter"] = e3d_akhter(self.camera_shapes, shapes_gt)
            else:
                world = np.asarray(rotations_gt).transpose(0, 2, 1) @ shapes_gt
                out["e3d_akhter"] = e3d_akhter(self.shapes, world)
        if rotations_gt is not None:
            out["e_R"] = rotation_error(self.rotations, rotations_gt)
        return out

    def summary(self):
        """A few lines describing the run: sizes, fit, missing data, the diagnostics' notes
        (no action needed) and warnings, time."""
        F, P = self.n_frames, self.n_points
        lines = [f"nrsfm {self.method}: F={F} frames, P={P} points, K={self.K}, "
                 f"scale={self.scale:.4g}",
                 f"  reprojection RMS {self.reprojection_error():.3g} (input units)"]
        if self.observed is not None:
            c = self.completion
            lines.append(f"  missing data: {100 * (1 - self.observed.mean()):.1f} % of the "
                         f"observations filled ({c.method}, lags {c.lags}, "
                         f"{c.n_iter} iterations); {int(self.undetermined.sum())} of {P} "
                         f"tracks undetermined (seen in too few frames: their 3D is an "
                         f"extrapolation), {int(self.unreliable.sum())} of them unreliable "
                         f"(the fills made from their neighbours and the model disagree)")
        if self.diagnostics is not None:            # notes need no action; flags warned
            lines += [f"  note: {n}" for n in self.diagnostics.notes]
            lines += [f"  WARNING: {f}" for f in self.diagnostics.flags]
        t = ", ".join(f"{k} {v:.3f}s" for k, v in self.timings.items())
        lines.append(f"  time: {t}")
        return "\n".join(lines)


def _progress_printer(progress):
    if callable(progress):
        return progress
    if progress:
        return lambda msg: print(f"[nrsfm] {msg}", file=sys.stderr, flush=True)
    return lambda msg: None


@contextmanager
def _timed(timings, name):
    t0 = time.perf_counter()
    yield
    timings[name] = time.perf_counter() - t0


def reconstruct(W, K, method=None, rotations=None, *, seed=0, rotation_options=None,
                shape_options=None, shape_solver=None, progress=False,
                blas_thread_limit=1, missing=None, settings=None):
    """Recover camera rotations and per-frame 3D shapes from 2D tracks.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Measurements: rows ``x_f, y_f`` interleaved, or per-frame tracks. Rows are
        centred here (per-frame translation is removed).
    K : int
        Number of shape bases, ``1 <= K`` and ``3K <= min(2F, P - 1)``.
    method : {"organic", "bmm", "wnn", "pseudo_inverse"}, optional
        ``organic`` (default): all K corrective triplets, registered, filtered and
        L1-averaged rotations; shape by the partial-sum weighted nuclear norm (N = 1),
        minimised by ``shape_solver``.
        ``bmm``: Dai et al.'s baseline (first triplet, plain nuclear norm).
        ``wnn``: the averaged rotations with a weighted nuclear norm on every singular
        value (N = 0). ``pseudo_inverse``: rank-K truncation of ``pinv(R) W``.
    rotations : (F, 3, 3) array_like, optional
        Known camera rotations; the rotation stage is then skipped.
    seed : int
        Seed for every random choice (results are deterministic for a given seed).
    rotation_options : dict, optional
        Fields of :class:`nrsfm.settings.RotationSettings` that override the method's
        preset (not ``strategy``, which the method fixes; research strategies run with
        ``settings=nrsfm.research.research_settings(...)``).
    shape_options : dict, optional
        Fields of the solver's settings (:class:`nrsfm.settings.BilinearSettings`,
        :class:`~nrsfm.settings.AdmmSettings`, :class:`~nrsfm.settings.ClosedFormSettings`,
        :class:`~nrsfm.settings.ConstrainedSettings`).
    shape_solver : str, optional
        A solver registered in :data:`nrsfm.stages.shape.SOLVERS`: ``bilinear`` (default): the factored weighted nuclear norm minimised to a
        stationary point (:mod:`nrsfm.stages.shape.bilinear`); ``admm``: the paper's
        continuation ADMM (:mod:`nrsfm.stages.shape.admm`); ``closed_form``: the exact
        rank-K solution (no prior); ``constrained``: the prior's norm with W fitted to
        within its noise (:mod:`nrsfm.stages.shape.constrained`, ``docs/shape_constrained.md``).
        See ``docs/shape_stage.md`` for the measurements behind the default.
    progress : bool or callable
        Print stage progress to stderr (or call ``progress(message)``).
    blas_thread_limit : int or None
        BLAS threads while the solvers run (the matrices are small: one is fastest).
    missing : {"complete", "error"}
        What to do with missing observations: NaN in W or tracks (a point counts as missing
        in a frame when either coordinate is NaN), or the mask of a
        ``numpy.ma.MaskedArray``. ``complete`` (default): fill W by low-rank completion
        (:func:`nrsfm.stages.completion.complete`) and run the pipeline on it; the result
        keeps ``completion``, ``observed``, ``W_completed`` and the tracks the data leave
        ``undetermined``. The completion is ``settings.measurement.completion``, by
        default ``"auto"``: soft-impute of the time-lagged W where the lags rule asks for
        lags (few points per frame for the rank 3K: MoCap-sized W), the rank-3K
        factorisation of the observed entries elsewhere (dense tracks);
        ``"factorisation"`` or ``"soft_impute"`` force one. ``error``: refuse.
    settings : nrsfm.settings.Settings, optional
        Every setting, typed. It replaces ``method``, ``shape_solver``, ``missing``,
        ``rotation_options`` and ``shape_options``: giving any of them beside it is a
        ValueError (put them into the settings instead).

    Returns
    -------
    Reconstruction

    Raises
    ------
    ValueError
        Bad shapes, non-finite input, K out of range (including 3K above
        ``min(2F, P - 1)``, the largest rank of a row-centred W), unknown method, solver
        or option, an option beside ``settings=``, bad rotations; missing observations with ``missing="error"``; a frame
        or point with too few observations to be determined (named in the message).

    Warns
    -----
    nrsfm.NRSfMWarning
        When a quality signal of the run crosses its threshold (``result.diagnostics``).
    """
    settings = _settings(settings, method=method, shape_solver=shape_solver,
                         missing=missing, rotation_options=rotation_options,
                         shape_options=shape_options)
    # every input check before any computation (the completion can take a while)
    W, K, rotations = check_problem(W, K, rotations, settings.measurement.missing)
    say = _progress_printer(progress)
    timings = {}
    with blas_threads(blas_thread_limit) if blas_thread_limit else nullcontext():
        completion = None
        if np.isnan(W).any():
            with _timed(timings, "completion"):
                completion = complete(W, K, settings.measurement)
            W = completion.W
        with _timed(timings, "factorize"):
            meas = measure(W, K)
        fact = meas.factorization
        say(f"rank-{3 * K} factorisation of {W.shape[0]}x{W.shape[1]} W: residual "
            f"{fact.residual:.3g}")
        rotation_stage = None
        if rotations is None:
            with _timed(timings, "rotations"):
                rotation_stage = settings.rotation.estimate(fact.M_hat, K, seed, say)
            rotations = rotation_stage.rotations
        with _timed(timings, "shape"):
            rotations, shape_stage = shape_for_rotations(meas.Wn, rotations, K, rotation_stage,
                                                         settings.shape, say)
    amp = (depth_amplification(rotations, shape_stage.shapes, K)
           if settings.shape.solver.estimates_depth else None)
    diagnostics = diagnose(meas.Wn, K, fact, rotation_stage, seed, depth_amplification=amp)
    if diagnostics.flags:
        warnings.warn(diagnostics.message, NRSfMWarning, stacklevel=2)
    params = settings.params(K, seed, meas.scale, rotations_given=rotation_stage is None)
    shapes = meas.restore(shape_stage.shapes)
    if not (np.all(np.isfinite(shapes)) and np.isfinite(meas.scale)):
        raise ValueError(f"the shapes overflow in the input's units (max|W| = "
                         f"{np.abs(W).max():.3g}); rescale W")
    spread = None
    if completion is not None and settings.measurement.fill == "neighbours":
        with _timed(timings, "fill"):
            undetermined = fill_gain(fact.M_hat, completion.observed) > MAX_GAIN
            shapes, spread = fill_unseen(shapes, completion.observed, undetermined)
    return Reconstruction(rotations=rotations, shapes=shapes, method=settings.method, K=K,
                          W=meas.W, row_means=meas.row_means, scale=meas.scale,
                          factorization=fact, X_init=meas.restore(shape_stage.X_init),
                          rotation_stage=rotation_stage, shape_stage=shape_stage,
                          params=params, timings=timings, diagnostics=diagnostics,
                          observed=None if completion is None else completion.observed,
                          W_completed=None if completion is None else completion.W,
                          completion=completion, fill_spread=spread)


def _settings(settings, **keywords):
    """The run's Settings: ``settings`` as given, or built by :func:`method_settings` from
    the keywords given (its defaults for those that are None); a keyword beside
    ``settings`` is refused."""
    if settings is None:
        return method_settings(**{k: v for k, v in keywords.items() if v is not None})
    if not isinstance(settings, Settings):
        raise ValueError(f"settings must be an nrsfm.settings.Settings; got {settings!r}")
    beside = sorted(k for k, v in keywords.items() if v is not None)
    if beside:
        raise ValueError(f"settings= replaces {', '.join(sorted(keywords))}; got "
                         f"{', '.join(beside)} beside it, which would be ignored: put them "
                         f"into the settings (e.g. dataclasses.replace(settings.shape, "
                         f"solver=...))")
    return settings
