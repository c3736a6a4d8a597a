"""What a recording of a reconstruction shows, as numpy arrays (no rerun, no matplotlib).

:func:`recording_content` maps a :class:`nrsfm.Reconstruction` (and optionally its ground
truth) to a :class:`RecordingContent`: the estimate aligned to the ground truth for display,
per-frame errors, the rotation samples of every corrective triplet, the shape-stage
history, singular values and a markdown report. The Rerun logging
(:mod:`nrsfm.views.recording`) and the matplotlib figures (:mod:`nrsfm.views.figures`) both
draw from it.

Display alignment
-----------------
NRSfM recovers shapes and cameras up to a global rotation / reflection (and each frame's
shape up to the camera's depth sign). To overlay estimate and ground truth:

* shapes: each estimated frame is mapped onto the ground truth of that frame by a
  similarity Procrustes (rotation, reflection, scale: :func:`nrsfm.geometry.align_similarity`)
  -- the same alignment as the ``e3d`` metric, so the gap seen between the two point clouds
  is what ``e3d`` measures. Both are drawn centred in the ground truth's world frame.
* cameras (and every rotation sample): one global orthogonal ``Q`` minimising
  ``sum_f ||R_gt,f[:2] - R_est,f[:2] Q||_F^2`` (the alignment of the ``e_R`` metric); the
  displayed camera is ``R_est,f[:2] Q`` completed with ``r3 = r1 x r2``.

Without ground truth nothing is aligned: the estimate is drawn as returned.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["RecordingContent", "recording_content", "HISTORY_KEYS"]

#: Shape-stage history quantities drawn, in this order (ADMM | bilinear solver).
HISTORY_KEYS = ("cost", "data_term", "residual", "rho", "grad_norm")
#: Camera distance from the origin and axis length, in multiples of the shapes' extent.
CAMERA_DISTANCE = 1.5
AXIS_LENGTH = 0.4


@dataclass
class RecordingContent:
    """Everything a recording shows, as numpy arrays (no rerun objects).

    Shapes are (F, P, 3) point arrays (rerun's layout), rotations (F, 3, 3).
    """

    n_frames: int
    n_points: int
    frames: np.ndarray
    shapes_est: np.ndarray
    shapes_gt: np.ndarray | None = None
    edges: np.ndarray | None = None
    cameras_est: np.ndarray | None = None
    cameras_gt: np.ndarray | None = None
    camera_distance: float = 1.0
    axis_length: float = 0.3
    tracks: np.ndarray | None = None          # (F, P, 2) measured (centred) W
    filled: np.ndarray | None = None          # (F, P) bool: not observed, the 3D a fill
    fill_gain: np.ndarray | None = None       # (P,) the fill's noise gain (reliability)
    fill_spread: np.ndarray | None = None     # (P,) neighbour fills' spread (NaN: not so filled)
    reprojected: np.ndarray | None = None     # (F, P, 2) R_f X_f
    triplet_rotations: np.ndarray | None = None   # (K, F, 3, 3) registered, display-aligned
    triplet_kept: np.ndarray | None = None        # (K, F) bool
    triplet_distance: np.ndarray | None = None    # (K, F) chordal distance to the average
    triplet_coefficients: np.ndarray | None = None  # (K, F)
    averaged: np.ndarray | None = None            # (F, 3, 3) display-aligned
    sign_from_smoothness: np.ndarray | None = None  # (F,) bool
    rotations_gt_display: np.ndarray | None = None
    errors_per_frame: dict = field(default_factory=dict)
    errors: dict = field(default_factory=dict)
    admm: dict = field(default_factory=dict)      # name -> (n_iter,) float array
    singular_values: dict = field(default_factory=dict)  # name -> 1-D array
    report: str = ""
    aligned: bool = False


def complete_rotations(R2):
    """(F, 2, 3) or (F, 3, 3) -> (F, 3, 3) with the third row r1 x r2."""
    R2 = np.asarray(R2, float)[..., :2, :]
    return np.concatenate([R2, np.cross(R2[..., 0, :], R2[..., 1, :])[..., None, :]], axis=-2)


def _gt_world(sequence):
    """Ground-truth shapes in the ground truth's world frame, (F, 3, P), or None."""
    if sequence is None or sequence.shapes is None:
        return None
    if getattr(sequence, "world_shapes", None) is not None:
        X = np.asarray(sequence.world_shapes, float)
    elif sequence.rotations is not None:
        X = np.asarray(sequence.rotations, float).transpose(0, 2, 1) @ sequence.shapes
    else:
        X = np.asarray(sequence.shapes, float)    # no camera: camera frame is the world
    return X - X.mean(axis=2, keepdims=True)


def _stage_value(stage, name, default=None):
    return getattr(stage, name, default) if stage is not None else default


def _world_content(result, sequence):
    """The 3D world part of the content: aligned shapes, cameras, image, and ``Q``."""
    from ..geometry import align_similarity as similarity_align
    from ..metrics import camera_alignment

    F, P = result.n_frames, result.n_points
    X_est = np.asarray(result.shapes, float)
    R_est = np.asarray(result.rotations, float)
    X_gt = _gt_world(sequence)
    R_gt = None if sequence is None or sequence.rotations is None else np.asarray(
        sequence.rotations, float)
    X_disp = (similarity_align(X_est, X_gt) if X_gt is not None
              else X_est - X_est.mean(axis=2, keepdims=True))
    Q = camera_alignment(R_est, R_gt) if R_gt is not None else np.eye(3)
    ref = X_gt if X_gt is not None else X_disp
    extent = float(np.max(np.linalg.norm(ref, axis=1))) if ref.size else 1.0
    extent = extent if extent > 0 else 1.0
    c = RecordingContent(n_frames=F, n_points=P, frames=np.arange(F),
                         shapes_est=X_disp.transpose(0, 2, 1).copy(),
                         shapes_gt=None if X_gt is None else X_gt.transpose(0, 2, 1).copy(),
                         edges=None if sequence is None or sequence.edges is None
                         else np.asarray(sequence.edges, int),
                         cameras_est=complete_rotations(R_est[..., :2, :] @ Q),
                         cameras_gt=None if R_gt is None else complete_rotations(R_gt),
                         camera_distance=CAMERA_DISTANCE * extent,
                         axis_length=AXIS_LENGTH * extent, aligned=X_gt is not None)
    Wt = np.asarray(result.W, float).reshape(F, 2, P)
    c.tracks = Wt.transpose(0, 2, 1).copy()
    c.reprojected = (R_est[:, :2] @ X_est).transpose(0, 2, 1).copy()
    if getattr(result, "observed", None) is not None:
        c.filled = ~np.asarray(result.observed, bool)
        c.fill_gain = np.asarray(result.fill_gain, float)
        spread = getattr(result, "fill_spread", None)
        c.fill_spread = None if spread is None else np.asarray(spread, float)
    return c, Q, R_gt


def _add_errors(c, result, sequence, R_gt):
    from ..metrics import e3d, rotation_error

    if sequence is not None and sequence.shapes is not None:
        c.errors_per_frame["e3d"] = e3d(result.shapes, sequence.shapes, per_frame=True)
    if R_gt is not None:
        c.errors_per_frame["e_R"] = rotation_error(result.rotations, R_gt, per_frame=True)
    c.errors = {k: float(np.mean(v)) for k, v in c.errors_per_frame.items()}
    c.errors["reprojection_rms"] = result.reprojection_error()


def _add_rotation_stage(c, result, Q, R_gt):
    """Registered samples per triplet, the filter's choice, the average (display-aligned)."""
    def disp_rot(R):
        return complete_rotations(np.asarray(R, float)[..., :2, :] @ Q)

    rs, F = result.rotation_stage, result.n_frames
    registered = _stage_value(rs, "registered")
    averaged = _stage_value(rs, "averaged")
    if registered is not None:
        registered = np.asarray(registered, float)
        K = registered.shape[0]
        c.triplet_rotations = disp_rot(registered)
        kept = _stage_value(rs, "kept")
        c.triplet_kept = (np.ones((K, F), bool) if kept is None
                          else np.asarray(kept, bool).reshape(K, F))
        final = complete_rotations(averaged if averaged is not None else result.rotations)
        c.triplet_distance = np.linalg.norm(complete_rotations(registered) - final[None],
                                            axis=(2, 3))
        coeff = _stage_value(rs, "coefficients")
        if coeff is not None:
            c.triplet_coefficients = np.asarray(coeff, float).reshape(K, F)
    flips = _stage_value(rs, "sign_from_smoothness")
    if flips is not None:
        c.sign_from_smoothness = np.asarray(flips, bool).ravel()
    if averaged is not None:
        c.averaged = disp_rot(averaged)
    if rs is not None and R_gt is not None:
        c.rotations_gt_display = complete_rotations(R_gt)


def _add_shape_stage(c, result):
    """Shape-stage history and the spectra, in the solver's units (input / scale)."""
    from ..stages.shape import phi

    ss = result.shape_stage
    history = _stage_value(ss, "history") or {}
    for key in list(HISTORY_KEYS) + sorted(k for k in history if k not in HISTORY_KEYS):
        if key in history:
            v = np.asarray(history[key], float).ravel()
            if v.size:
                c.admm[key] = v
    c.singular_values["W"] = np.asarray(result.factorization.singular_values, float)
    sv_x = _stage_value(ss, "X_init_singular_values")
    if sv_x is None:
        sv_x = np.linalg.svd(phi(np.asarray(result.X_init, float) / result.scale),
                             compute_uv=False)
    c.singular_values["X_init"] = np.asarray(sv_x, float)
    theta = _stage_value(ss, "theta")
    if theta is not None:
        c.singular_values["theta"] = np.asarray(theta, float).ravel()


def recording_content(result, sequence=None):
    """Compute what a recording of ``result`` shows (no rerun calls).

    Parameters
    ----------
    result : nrsfm.Reconstruction
        Stages may be missing (``rotation_stage`` / ``shape_stage`` None): their parts are
        left out.
    sequence : nrsfm.sequence.Sequence, optional
        Ground truth (shapes, rotations, skeleton edges). Frame count must match.

    Returns
    -------
    RecordingContent
    """
    if sequence is not None and sequence.n_frames != result.n_frames:
        raise ValueError(f"sequence has {sequence.n_frames} frames, result has "
                         f"{result.n_frames}")
    c, Q, R_gt = _world_content(result, sequence)
    _add_errors(c, result, sequence, R_gt)
    _add_rotation_stage(c, result, Q, R_gt)
    _add_shape_stage(c, result)
    c.report = _report(result, sequence, c)
    return c


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, np.ndarray):
        return f"array{v.shape}"
    if isinstance(v, dict):
        return ", ".join(f"{k}={_fmt(x)}" for k, x in v.items()) or "{}"
    return str(v)


