"""What a recording of a reconstruction shows, as numpy arrays (no rerun, no matplotlib).

:func:`recording_content` maps a :class:`nrsfm.Reconstruction` (and its ground truth) to a
:class:`RecordingContent`, which the Rerun recording (:mod:`.recording`) and the figures
(:mod:`.figures`) draw. Estimate and ground truth are overlaid as the metrics align them:
each estimated shape by a per-frame similarity Procrustes onto the ground truth in its world
frame (as ``e3d``), the cameras and rotation samples by one global orthogonal ``Q``
minimising ``sum_f ||R_gt,f[:2] - R_est,f[:2] Q||_F^2`` (as ``e_R``), completed with
``r3 = r1 x r2``. Without ground truth the estimate is drawn as returned.

A perspective result (``result.perspective``, :mod:`nrsfm.stages.perspective`) is drawn in
its own world frame instead, so that the cameras' translations show: the shapes as returned
(in units of each frame's centroid depth), each camera at its centre ``-R_f' t_f`` with the
intrinsics' frustum, and the ground truth similarity-aligned per frame onto the estimate (as
``e3d`` aligns them); the image in pixels: the tracks, the orthographic start's projection
and the perspective projection, with their per-frame RMS distances to the tracks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Shape-stage history quantities drawn, in this order (ADMM | bilinear solver).
HISTORY_KEYS = ("cost", "data_term", "residual", "rho", "grad_norm")
#: Perspective-refinement history quantities drawn (:class:`~nrsfm.stages.perspective.
#: PerspectiveResult` ``history``).
PERSPECTIVE_HISTORY_KEYS = ("cost", "data_term")


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
    point_scale: float | None = None  # points' radius in POINT_RADIUS units (camera_distance)
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
    # a perspective result (None otherwise): the image in pixels, the cameras' centres
    camera_centres: np.ndarray | None = None  # (F, 3) -R_f' t_f in the world frame
    intrinsics: np.ndarray | None = None  # (3, 3) camera matrix (pixels)
    image_size: tuple | None = None  # (width, height) pixels
    orthographic_image: np.ndarray | None = None  # (F, P, 2) the start's projection, pixels
    perspective_image: np.ndarray | None = None  # (F, P, 2) pi(R_f S_f + t_f), pixels
    reprojection_per_frame: dict = field(default_factory=dict)  # name -> (F,) RMS, pixels
    perspective_history: dict = field(default_factory=dict)  # name -> (n_iter + 1,)

    @property
    def perspective(self):
        """Whether this is the content of a perspective result."""
        return self.perspective_image is not None


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


def _pixels(x, A):
    """(F, 2, P) normalised image coordinates -> pixels (F, P, 2), by the camera matrix."""
    return (A[:2, :2] @ x + A[:2, 2:]).transpose(0, 2, 1).copy()


def _rms_per_frame(d, mask):
    """(F,) RMS length of the (F, P, 2) image differences ``d`` over the points in ``mask``."""
    n = np.maximum(mask.sum(axis=1), 1)
    return np.sqrt(np.sum(np.where(mask[..., None], d, 0.0) ** 2, axis=(1, 2)) / n)


def perspective_cameras(result):
    """A perspective result's cameras as drawn: the (F, 3) centres ``-R_f' t_f`` in the
    refinement's world frame, their mean distance from its origin and the cameras' axis
    length (the frusta reach 3 times as far)."""
    R = np.asarray(result.rotations, float)
    t = np.asarray(result.perspective.translations, float)
    centres = -np.einsum("fji,fj->fi", R, t)
    distance = float(np.mean(np.linalg.norm(centres, axis=1)))
    return centres, distance, 0.12 * distance


def _perspective_content(c, result, sequence, image_size=None):
    """Redraw the world and the image of ``c`` for a perspective result (module docstring):
    shapes and cameras in the refinement's world frame, the image in pixels."""
    from ..geometry import align_similarity

    p, F, P = result.perspective, result.n_frames, result.n_points
    A = np.asarray(p.intrinsics, float)
    X_est, R_est = np.asarray(result.shapes, float), np.asarray(result.rotations, float)
    c.shapes_est = X_est.transpose(0, 2, 1).copy()
    X_gt = _gt_world(sequence)
    if X_gt is not None:
        c.shapes_gt = align_similarity(X_gt, X_est).transpose(0, 2, 1).copy()
    c.cameras_est, c.cameras_gt = complete_rotations(R_est), None
    c.camera_centres, c.camera_distance, c.axis_length = perspective_cameras(result)
    extent = float(np.max(np.linalg.norm(X_est, axis=1))) if X_est.size else 1.0
    extent = extent if extent > 0 else 1.0
    c.point_scale = 3.0 * extent  # the points twice the size they have in an orthographic view
    if image_size is None and sequence is not None:
        image_size = sequence.extra.get("image_size")
    height, width = (2.0 * A[1, 2], 2.0 * A[0, 2]) if image_size is None else image_size[:2]
    c.intrinsics, c.image_size = A, (float(width), float(height))
    # the tracks, the orthographic start (its rotations and shapes, the image centroids)
    # and the perspective projection, all in pixels
    centroids = np.asarray(result.row_means, float).reshape(F, 2, 1)
    x = np.asarray(result.W, float).reshape(F, 2, P) + centroids
    R0 = np.asarray(result.rotation_stage.rotations, float)
    X0 = np.asarray(result.shape_stage.shapes, float) * result.scale
    Y = p.camera_points
    c.tracks = _pixels(x, A)
    c.orthographic_image = _pixels(R0[:, :2] @ X0 + centroids, A)
    c.perspective_image = _pixels(Y[:, :2] / Y[:, 2:3], A)
    c.reprojected = None
    seen = np.ones((F, P), bool) if result.observed is None else np.asarray(result.observed)
    for name in ("orthographic", "perspective"):
        d = getattr(c, f"{name}_image") - c.tracks
        c.reprojection_per_frame[name] = _rms_per_frame(d, seen)
    for key in PERSPECTIVE_HISTORY_KEYS:
        v = np.asarray(p.history.get(key, []), float).ravel()
        if v.size:
            c.perspective_history[key] = v


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


