"""What a recording of a reconstruction shows, as numpy arrays (no rerun, no matplotlib).

:func:`recording_content` maps a :class:`nrsfm.Reconstruction` (and its ground truth) to a
:class:`RecordingContent`, which the Rerun recording (:mod:`.recording`) and the figures
(:mod:`.figures`) draw. Estimate and ground truth are overlaid as the metrics align them:
each estimated shape by a per-frame similarity Procrustes onto the ground truth in its world
frame (as ``e3d``), the cameras and rotation samples by one global orthogonal ``Q``
minimising ``sum_f ||R_gt,f[:2] - R_est,f[:2] Q||_F^2`` (as ``e_R``), completed with
``r3 = r1 x r2``. Without ground truth the estimate is drawn as returned.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Shape-stage history quantities drawn, in this order (ADMM | bilinear solver).
HISTORY_KEYS = ("cost", "data_term", "residual", "rho", "grad_norm")


@dataclass
class RecordingContent:
    """Everything a recording shows: shapes as (F, P, 3) point arrays (rerun's layout),
    rotations (F, 3, 3), display-aligned."""

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
    tracks: np.ndarray | None = None  # (F, P, 2) measured (centred) W
    filled: np.ndarray | None = None  # (F, P) bool: not observed, the 3D is a fill
    fill_gain: np.ndarray | None = None  # (P,) the fill's noise gain
    fill_spread: np.ndarray | None = None  # (P,) spread of the neighbour fills (NaN: none)
    reprojected: np.ndarray | None = None  # (F, P, 2) R_f X_f
    triplet_rotations: np.ndarray | None = None  # (K, F, 3, 3) registered samples
    triplet_kept: np.ndarray | None = None  # (K, F) bool
    triplet_angle: np.ndarray | None = None  # (K, F) geodesic angle to the average (rad)
    triplet_coefficients: np.ndarray | None = None  # (K, F)
    averaged: np.ndarray | None = None  # (F, 3, 3)
    sign_from_smoothness: np.ndarray | None = None  # (F,) bool
    rotations_gt_display: np.ndarray | None = None
    errors_per_frame: dict = field(default_factory=dict)
    errors: dict = field(default_factory=dict)
    admm: dict = field(default_factory=dict)  # shape-stage history: name -> (n_iter,)
    singular_values: dict = field(default_factory=dict)  # name -> 1-D array
    report: str = ""
    aligned: bool = False


def complete_rotations(R2):
    """(F, 2, 3) or (F, 3, 3) -> (F, 3, 3) with the third row r1 x r2."""
    R2 = np.asarray(R2, float)[..., :2, :]
    return np.concatenate([R2, np.cross(R2[..., 0, :], R2[..., 1, :])[..., None, :]], axis=-2)


def _gt_world(sequence):
    """Ground-truth shapes in the ground truth's world frame, centred, (F, 3, P), or None."""
    if sequence is None or sequence.shapes is None:
        return None
    if getattr(sequence, "world_shapes", None) is not None:
        X = np.asarray(sequence.world_shapes, float)
    elif sequence.rotations is not None:
        X = np.asarray(sequence.rotations, float).transpose(0, 2, 1) @ sequence.shapes
    else:
        X = np.asarray(sequence.shapes, float)  # no camera: the camera frame is the world
    return X - X.mean(axis=2, keepdims=True)


def _get(stage, name):
    return getattr(stage, name, None) if stage is not None else None


def _world_content(result, sequence):
    """The 3D world part of the content (aligned shapes, cameras, image) and ``Q``."""
    from ..geometry import align_similarity
    from ..metrics import camera_alignment

    F, P = result.n_frames, result.n_points
    X_est, R_est = np.asarray(result.shapes, float), np.asarray(result.rotations, float)
    X_gt = _gt_world(sequence)
    R_gt = None if sequence is None or sequence.rotations is None else sequence.rotations
    R_gt = None if R_gt is None else np.asarray(R_gt, float)
    if X_gt is not None:
        X_disp = align_similarity(X_est, X_gt)
    else:
        X_disp = X_est - X_est.mean(axis=2, keepdims=True)
    Q = camera_alignment(R_est, R_gt) if R_gt is not None else np.eye(3)
    ref = X_gt if X_gt is not None else X_disp
    extent = float(np.max(np.linalg.norm(ref, axis=1))) if ref.size else 1.0
    extent = extent if extent > 0 else 1.0
    c = RecordingContent(F, P, np.arange(F), X_disp.transpose(0, 2, 1).copy())
    c.shapes_gt = None if X_gt is None else X_gt.transpose(0, 2, 1).copy()
    edges = None if sequence is None else sequence.edges
    c.edges = None if edges is None else np.asarray(edges, int)
    c.cameras_est = complete_rotations(R_est[..., :2, :] @ Q)
    c.cameras_gt = None if R_gt is None else complete_rotations(R_gt)
    c.camera_distance, c.axis_length = 1.5 * extent, 0.4 * extent  # multiples of the extent
    c.aligned = X_gt is not None
    c.tracks = np.asarray(result.W, float).reshape(F, 2, P).transpose(0, 2, 1).copy()
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
    rs, F = result.rotation_stage, result.n_frames
    registered, averaged = _get(rs, "registered"), _get(rs, "averaged")
    if registered is not None:
        registered = np.asarray(registered, float)
        K = registered.shape[0]
        c.triplet_rotations = complete_rotations(registered[..., :2, :] @ Q)
        kept = _get(rs, "kept")
        c.triplet_kept = np.ones((K, F), bool) if kept is None else np.asarray(kept, bool)
        c.triplet_kept = c.triplet_kept.reshape(K, F)
        final = complete_rotations(averaged if averaged is not None else result.rotations)
        angle = _get(rs, "filter_distance")  # what the filter compares with delta
        if angle is None:
            trace = np.einsum("kfij,fij->kf", complete_rotations(registered), final)
            angle = np.arccos(np.clip((trace - 1) / 2, -1.0, 1.0))
        c.triplet_angle = np.asarray(angle, float).reshape(K, F)
        if _get(rs, "coefficients") is not None:
            c.triplet_coefficients = np.asarray(rs.coefficients, float).reshape(K, F)
    if _get(rs, "sign_from_smoothness") is not None:
        c.sign_from_smoothness = np.asarray(rs.sign_from_smoothness, bool).ravel()
    if averaged is not None:
        c.averaged = complete_rotations(np.asarray(averaged, float)[..., :2, :] @ Q)
    if rs is not None and R_gt is not None:
        c.rotations_gt_display = complete_rotations(R_gt)


def _add_shape_stage(c, result):
    """Shape-stage history and the spectra, in the solver's units (input / scale)."""
    from ..stages.shape import phi

    ss = result.shape_stage
    history = _get(ss, "history") or {}
    for key in list(HISTORY_KEYS) + sorted(k for k in history if k not in HISTORY_KEYS):
        v = np.asarray(history.get(key, []), float).ravel()
        if v.size:
            c.admm[key] = v
    c.singular_values["W"] = np.asarray(result.factorization.singular_values, float)
    sv_x = _get(ss, "X_init_singular_values")
    if sv_x is None:
        X_init = np.asarray(result.X_init, float) / result.scale
        sv_x = np.linalg.svd(phi(X_init), compute_uv=False)
    c.singular_values["X_init"] = np.asarray(sv_x, float)
    if _get(ss, "theta") is not None:
        c.singular_values["theta"] = np.asarray(ss.theta, float).ravel()


def recording_content(result, sequence=None):
    """The :class:`RecordingContent` of the :class:`nrsfm.Reconstruction` ``result`` (the
    parts of a stage that did not run left out), with the ground truth of ``sequence``
    (shapes, rotations, skeleton edges; as many frames) if given."""
    if sequence is not None and sequence.n_frames != result.n_frames:
        raise ValueError(f"sequence has {sequence.n_frames} frames, result has {result.n_frames}")
    c, Q, R_gt = _world_content(result, sequence)
    _add_errors(c, result, sequence, R_gt)
    _add_rotation_stage(c, result, Q, R_gt)
    _add_shape_stage(c, result)
    c.report = _report(result, sequence, c)
    return c


def _table(head, rows):
    """A markdown section with a two-column table; ``head``: "title|column|column"."""
    title, a, b = head.split("|")
    return ["", f"## {title}", "", f"| {a} | {b} |", "| --- | --- |"] + rows


def _report(result, sequence, c):
    """The run's report, markdown: errors, stages, parameters, timings, display notes."""
    rs, ss = result.rotation_stage, result.shape_stage
    name = getattr(sequence, "name", None) or "(no ground truth)"
    size = f"F = {result.n_frames} frames, P = {result.n_points} points, K = {result.K}"
    lines = [f"# nrsfm run: `{result.method}` on {name}", "", f"{size}, scale = {result.scale:.6g}"]
    lines += _table("Errors|metric|value", [f"| {k} | {v:.6g} |" for k, v in c.errors.items()])
    lines += ["", "## Stages", ""]
    lines.append(f"- rotation stage: {'ran' if rs is not None else 'skipped (rotations given)'}")
    shape = "ran" if ss is not None else "skipped (pseudo-inverse + rank-K truncation)"
    lines.append(f"- shape stage: {shape}")
    if ss is not None:
        n_iter, converged = _get(ss, "n_iter"), _get(ss, "converged")
        lines.append(f"- shape solver {ss.solver}: {n_iter} iterations, converged = {converged}")
        if _get(ss, "grad_norm") is not None:
            optimality = f"relative gradient norm {ss.grad_norm:.3g} (first-order optimality)"
            lines.append(f"- shape objective {ss.objective:.6g}, {optimality}")
    if c.triplet_kept is not None:
        kept = c.triplet_kept
        lines.append(f"- rotation samples kept by the filter: {int(kept.sum())} of {kept.size}")
    params = dict(method=result.method, K=result.K, seed=result.seed, rotations_given=rs is None)
    params.update(shape_solver=result.settings.shape_solver, scale=f"{result.scale:.6g}")
    lines += _table("Parameters|parameter|value", [f"| {k} | {v} |" for k, v in params.items()])
    lines += _table(
        "Timings (s)|stage|seconds", [f"| {k} | {v:.3f} |" for k, v in result.timings.items()]
    )
    if getattr(result, "diagnostics", None) is not None:
        lines += ["", "## Diagnostics", "", "```", result.diagnostics.summary(), "```"]
    shapes = "Estimated shapes are similarity-aligned per frame onto the ground truth"
    shapes += " (as in e3d)."
    if not c.aligned:
        shapes = "No ground-truth shapes: shapes drawn as estimated."
    cameras = "Cameras and rotation samples: one global orthogonal alignment onto the ground-truth"
    cameras += " cameras (as in e_R)."
    if c.cameras_gt is None:
        cameras = "No ground-truth cameras: cameras and rotation samples drawn as estimated."
    lines += ["", "## Display", "", shapes, cameras]
    lines.append("Singular values are in the solver's units (input / scale).")
    return "\n".join(lines)