def _stage_lines(result, c):
    rs, ss = result.rotation_stage, result.shape_stage
    lines = ["## Stages", "",
             f"- rotation stage: {'ran' if rs is not None else 'skipped (rotations given)'}",
             f"- shape stage: {'ran' if ss is not None else 'skipped (pseudo-inverse + rank-K truncation)'}"]
    if ss is not None:
        solver = ss.solver
        lines.append(f"- shape solver {solver}: {_stage_value(ss, 'n_iter')} iterations, "
                     f"converged = {_stage_value(ss, 'converged')}")
        if _stage_value(ss, "grad_norm") is not None:
            lines.append(f"- shape objective {_stage_value(ss, 'objective'):.6g}, relative "
                         f"gradient norm {_stage_value(ss, 'grad_norm'):.3g} (first-order "
                         "optimality)")
    if c.triplet_kept is not None:
        lines.append(f"- rotation samples kept by the filter: {int(c.triplet_kept.sum())} of "
                     f"{c.triplet_kept.size}")
    return lines


def _report(result, sequence, c):
    """The run's report, markdown: errors, stages, parameters, timings, display notes."""
    name = getattr(sequence, "name", None) or "(no ground truth)"
    lines = [f"# nrsfm run: `{result.method}` on {name}", "",
             f"F = {result.n_frames} frames, P = {result.n_points} points, K = {result.K}, "
             f"scale = {result.scale:.6g}", "", "## Errors", "", "| metric | value |",
             "| --- | --- |"]
    lines += [f"| {k} | {v:.6g} |" for k, v in c.errors.items()]
    lines += [""] + _stage_lines(result, c)
    lines += ["", "## Parameters", "", "| parameter | value |", "| --- | --- |"]
    params = dict(method=result.method, K=result.K, seed=result.seed,
                  rotations_given=result.rotation_stage is None,
                  shape_solver=result.settings.shape_solver,
                  scale=result.scale)
    lines += [f"| {k} | {_fmt(v)} |" for k, v in params.items()]
    lines += ["", "## Timings (s)", "", "| stage | seconds |", "| --- | --- |"]
    lines += [f"| {k} | {v:.3f} |" for k, v in result.timings.items()]
    if getattr(result, "diagnostics", None) is not None:
        lines += ["", "## Diagnostics", "", "```", result.diagnostics.summary(), "```"]
    lines += ["", "## Display", "",
              ("Estimated shapes are similarity-aligned per frame onto the ground truth (as in "
               "e3d)." if c.aligned else "No ground-truth shapes: shapes drawn as estimated."),
              ("Cameras and rotation samples: one global orthogonal alignment onto the "
               "ground-truth cameras (as in e_R)." if c.cameras_gt is not None else
               "No ground-truth cameras: cameras and rotation samples drawn as estimated."),
              "Singular values are in the solver's units (input / scale)."]
    return "\n".join(lines)
