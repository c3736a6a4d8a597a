"""The public entry point: ``reconstruct(W, K, method=...)``, and its result type."""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ._validation import (blas_threads, check_centred_rank, check_K, check_measurements,
                          check_rotations, power_of_two_scale)
from .measurement import Factorization, centre_rows, factorize
from .scale import normalization_scale
from .shape import pseudo_inverse_shapes, truncate_rank

__all__ = ["METHODS", "Reconstruction", "reconstruct"]

#: method -> (rotation strategy, shape prior). ``None`` prior: rank-K pseudo-inverse shape.
METHODS = {
    "organic": ("organic", "organic"),        # all K triplets, averaged; PSVT (N = 1) WNN
    "bmm": ("bmm", "nuclear"),                 # Dai et al.: first triplet, nuclear norm
    "wnn": ("organic", "weighted"),           # weighted nuclear norm over all singular values
    "pseudo_inverse": ("organic", None),      # rank-K truncated pinv(R) W
}


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
        The solvers ran on ``W / scale`` (see :mod:`nrsfm.scale`).
    factorization : Factorization
        Rank-3K SVD of ``W / scale`` (``M_hat``, ``B_hat``, singular values).
    rotation_stage : object or None
        The rotation stage's result (triplets G^k, per-triplet rotations R^k,
        registration, filtering, averaging), None when rotations were given.
    shape_stage : object or None
        The shape stage's result (X_init, weights, ADMM history), None for
        ``method="pseudo_inverse"``.
    X_init : (F, 3, P) ndarray
        Pseudo-inverse shape ``pinv(R) W`` in the input's units.
    params : dict
        Every setting used.
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
    completion : CompletionResult or None
        The completion's result (:mod:`nrsfm.completion`).
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
    shape_stage: object = None
    params: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    diagnostics: object = None
    observed: np.ndarray = None
    W_completed: np.ndarray = None
    completion: object = None

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
        """A few lines describing the run."""
        F, P = self.n_frames, self.n_points
        lines = [f"nrsfm {self.method}: F={F} frames, P={P} points, K={self.K}, "
                 f"scale={self.scale:.4g}",
                 f"  reprojection RMS {self.reprojection_error():.3g} (input units)"]
        t = ", ".join(f"{k} {v:.3f}s" for k, v in self.timings.items())
        lines.append(f"  time: {t}")
        return "\n".join(lines)


def _progress_printer(progress):
    if callable(progress):
        return progress
    if progress:
        return lambda msg: print(f"[nrsfm] {msg}", file=sys.stderr, flush=True)
    return lambda msg: None


