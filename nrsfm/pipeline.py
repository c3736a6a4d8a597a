"""The public entry point: ``reconstruct(W, K, method=...)``, and its result type.

``reconstruct`` is the composition of the stages (``docs/architecture.md``), each run with
its typed settings (:mod:`nrsfm.settings`):

    W --check--> [completion] --> measure (centre, scale, rank-3K SVD)
      --> rotations (RotationSettings) --> shape (BilinearSettings / AdmmSettings)
      --> diagnostics --> [fill of the points not seen, its flag] --> one warning
"""

from __future__ import annotations

import sys
import time
import warnings
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .diagnostics import NRSfMWarning, diagnose, diagnose_fill, diagnose_perspective
from .metrics import depth_amplification
from .settings import KEYWORDS, METHODS, Settings
from .stages.completion import MAX_GAIN, complete, fill_gain
from .stages.fill import SPREAD_MAX, fill_unseen
from .stages.measurement import Factorization, measure, power_of_two_scale
from .stages.perspective import PerspectiveSettings, check_intrinsics, normalise
from .stages.perspective import refine_perspective
from .stages.rotations import RotationResult, estimate_rotations
from .stages.shape import ShapeResult, solve_pseudo_inverse
from .stages.shape.bilinear import bilinear_weights
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
    K : int
    W : (2F, P) ndarray
        The row-centred input, in the input's units.
    row_means : (2F,) ndarray
        What centring removed (per-frame translation).
    scale : float
        ``||W||_F / 170``: the stages ran on ``W / scale`` (:mod:`nrsfm.stages.measurement`).
    factorization : Factorization
        Rank-3K SVD of ``W / scale`` (``M_hat``, ``B_hat``, singular values).
    rotation_stage : RotationResult or None
        The rotation stage's result (triplets G^k, per-triplet rotations R^k,
        registration, filtering, averaging), None when rotations were given.
    shape_stage : ShapeResult
        The shape stage's result (X_init, weights, history, objective, optimality), in the
        units of ``W / scale``.
    X_init : (F, 3, P) ndarray
        Pseudo-inverse shape ``pinv(R) W`` in the input's units.
    settings : Settings
        Every setting of the run.
    seed : int
    timings : dict
        Seconds per stage.
    diagnostics : nrsfm.diagnostics.Diagnostics or None
        Measured quality signals and the flags raised (see :mod:`nrsfm.diagnostics`).
    completion : nrsfm.stages.completion.Completion or None
        Where the input had missing observations: the completion stage's result (the
        completed W in the input's units, the ``observed`` mask, the method, lags,
        iterations; :attr:`observed`, :attr:`W_completed`).
    perspective : nrsfm.stages.perspective.PerspectiveResult or None
        With ``intrinsics=``: the perspective refinement (translations, the start chosen,
        noise, prior balance, history, reprojection in pixels before and after).
    fill_spread : (P,) ndarray or None
        Where the :attr:`undetermined` points were filled from their neighbours
        (:func:`nrsfm.stages.fill.fill_unseen`): how far each one's four fills stray from
        their median, in units of the shapes' RMS radius (NaN for the points not filled so).
    """

    rotations: np.ndarray
    shapes: np.ndarray
    K: int
    W: np.ndarray
    row_means: np.ndarray
    scale: float
    factorization: Factorization
    X_init: np.ndarray
    settings: Settings
    seed: int = 0
    rotation_stage: RotationResult = None
    shape_stage: ShapeResult = None
    timings: dict = field(default_factory=dict)
    diagnostics: object = None
    completion: object = None
    fill_spread: np.ndarray = None
    perspective: object = None

    @property
    def method(self):
        return self.settings.method

    @property
    def observed(self):
        """(F, P) bool or None: True where a point was observed (None for complete input)."""
        return None if self.completion is None else self.completion.observed

    @property
    def W_completed(self):
        """(2F, P) or None: the completed W (input units, before centring) that ran."""
        return None if self.completion is None else self.completion.W

    @cached_property
    def fill_gain(self):
        """(P,) ndarray or None: how much each track's filled entries amplify measurement
        noise under ``M_hat`` (:func:`nrsfm.stages.completion.fill_gain`)."""
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
        """(P,) bool: :attr:`undetermined` tracks except those whose neighbour fills agree
        (:attr:`fill_spread` at most :data:`nrsfm.stages.fill.SPREAD_MAX`): their 3D in the
        frames they were not seen in may be far off."""
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
        """RMS of ``W_f - R_f X_f`` over all entries, in the input's units (with intrinsics:
        the image distance of the perspective projection, in pixels, over the points seen)."""
        if self.perspective is not None:
            return self.perspective.reprojection_after
        proj = (self.rotations[:, :2] @ self.shapes).reshape(self.W.shape)
        p2 = power_of_two_scale(self.W)  # exact rescaling: no overflow/underflow
        d = self.W / p2 - proj / p2
        return float(np.sqrt(np.mean(d**2)) * p2)

    def errors(self, shapes_gt=None, rotations_gt=None, world_shapes_gt=None):
        """Benchmark errors against ground truth: a dict of ``e3d`` (per-frame similarity
        alignment) and ``e3d_akhter`` given ``shapes_gt`` (F, 3, P, in the camera frame:
        ``Sequence.shapes``), ``e_R`` given ``rotations_gt`` (F, 3, 3); ``world_shapes_gt``:
        the ground truth in its world frame (default ``R_gt' shapes_gt``).

        Notes
        -----
        ``e3d_akhter`` uses one global alignment, so the frame matters: the world-frame
        shapes where the ground-truth cameras move (as Akhter's and Dai's code do), the
        camera-frame shapes ``R_f X_f`` where the ground-truth camera is fixed (the
        factorisation then puts the object's rigid motion into the cameras).
        """
        from .metrics import e3d, e3d_akhter, rotation_error

        out = {}
        if shapes_gt is not None:
            out["e3d"] = e3d(self.shapes, shapes_gt)
            fixed = rotations_gt is None or np.allclose(rotations_gt, rotations_gt[:1], atol=1e-12)
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
        """A few lines describing the run: sizes, fit, missing data, the ids of the
        diagnostics' notes (no action needed; their text is in ``diagnostics.notes``), the
        warnings in full, time."""
        F, P = self.n_frames, self.n_points
        lines = [
            f"nrsfm {self.method}: F={F} frames, P={P} points, K={self.K}, scale={self.scale:.4g}",
            f"  reprojection RMS {self.reprojection_error():.3g} (input units)",
        ]
        if self.observed is not None:
            c = self.completion
            lines.append(
                f"  missing data: {100 * (1 - self.observed.mean()):.1f} % of the "
                f"observations filled ({c.method}, lags {c.lags}, "
                f"{c.n_iter} iterations); {int(self.undetermined.sum())} of {P} "
                f"tracks undetermined (seen in too few frames: their 3D is an "
                f"extrapolation), {int(self.unreliable.sum())} of them unreliable "
                f"(the fills made from their neighbours and the model disagree)"
            )
        if self.perspective is not None:
            p = self.perspective
            lines.append(
                f"  perspective refinement: {p.start} start, {p.n_iter} iterations, "
                f"reprojection {p.reprojection_before:.3g} px (orthographic start) -> "
                f"{p.reprojection_after:.3g} px; shapes in units of each frame's centroid depth"
            )
        if self.diagnostics is not None:  # notes need no action; flags warned
            ids = [n.split(":", 1)[0] for n in self.diagnostics.notes]  # the text: .notes
            lines += [f"  notes (no action needed): {', '.join(ids)}"] if ids else []
            lines += [f"  WARNING: {f}" for f in self.diagnostics.flags]
        t = ", ".join(f"{k} {v:.3f}s" for k, v in self.timings.items())
        lines.append(f"  time: {t}")
        return "\n".join(lines)


@contextmanager
def _timed(timings, name):
    t0 = time.perf_counter()
    yield
    timings[name] = time.perf_counter() - t0


def reconstruct(
    W,
    K,
    method=None,
    rotations=None,
    *,
    shape_solver=None,
    missing=None,
    intrinsics=None,
    settings=None,
    seed=0,
    progress=False,
    blas_thread_limit=1,
):
    """Recover camera rotations and per-frame 3D shapes from 2D tracks.

    One run is configured one way: the keywords ``method``, ``shape_solver`` and
    ``missing`` (each one field of :class:`nrsfm.Settings`, :data:`nrsfm.settings.KEYWORDS`),
    or ``settings=`` with every setting.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Measurements: rows ``x_f, y_f`` interleaved, or per-frame tracks. Rows are
        centred here (per-frame translation is removed). NaN (or the mask of a
        ``numpy.ma.MaskedArray``) marks a point not seen in a frame.
    K : int
        Number of shape bases, ``1 <= K`` and ``3K <= min(2F, P - 1)``.
    method : {"organic", "bmm", "wnn", "pseudo_inverse"}, optional
        ``organic`` (default): all K corrective triplets, registered, filtered and
        L1-averaged rotations; shape by the partial-sum weighted nuclear norm (Eq. 10).
        ``bmm``: Dai et al.'s baseline (first triplet, plain nuclear norm, Eq. 7).
        ``wnn``: the averaged rotations with a weighted nuclear norm on every singular
        value (Eq. 8). ``pseudo_inverse``: rank-K truncation of ``pinv(R) W``.
    rotations : (F, 3, 3) array_like, optional
        Known camera rotations; the rotation stage is then skipped.
    shape_solver : {"bilinear", "admm"}, optional
        ``bilinear`` (default): the factored weighted nuclear norm minimised to a
        stationary point; ``admm``: the paper's continuation ADMM.
    missing : {"complete", "error"}, optional
        Missing observations: complete W by low-rank completion and run on it (default;
        the result keeps ``completion``, ``observed`` and the tracks the data leave
        ``undetermined``), or refuse.
    intrinsics : (3, 3) array_like or sequence of 3 or 4 numbers, optional
        The camera's intrinsics (pixels): a camera matrix, ``(f, cx, cy)`` or ``(fx, fy, cx,
        cy)``. Given, W is read as pixel tracks of a pinhole camera: the stages run on the
        normalised coordinates ``K_cam^-1 [u v 1]'`` and a perspective refinement follows
        (:mod:`nrsfm.stages.perspective`): ``rotations``, ``shapes`` (in units of each frame's
        centroid depth) and ``perspective`` (translations, history) are its answer, the other
        fields the orthographic start's (in normalised units). None: the orthographic camera.
    settings : nrsfm.Settings, optional
        Every setting, typed; then none of the three keywords above.
    seed : int
        Seed for every random choice (results are deterministic for a given seed).
    progress : bool or callable
        Print stage progress to stderr (or call ``progress(message)``).
    blas_thread_limit : int or None
        BLAS threads while the stages run (the matrices are small: one is fastest).

    Returns
    -------
    Reconstruction

    Raises
    ------
    ValueError
        Bad shapes, non-finite input, K out of range (including 3K above
        ``min(2F, P - 1)``, the largest rank of a row-centred W), an unknown method, solver
        or rule, a keyword beside ``settings=``, bad rotations, missing observations with
        ``missing="error"``, a frame or point with too few observations (named).

    Warns
    -----
    nrsfm.NRSfMWarning
        When a quality signal of the run crosses its threshold (``result.diagnostics``),
        tracks the fill leaves unreliable (``result.unreliable``) included: one warning
        with every flag of the run.

    Examples
    --------
    >>> import nrsfm, data_tools
    >>> seq = data_tools.make_synthetic(F=40, P=30, K=2, seed=0)
    >>> res = nrsfm.reconstruct(seq.W, 2)
    >>> res.rotations.shape, res.shapes.shape
    ((40, 3, 3), (40, 3, 30))
    >>> bool(res.errors(seq.shapes)["e3d"] < 1e-3)
    True
    """
    settings = _settings(settings, method=method, shape_solver=shape_solver, missing=missing)
    # every input check before any computation (the completion can take a while)
    W, K, rotations = check_problem(W, K, rotations, settings.measurement.missing)
    camera = None
    if intrinsics is not None:
        camera = check_intrinsics(intrinsics)
        if rotations is not None:
            raise ValueError(
                "rotations= with intrinsics=: the perspective refinement estimates the "
                "rotations, so given ones would not be kept; give one or the other"
            )
    elif settings.perspective != PerspectiveSettings():
        raise ValueError(
            f"settings.perspective={settings.perspective!r} is used only with intrinsics=; "
            f"without it the camera is orthographic and it would be ignored"
        )
    say = progress if callable(progress) else (lambda msg: None)
    if progress and not callable(progress):
        say = lambda msg: print(f"[nrsfm] {msg}", file=sys.stderr, flush=True)  # noqa: E731
    with blas_threads(blas_thread_limit) if blas_thread_limit else nullcontext():
        if camera is None:
            return _orthographic(W, K, rotations, settings, seed, say)
        x = normalise(W, camera)
        res = _orthographic(x.reshape(W.shape), K, None, settings, seed, say, warn=False)

        def one():  # the continuation's start, when it is run: its warnings are not the run's
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r1 = _orthographic(
                    x.reshape(W.shape), 1, None, settings, seed, lambda m: None, False
                )
            return r1.rotations, r1.shapes, r1.row_means.reshape(-1, 2)

        with _timed(res.timings, "perspective"):
            sigma = res.shape_stage.X_init_singular_values * res.scale
            a = None if settings.prior is None else bilinear_weights(sigma, K, settings.prior)
            start = (res.rotations, res.shapes, res.row_means.reshape(-1, 2))
            persp = refine_perspective(
                x,
                K,
                start,
                one,
                a,
                sigma[0],
                intrinsics=camera,
                observed=res.observed,
                settings=settings.perspective,
                progress=say,
            )
        say(
            f"perspective refinement ({persp.start} start, {persp.n_iter} iterations): "
            f"reprojection {persp.reprojection_before:.3g} -> {persp.reprojection_after:.3g} px"
        )
    diagnose_perspective(res.diagnostics, persp)
    if res.diagnostics.flags:  # one warning per run, every flag in it
        warnings.warn(res.diagnostics.message, NRSfMWarning, stacklevel=2)
    return replace(res, rotations=persp.rotations, shapes=persp.shapes, perspective=persp)


def _orthographic(W, K, rotations, settings, seed, say, warn=True):
    """The orthographic stages on checked W: :func:`reconstruct` without intrinsics (its
    warning: ``warn``; else the flags are only in ``diagnostics``)."""
    timings = {}
    completion = None
    if np.isnan(W).any():
        with _timed(timings, "completion"):
            completion = complete(W, K, settings.measurement)
        W = completion.W
    with _timed(timings, "factorize"):
        meas = measure(W, K)
    fact = meas.factorization
    say(f"rank-{3 * K} factorisation of W {W.shape}: residual {fact.residual:.3g}")
    rotation_stage, single = None, METHODS[settings.method].single
    if rotations is None:
        with _timed(timings, "rotations"):
            rotation_stage = estimate_rotations(
                fact.M_hat, K, settings.rotation, single=single, seed=seed, progress=say
            )
        rotations = rotation_stage.rotations
    with _timed(timings, "shape"):  # the settings' solver, or none
        if settings.shape is None:
            shape_stage = solve_pseudo_inverse(meas.Wn, rotations, K)
        else:
            shape_stage = settings.shape.solve(meas.Wn, rotations, K, settings.prior, say)
    shapes = shape_stage.shapes
    amp = None if settings.shape is None else depth_amplification(rotations, shapes, K)
    diagnostics = diagnose(meas.Wn, K, fact, rotation_stage, seed, depth_amplification=amp)
    shapes = meas.restore(shape_stage.shapes)
    if not (np.all(np.isfinite(shapes)) and np.isfinite(meas.scale)):
        raise ValueError(f"the shapes overflow in W's units (max|W| {np.abs(W).max():.3g})")
    spread, gain, by_neighbours = None, None, settings.measurement.fill == "neighbours"
    if completion is not None:
        with _timed(timings, "fill") if by_neighbours else nullcontext():
            gain = fill_gain(fact.M_hat, completion.observed)
            if by_neighbours:
                shapes, spread = fill_unseen(shapes, completion.observed, gain > MAX_GAIN)
    result = Reconstruction(
        rotations=rotations,
        shapes=shapes,
        K=K,
        W=meas.W,
        row_means=meas.row_means,
        scale=meas.scale,
        factorization=fact,
        X_init=meas.restore(shape_stage.X_init),
        settings=settings,
        seed=seed,
        rotation_stage=rotation_stage,
        shape_stage=shape_stage,
        timings=timings,
        diagnostics=diagnostics,
        completion=completion,
        fill_spread=spread,
    )
    if completion is not None:  # the tracks the fill leaves unreliable: a flag of the run
        vars(result)["fill_gain"] = gain  # its cached property, computed once
        diagnose_fill(diagnostics, result.unreliable, by_neighbours)
    if warn and diagnostics.flags:  # one warning per run, every flag in it
        warnings.warn(diagnostics.message, NRSfMWarning, stacklevel=3)
    return result


def _settings(settings, **keywords):
    """The run's Settings: ``settings`` as given, or :meth:`Settings.from_keywords` of the
    keywords given; a keyword beside ``settings`` is refused (it would be ignored)."""
    given = {k: v for k, v in keywords.items() if v is not None}
    if settings is None:
        return Settings.from_keywords(**given)
    if not isinstance(settings, Settings):
        raise ValueError(f"settings must be an nrsfm.Settings; got {settings!r}")
    if given:
        raise ValueError(
            f"settings= replaces the keywords {', '.join(KEYWORDS)}; got "
            f"{', '.join(sorted(given))} beside it, which would be ignored: "
            f"set them in the settings ({', '.join(KEYWORDS.values())})"
        )
    return settings