def recording_content(result, sequence=None, *, image_size=None):
    """The :class:`RecordingContent` of the :class:`nrsfm.Reconstruction` ``result`` (the
    parts of a stage that did not run left out), with the ground truth of ``sequence``
    (shapes, rotations, skeleton edges; as many frames) if given. ``image_size`` (height,
    width in pixels, as ``nrsfm track`` writes it; else ``sequence.extra["image_size"]``)
    sizes a perspective result's frusta; without it, twice the principal point."""
    if sequence is not None and sequence.n_frames != result.n_frames:
        raise ValueError(f"sequence has {sequence.n_frames} frames, result has {result.n_frames}")
    c, Q, R_gt = _world_content(result, sequence)
    if getattr(result, "perspective", None) is not None:
        _perspective_content(c, result, sequence, image_size)
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
    if c.perspective:
        return "\n".join(lines + _perspective_report(result.perspective, c))
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


def _perspective_report(p, c):
    """The report's lines on the perspective refinement and how it is drawn."""
    rows = [
        f"| start chosen | {p.start} |",
        *[f"| objective E, {k} start | {v:.6g} |" for k, v in p.objectives.items()],
        f"| iterations | {p.n_iter} |",
        f"| converged | {p.converged} |",
        f"| noise (normalised units) | {p.noise:.3g} |",
        f"| prior balance mu | {p.mu:.3g} |",
        f"| largest depth ratio in a frame | {p.depth_ratio:.3g} |",
        f"| reprojection RMS, orthographic start (px) | {p.reprojection_before:.4g} |",
        f"| reprojection RMS, perspective (px) | {p.reprojection_after:.4g} |",
    ]
    lines = _table("Perspective refinement|quantity|value", rows)
    f, cx, cy = c.intrinsics[0, 0], c.intrinsics[0, 2], c.intrinsics[1, 2]
    shapes = "Shapes and cameras in the refinement's world frame, in units of each frame's"
    shapes += " centroid depth: each camera at its centre -R_f' t_f (no alignment)."
    if c.shapes_gt is not None:
        shapes += " The ground truth is similarity-aligned per frame onto the estimate (as in e3d)."
    image = f"Image in pixels (focal {f:.6g}, principal point ({cx:.6g}, {cy:.6g})): the tracks,"
    image += " the orthographic start's projection and the perspective projection (their"
    image += " RMS distances to the tracks per frame: /reprojection/...)."
    notes = [shapes, image, "Singular values are the orthographic start's (solver's units)."]
    return lines + ["", "## Display", ""] + notes