def reconstruct(W, K, method="organic", rotations=None, *, seed=0, rotation_options=None,
                shape_options=None, shape_solver="bilinear", progress=False,
                blas_thread_limit=1, missing="complete"):
    """Recover camera rotations and per-frame 3D shapes from 2D tracks.

    Parameters
    ----------
    W : (2F, P) or (F, 2, P) array_like
        Measurements: rows ``x_f, y_f`` interleaved, or per-frame tracks. Rows are
        centred here (per-frame translation is removed).
    K : int
        Number of shape bases, ``1 <= K`` and ``3K <= min(2F, P - 1)``.
    method : {"organic", "bmm", "wnn", "pseudo_inverse"}
        ``organic`` (default): all K corrective triplets, registered, filtered and
        L1-averaged rotations; shape by partial-sum weighted nuclear norm ADMM (N = 1).
        ``bmm``: Dai et al.'s baseline (first triplet, plain nuclear norm).
        ``wnn``: the averaged rotations with a weighted nuclear norm on every singular
        value (N = 0). ``pseudo_inverse``: rank-K truncation of ``pinv(R) W``.
    rotations : (F, 3, 3) array_like, optional
        Known camera rotations; the rotation stage is then skipped.
    seed : int
        Seed for every random choice (results are deterministic for a given seed).
    rotation_options, shape_options : dict, optional
        Passed to :func:`nrsfm.rotations.estimate_rotations` and to the shape solver.
    shape_solver : {"admm", "bilinear", "closed_form"}
        ``bilinear`` (default): the factored weighted nuclear norm minimised to a
        stationary point,
        :func:`nrsfm.shape_bilinear.optimize_shapes_bilinear`; ``admm``: the paper's
        continuation ADMM, :func:`nrsfm.shape.optimize_shapes`; ``closed_form``: the exact
        rank-K solution, :func:`nrsfm.shape_bilinear.closed_form_result` (no prior). See
        ``docs/shape_stage.md`` for the measurements behind the default.
    progress : bool or callable
        Print stage progress to stderr (or call ``progress(message)``).
    blas_thread_limit : int or None
        BLAS threads while the solvers run (the matrices are small: one is fastest).
    missing : {"complete", "error"}
        What to do with missing observations: NaN in W or tracks (a point counts as missing
        in a frame when either coordinate is NaN), or the mask of a
        ``numpy.ma.MaskedArray``. ``complete`` (default): fill W by low-rank completion
        (:func:`nrsfm.completion.complete_measurements`) and run the pipeline on it; the
        result keeps ``observed`` and ``W_completed``. ``error``: refuse.

    Returns
    -------
    Reconstruction

    Raises
    ------
    ValueError
        Bad shapes, non-finite input, K out of range (including 3K above
        ``min(2F, P - 1)``, the largest rank of a row-centred W), unknown method, bad
        rotations; missing observations with ``missing="error"``; a frame or point with
        too few observations to be determined (named in the message).

    Warns
    -----
    nrsfm.NRSfMWarning
        When a quality signal of the run crosses its threshold (``result.diagnostics``).
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {sorted(METHODS)}")
    from .shape import SHAPE_SOLVERS

    if shape_solver not in SHAPE_SOLVERS:
        raise ValueError(f"unknown shape_solver {shape_solver!r}; expected one of "
                         f"{list(SHAPE_SOLVERS)}")
    if missing not in ("complete", "error"):
        raise ValueError(f"missing must be 'complete' or 'error'; got {missing!r}")
    W = check_measurements(W, allow_missing=True)
    F, P = W.shape[0] // 2, W.shape[1]
    missing_entries = np.isnan(W)
    if missing_entries.any() and missing == "error":
        n_miss = int(missing_entries.reshape(F, 2, P).any(axis=1).sum())
        raise ValueError(f"W has {n_miss} missing (frame, point) observations (NaN or "
                         f"masked) and missing='error'; use missing='complete' to "
                         f"fill them by low-rank completion")
    # every input check before any computation (the completion can take a while)
    K = check_K(K, F, P)
    K = check_centred_rank(K, F, P)
    if rotations is not None:
        rotations = check_rotations(rotations, "rotations", n_frames=F)
    say = _progress_printer(progress)
    rotation_strategy, prior = METHODS[method]
    timings = {}
    completion = None

    limit = blas_threads(blas_thread_limit) if blas_thread_limit else _nullcontext()
    with limit:
        if missing_entries.any():
            from .completion import complete_measurements

            t0 = time.perf_counter()
            completion = complete_measurements(W)
            timings["completion"] = time.perf_counter() - t0
            if not completion.converged:
                warnings.warn(f"the completion of W stopped at its iteration cap "
                              f"({completion.n_iter}) before converging: the filled "
                              f"entries may be inaccurate", RuntimeWarning, stacklevel=2)
            W = completion.W

        t0 = time.perf_counter()
        # Any finite W: divide by an exact power of two near max|W| first, so that
        # centring, norms and SVD neither overflow (|W| ~ 1e153) nor underflow (~ 1e-165).
        p2 = power_of_two_scale(W)
        Wc_p, row_means_p = centre_rows(W / p2)
        s = normalization_scale(Wc_p)
        Wn = Wc_p / s
        scale = s * p2
        Wc, row_means = Wc_p * p2, row_means_p * p2
        fact = factorize(Wn, K)
        timings["factorize"] = time.perf_counter() - t0
        say(f"rank-{3 * K} factorisation of {2 * F}x{P} W: residual {fact.residual:.3g}")

        rotation_stage = None
        if rotations is None:
            from .rotations import estimate_rotations

            t0 = time.perf_counter()
            rotation_stage = estimate_rotations(
                fact.M_hat, K, strategy=rotation_strategy, seed=seed, progress=say,
                **(rotation_options or {}))
            rotations = rotation_stage.rotations
            timings["rotations"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        shape_stage = None
        if prior is None:
            X_init = pseudo_inverse_shapes(Wn, rotations)
            shapes = truncate_rank(X_init, K)
        else:
            from .shape import solve_shapes

            # Wn = W / scale: the ADMM's constants assume that scale (nrsfm.scale); the
            # bilinear and closed-form solvers are scale-free, so it does not matter to them.
            shape_stage = solve_shapes(Wn, rotations, K, prior=prior, solver=shape_solver,
                                       progress=say, **(shape_options or {}))
            X_init, shapes = shape_stage.X_init, shape_stage.shapes
        timings["shape"] = time.perf_counter() - t0

    from .diagnostics import diagnose

    diagnostics = diagnose(Wn, K, fact.singular_values, fact.M_hat, rotation_stage, seed)
    diagnostics.warn(stacklevel=2)
    params = dict(method=method, K=K, seed=seed, rotation_strategy=rotation_strategy,
                  shape_prior=prior, shape_solver=shape_solver,
                  rotation_options=dict(rotation_options or {}),
                  shape_options=dict(shape_options or {}), scale=scale,
                  rotations_given=rotation_stage is None, missing=missing)
    shapes_out, X_init_out = (shapes * s) * p2, (X_init * s) * p2
    if not (np.all(np.isfinite(shapes_out)) and np.isfinite(scale)):
        raise ValueError(f"the shapes overflow in the input's units (max|W| = "
                         f"{np.abs(W).max():.3g}); rescale W")
    return Reconstruction(rotations=rotations, shapes=shapes_out, method=method, K=K,
                          W=Wc, row_means=row_means, scale=scale, factorization=fact,
                          X_init=X_init_out, rotation_stage=rotation_stage,
                          shape_stage=shape_stage, params=params, timings=timings,
                          diagnostics=diagnostics,
                          observed=None if completion is None else completion.observed,
                          W_completed=None if completion is None else completion.W,
                          completion=completion)


class _nullcontext:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False
