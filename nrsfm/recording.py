"""Rerun recordings of a reconstruction: every stage's intermediates, for inspection.

Two steps, kept apart:

* :func:`recording_content` computes what is shown (pure numpy, no rerun): the estimate
  aligned to the ground truth for display, per-frame errors, the rotation samples of every
  corrective triplet, the ADMM history, singular values and a text report.
* :func:`log_content` sends that content to a ``rerun.RecordingStream``.

:func:`build_recording` does both and returns the stream (buffered in memory until a sink
is attached, e.g. ``rec.save(path)`` or ``rec.notebook_show()``); :func:`save_recording`
writes an ``.rrd`` file.

Display alignment (what the 3D view shows)
------------------------------------------
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

Entity paths (timeline in brackets)
-----------------------------------
* ``/world/shapes/estimate`` Points3D, the aligned estimate [frame];
  ``/world/shapes/estimate/skeleton`` LineStrips3D where the sequence has edges [frame]
* ``/world/shapes/ground_truth`` (small points), ``.../rings`` (wireframe spheres around
  them, Ellipsoids3D) and ``.../skeleton`` [frame]
* ``/world/cameras/estimate``, ``/world/cameras/ground_truth``: Transform3D camera -> world
  (rotation ``R_f'``, centre ``-d r3_f``) drawn with TransformAxes3D (x, y, viewing
  direction z in red, green, blue) and a Pinhole frustum in the camera's colour (the
  ground truth's larger) [frame]
* ``/world/trajectory/estimate``, ``/world/trajectory/ground_truth``: LineStrips3D of the
  camera centres [static]
* ``/rotations/triplet_k`` (k = 1..K): Arrows3D, the rows of the registered ``R^k_f``,
  grey where the filter dropped the sample; ``/rotations/averaged`` (the L1 average, before
  the smoothness sign rule), ``/rotations/ground_truth`` [frame]
* ``/rotation_samples/kept/triplet_k`` (1 kept, 0 dropped),
  ``/rotation_samples/distance/triplet_k`` (chordal ``||R^k_f - R_avg,f||_F``),
  ``/rotation_samples/coefficient/triplet_k`` (``|c_fk|``),
  ``/rotation_samples/n_kept`` (samples kept per frame),
  ``/rotation_samples/sign_from_smoothness`` (1 where the depth sign was flipped):
  Scalars [frame]
* ``/errors/e3d``, ``/errors/e_R``: per-frame errors, Scalars [frame]
* ``/image/measured``, ``/image/reprojected``: Points2D, ``W_f`` and ``R_f X_f`` [frame]
* ``/admm/cost``, ``/admm/data_term``, ``/admm/residual``, ``/admm/rho``: the raw ADMM
  history, Scalars [admm_iteration]
* ``/admm_history/cost`` and ``/admm_history/{data_term,residual,rho}`` (log10): the same
  history as BarCharts over the iteration, shown in the default layout whatever the
  timeline [static]
* ``/singular_values/W`` (of ``W / scale``), ``/singular_values/X_init`` (of
  ``X_init# / scale``), ``/singular_values/theta`` (the weights) and
  ``/singular_values/log10_theta``: BarChart [static]
* ``/run/report``: TextDocument, markdown: parameters, errors, timings [static]

The blueprint (:func:`make_blueprint`) opens on the timeline ``frame``; every view in it
shows data there. Parts of a stage that did not run (``rotation_stage`` / ``shape_stage`` None) and ground
truth that is not given are left out.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .metrics import camera_alignment  # noqa: F401  (re-exported for notebooks)

__all__ = ["RecordingContent", "recording_content", "log_content", "make_blueprint",
           "build_recording", "save_recording", "output_path", "show_recording", "shown_path",
           "ENTITY_PATHS"]

#: Top-level entity paths written (sub-paths depend on the stages that ran).
ENTITY_PATHS = ("/world", "/rotations", "/rotation_samples", "/errors", "/image", "/admm",
                "/admm_log10", "/singular_values", "/run")

ESTIMATE_COLOR = (255, 140, 0, 255)
GT_COLOR = (70, 130, 255, 255)
AXIS_COLORS = np.array([(230, 60, 60, 255), (60, 200, 60, 255), (70, 110, 255, 255)],
                       dtype=np.uint8)
DROPPED_COLOR = (140, 140, 140, 110)
ADMM_KEYS = ("cost", "data_term", "residual", "rho", "grad_norm")  # admm | bilinear


# --------------------------------------------------------------------------- computation

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


def _complete(R2):
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


def recording_content(result, sequence=None):
    """Compute what a recording of ``result`` shows (no rerun calls).

    Parameters
    ----------
    result : nrsfm.Reconstruction
        Stages may be missing (``rotation_stage`` / ``shape_stage`` None): their parts are
        left out.
    sequence : data_tools.Sequence, optional
        Ground truth (shapes, rotations, skeleton edges). Frame count must match.

    Returns
    -------
    RecordingContent
    """
    from .geometry import align_similarity as similarity_align
    from .metrics import e3d, rotation_error
    from .stages.shape import phi

    F, P = result.n_frames, result.n_points
    X_est = np.asarray(result.shapes, float)
    R_est = np.asarray(result.rotations, float)
    if sequence is not None and sequence.n_frames != F:
        raise ValueError(f"sequence has {sequence.n_frames} frames, result has {F}")

    X_gt = _gt_world(sequence)
    R_gt = None if sequence is None or sequence.rotations is None else np.asarray(
        sequence.rotations, float)
    if X_gt is not None:
        X_disp = similarity_align(X_est, X_gt)
    else:
        X_disp = X_est - X_est.mean(axis=2, keepdims=True)
    Q = camera_alignment(R_est, R_gt) if R_gt is not None else np.eye(3)

    def disp_rot(R):
        return _complete(np.asarray(R, float)[..., :2, :] @ Q)

    ref = X_gt if X_gt is not None else X_disp
    extent = float(np.max(np.linalg.norm(ref, axis=1))) if ref.size else 1.0
    extent = extent if extent > 0 else 1.0
    c = RecordingContent(n_frames=F, n_points=P, frames=np.arange(F),
                         shapes_est=X_disp.transpose(0, 2, 1).copy(),
                         shapes_gt=None if X_gt is None else X_gt.transpose(0, 2, 1).copy(),
                         edges=None if sequence is None or sequence.edges is None
                         else np.asarray(sequence.edges, int),
                         cameras_est=disp_rot(R_est),
                         cameras_gt=None if R_gt is None else _complete(R_gt),
                         camera_distance=1.5 * extent, axis_length=0.4 * extent,
                         aligned=X_gt is not None)

    Wt = np.asarray(result.W, float).reshape(F, 2, P)
    c.tracks = Wt.transpose(0, 2, 1).copy()
    c.reprojected = (R_est[:, :2] @ X_est).transpose(0, 2, 1).copy()

    # errors
    if sequence is not None and sequence.shapes is not None:
        c.errors_per_frame["e3d"] = e3d(X_est, sequence.shapes, per_frame=True)
    if R_gt is not None:
        c.errors_per_frame["e_R"] = rotation_error(R_est, R_gt, per_frame=True)
    c.errors = {k: float(np.mean(v)) for k, v in c.errors_per_frame.items()}
    c.errors["reprojection_rms"] = result.reprojection_error()

    # rotation stage
    rs = result.rotation_stage
    registered = _stage_value(rs, "registered")
    if registered is not None:
        registered = np.asarray(registered, float)
        K = registered.shape[0]
        c.triplet_rotations = disp_rot(registered)
        kept = _stage_value(rs, "kept")
        c.triplet_kept = (np.ones((K, F), bool) if kept is None
                          else np.asarray(kept, bool).reshape(K, F))
        avg = _stage_value(rs, "averaged")
        final = _complete(avg if avg is not None else R_est)
        c.triplet_distance = np.linalg.norm(_complete(registered) - final[None], axis=(2, 3))
        coeff = _stage_value(rs, "coefficients")
        if coeff is not None:
            c.triplet_coefficients = np.asarray(coeff, float).reshape(K, F)
    flips = _stage_value(rs, "sign_from_smoothness")
    if flips is not None:
        c.sign_from_smoothness = np.asarray(flips, bool).ravel()
    averaged = _stage_value(rs, "averaged")
    if averaged is not None:
        c.averaged = disp_rot(averaged)
    if rs is not None and R_gt is not None:
        c.rotations_gt_display = _complete(R_gt)

    # shape stage
    ss = result.shape_stage
    history = _stage_value(ss, "history") or {}
    for key in list(ADMM_KEYS) + sorted(k for k in history if k not in ADMM_KEYS):
        if key in history:
            v = np.asarray(history[key], float).ravel()
            if v.size:
                c.admm[key] = v

    # singular values, in the solver's units (input / result.scale)
    c.singular_values["W"] = np.asarray(result.factorization.singular_values, float)
    sv_x = _stage_value(ss, "X_init_singular_values")
    if sv_x is None:
        sv_x = np.linalg.svd(phi(np.asarray(result.X_init, float) / result.scale),
                             compute_uv=False)
    c.singular_values["X_init"] = np.asarray(sv_x, float)
    theta = _stage_value(ss, "theta")
    if theta is not None:
        c.singular_values["theta"] = np.asarray(theta, float).ravel()

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


def _report(result, sequence, c):
    name = getattr(sequence, "name", None) or "(no ground truth)"
    lines = [f"# nrsfm run: `{result.method}` on {name}", "",
             f"F = {result.n_frames} frames, P = {result.n_points} points, K = {result.K}, "
             f"scale = {result.scale:.6g}", "", "## Errors", "", "| metric | value |",
             "| --- | --- |"]
    lines += [f"| {k} | {v:.6g} |" for k, v in c.errors.items()]
    lines += ["", "## Stages", "",
              f"- rotation stage: {'ran' if result.rotation_stage is not None else 'skipped (rotations given)'}",
              f"- shape stage: {'ran' if result.shape_stage is not None else 'skipped (pseudo-inverse + rank-K truncation)'}"]
    ss = result.shape_stage
    if ss is not None:
        solver = result.params.get("shape_solver", "admm")
        lines.append(f"- shape solver {solver}: {_stage_value(ss, 'n_iter')} iterations, "
                     f"converged = {_stage_value(ss, 'converged')}")
        if _stage_value(ss, "grad_norm") is not None:
            lines.append(f"- shape objective {_stage_value(ss, 'objective'):.6g}, relative "
                         f"gradient norm {_stage_value(ss, 'grad_norm'):.3g} (first-order "
                         "optimality)")
    rs = result.rotation_stage
    if c.triplet_kept is not None:
        lines.append(f"- rotation samples kept by the filter: {int(c.triplet_kept.sum())} of "
                     f"{c.triplet_kept.size}")
    if rs is not None and _stage_value(rs, "strategy") is not None:
        lines.append(f"- rotation strategy: {_stage_value(rs, 'strategy')}")
    lines += ["", "## Parameters", "", "| parameter | value |", "| --- | --- |"]
    lines += [f"| {k} | {_fmt(v)} |" for k, v in result.params.items()]
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


# --------------------------------------------------------------------------- logging

def _log10(v):
    v = np.asarray(v, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log10(np.where(v > 0, v, np.nan))


#: ADMM quantities drawn on a log10 axis (they span many orders of magnitude).
ADMM_LOG = ("data_term", "residual", "rho", "grad_norm")


def _admm_label(name):
    return f"log10 {name}" if name in ADMM_LOG else name


def _eye(content):
    """Opening eye of the 3D views: behind and above the first camera, both cameras and
    shapes in view. Returns (position, up) for the world view."""
    R = content.cameras_gt if content.cameras_gt is not None else content.cameras_est
    if R is None or not len(R):
        return np.array([1.0, -1.5, 1.0]) * 2.5 * content.camera_distance, np.array([0, 0, 1.0])
    r1, r2, r3 = R[0]
    direction = -r3 - 0.55 * r2 + 0.45 * r1     # behind camera 0, above it (image y down)
    direction /= np.linalg.norm(direction)
    return 2.2 * content.camera_distance * direction, -r2


def make_blueprint(content=None):
    """The default layout, in which every view has data on the opening timeline ``frame``.

    Left: the 3D world (shapes, cameras as frusta with RGB axes), the rotation samples and
    the image. Right: the ADMM history as one bar chart per quantity (static, so it shows
    whatever the timeline; data term, residual and rho on log10 axes), per-frame errors and
    rotation-sample series in tabs, the spectra (theta on a log10 axis) and the report.
    """
    import rerun.blueprint as rrb

    has = (lambda attr: True) if content is None else (
        lambda attr: bool(getattr(content, attr) is not None and
                          (not isinstance(getattr(content, attr), dict)
                           or getattr(content, attr))))
    world_kw = {}
    if content is not None:
        pos, up = _eye(content)
        world_kw["eye_controls"] = rrb.EyeControls3D(position=pos, look_target=[0, 0, 0],
                                                     eye_up=up)
    gt_shapes = content is None or content.shapes_gt is not None
    left_top = rrb.Spatial3DView(
        origin="/world", name=("shapes (orange estimate, blue ground truth) and cameras"
                               if gt_shapes else "shapes and cameras (estimate)"), **world_kw)
    lower = []
    if has("triplet_rotations"):
        lower.append(rrb.Spatial3DView(
            origin="/rotations", name="camera axes: samples (thin), average (thick)" + (
                ", GT (pale)" if content is None or content.rotations_gt_display is not None
                else ""),
            eye_controls=rrb.EyeControls3D(position=[1.7, -2.0, 1.4], look_target=[0, 0, 0],
                                           eye_up=[0, 0, 1])))
    lower.append(rrb.Spatial2DView(origin="/image", name="image: measured (blue) vs "
                                   "reprojected (orange)"))
    left = rrb.Vertical(left_top, rrb.Horizontal(*lower), row_shares=[3, 2])

    no_legend = rrb.PlotLegend(visible=False)
    admm_names = (list(content.admm) if content is not None else list(ADMM_KEYS))
    admm = [rrb.BarChartView(origin=f"/admm_history/{n}",
                             name=("shape cost" if n == "cost"
                                   else _admm_label(n).replace("_", " ")),
                             plot_legend=no_legend)
            for n in admm_names if n in ADMM_KEYS]
    series = []
    errors = (list(content.errors_per_frame) if content is not None else ["e3d", "e_R"])
    for n in errors:
        series.append(rrb.TimeSeriesView(origin=f"/errors/{n}", name=f"{n} per frame",
                                         plot_legend=no_legend))
    if has("triplet_rotations"):
        series.append(rrb.TimeSeriesView(origin="/rotation_samples/distance",
                                         name="sample distance to average"))
        if content is None or content.triplet_coefficients is not None:
            series.append(rrb.TimeSeriesView(origin="/rotation_samples/coefficient",
                                             name="|c_fk| per triplet"))
        series.append(rrb.TimeSeriesView(
            origin="/rotation_samples", contents=["/rotation_samples/n_kept",
                                                  "/rotation_samples/sign_from_smoothness"],
            name="samples kept, sign flips"))
    spectra = [rrb.BarChartView(origin=f"/singular_values/{n}", name=title,
                                plot_legend=no_legend)
               for n, title in (("W", "singular values of W"),
                                ("X_init", "singular values of X_init#"),
                                ("log10_theta", "log10 weights theta"))
               if content is None or n in content.singular_values
               or (n == "log10_theta" and "theta" in content.singular_values)]
    report = rrb.TextDocumentView(origin="/run/report", name="report")
    right = []
    if admm:
        right.append(rrb.Grid(*admm, grid_columns=2, name="shape stage"))
    if series:
        right.append(rrb.Tabs(*series, name="per frame"))
    right.append(rrb.Tabs(*spectra, report, name="spectra and report"))
    shares = [3, 2, 2] if len(right) == 3 else [1] * len(right)
    return rrb.Blueprint(
        rrb.Horizontal(left, rrb.Vertical(*right, row_shares=shares), column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="frame"),
        auto_views=False, collapse_panels=False)


def _send_points(rec, rr, path, pts, frames, color, radius):
    F, P = pts.shape[:2]
    rec.send_columns(path, indexes=[rr.TimeColumn("frame", sequence=frames)],
                     columns=rr.Points3D.columns(positions=pts.reshape(-1, 3)).partition(
                         [P] * F))
    rec.log(path, rr.Points3D.from_fields(colors=[color], radii=[radius]), static=True)


def _send_skeleton(rec, rr, path, pts, edges, frames, color, radius):
    F = pts.shape[0]
    strips = pts[:, edges]                      # (F, E, 2, 3)
    rec.send_columns(path, indexes=[rr.TimeColumn("frame", sequence=frames)],
                     columns=rr.LineStrips3D.columns(strips=list(strips.reshape(-1, 2, 3)))
                     .partition([len(edges)] * F))
    rec.log(path, rr.LineStrips3D.from_fields(colors=[color], radii=[radius]), static=True)


def _send_scalars(rec, rr, path, values, index, timeline, name=None, color=None):
    rec.send_columns(path, indexes=[rr.TimeColumn(timeline, sequence=index)],
                     columns=rr.Scalars.columns(scalars=np.asarray(values, float)))
    if name or color is not None:
        rec.log(path, rr.SeriesLines(names=name, colors=color), static=True)


def _send_camera(rec, rr, path, R, frames, distance, axis_length, color, frustum=1.0):
    """Camera f as a transform camera -> world (rotation R_f', centre -distance r3_f), drawn
    as RGB axes (x, y, viewing direction z) and a frustum in the camera's colour."""
    centres = -distance * R[:, 2, :]
    rec.send_columns(path, indexes=[rr.TimeColumn("frame", sequence=frames)],
                     columns=rr.Transform3D.columns(mat3x3=R.transpose(0, 2, 1),
                                                    translation=centres))
    rec.log(path, rr.TransformAxes3D(axis_length), static=True)
    rec.log(path, rr.Pinhole(fov_y=0.7, aspect_ratio=1.3, camera_xyz=rr.ViewCoordinates.RDF,
                             image_plane_distance=frustum * axis_length, color=color,
                             line_width=0.006 * distance), static=True)
    return centres


def _send_axes(rec, rr, path, R, frames, colors, length, radius, labels=None):
    """Rows of R_f (the camera axes in the world) as three arrows from the origin."""
    F = R.shape[0]
    rec.send_columns(path, indexes=[rr.TimeColumn("frame", sequence=frames)],
                     columns=rr.Arrows3D.columns(vectors=(length * R).reshape(-1, 3),
                                                 colors=colors.reshape(-1, 4))
                     .partition([3] * F))
    rec.log(path, rr.Arrows3D.from_fields(radii=[radius], labels=labels), static=True)


def _bars(rec, rr, path, values, abscissa=None, color=None):
    v = np.asarray(values, float)
    x = np.arange(1, v.size + 1) if abscissa is None else np.asarray(abscissa, float)
    rec.log(path, rr.BarChart(v, abscissa=x, color=color), static=True)


def log_content(rec, content):
    """Send a :class:`RecordingContent` to the recording stream ``rec``."""
    import rerun as rr

    c = content
    fr = c.frames
    r_pt = 0.016 * c.camera_distance
    r_ln = 0.4 * r_pt

    # estimate: small bright points over larger ground-truth points, so both stay visible
    _send_points(rec, rr, "/world/shapes/estimate", c.shapes_est, fr, ESTIMATE_COLOR, r_pt)
    if c.edges is not None and len(c.edges):
        _send_skeleton(rec, rr, "/world/shapes/estimate/skeleton", c.shapes_est, c.edges, fr,
                       ESTIMATE_COLOR, r_ln)
    if c.shapes_gt is not None:
        # ground truth: small dots inside wireframe rings, so an estimate that sits on it
        # stays visible and one that misses it shows as a blue dot outside an orange one
        path = "/world/shapes/ground_truth"
        _send_points(rec, rr, path, c.shapes_gt, fr, GT_COLOR, 0.6 * r_pt)
        F, P = c.shapes_gt.shape[:2]
        rec.send_columns(f"{path}/rings", indexes=[rr.TimeColumn("frame", sequence=fr)],
                         columns=rr.Ellipsoids3D.columns(
                             centers=c.shapes_gt.reshape(-1, 3)).partition([P] * F))
        rec.log(f"{path}/rings", rr.Ellipsoids3D.from_fields(
            half_sizes=[[2.0 * r_pt] * 3], colors=[GT_COLOR], line_radii=[0.12 * r_pt],
            fill_mode=rr.components.FillMode.MajorWireframe), static=True)
        if c.edges is not None and len(c.edges):
            _send_skeleton(rec, rr, "/world/shapes/ground_truth/skeleton", c.shapes_gt,
                           c.edges, fr, GT_COLOR, 0.6 * r_ln)

    for name, R, color in (("estimate", c.cameras_est, ESTIMATE_COLOR),
                           ("ground_truth", c.cameras_gt, GT_COLOR)):
        if R is None:
            continue
        # the ground truth's frustum is the larger one: both show when they coincide
        centres = _send_camera(rec, rr, f"/world/cameras/{name}", R, fr, c.camera_distance,
                               c.axis_length, color, 1.0 if name == "estimate" else 1.5)
        rec.log(f"/world/trajectory/{name}",
                rr.LineStrips3D([centres], colors=[color], radii=[r_ln]), static=True)

    # 2D image: measured tracks (large, blue) and reprojection of the estimate (small)
    P = c.n_points
    # radii in screen points (negative in rerun): the same size at any zoom and data scale
    for name, pts, color, rad in (("measured", c.tracks, GT_COLOR, -7.0),
                                  ("reprojected", c.reprojected, ESTIMATE_COLOR, -4.0)):
        rec.send_columns(f"/image/{name}", indexes=[rr.TimeColumn("frame", sequence=fr)],
                         columns=rr.Points2D.columns(positions=pts.reshape(-1, 2)).partition(
                             [P] * c.n_frames))
        rec.log(f"/image/{name}", rr.Points2D.from_fields(
            colors=[color], radii=[rad], draw_order=1.0 if name == "measured" else 2.0),
            static=True)

    # rotation samples
    if c.triplet_rotations is not None:
        K = c.triplet_rotations.shape[0]
        for k in range(K):
            colors = np.broadcast_to(AXIS_COLORS, (c.n_frames, 3, 4)).copy()
            colors[~c.triplet_kept[k]] = DROPPED_COLOR
            _send_axes(rec, rr, f"/rotations/triplet_{k + 1}", c.triplet_rotations[k], fr,
                       colors, 1.0, 0.004)
            _send_scalars(rec, rr, f"/rotation_samples/kept/triplet_{k + 1}",
                          c.triplet_kept[k].astype(float), fr, "frame")
            _send_scalars(rec, rr, f"/rotation_samples/distance/triplet_{k + 1}",
                          c.triplet_distance[k], fr, "frame", f"triplet {k + 1}")
            if c.triplet_coefficients is not None:
                _send_scalars(rec, rr, f"/rotation_samples/coefficient/triplet_{k + 1}",
                              c.triplet_coefficients[k], fr, "frame", f"triplet {k + 1}")
        _send_scalars(rec, rr, "/rotation_samples/n_kept", c.triplet_kept.sum(axis=0), fr,
                      "frame", "samples kept by the filter", [(60, 160, 60)])
    if c.sign_from_smoothness is not None:
        _send_scalars(rec, rr, "/rotation_samples/sign_from_smoothness",
                      c.sign_from_smoothness.astype(float), fr, "frame",
                      "depth sign flipped (1)", [(200, 60, 200)])
    if c.averaged is not None:
        _send_axes(rec, rr, "/rotations/averaged", c.averaged, fr,
                   np.broadcast_to(AXIS_COLORS, (c.n_frames, 3, 4)), 1.15, 0.014)
    if c.rotations_gt_display is not None:
        pale = (0.45 * AXIS_COLORS[:, :3] + 0.55 * 255).astype(np.uint8)
        pale = np.concatenate([pale, np.full((3, 1), 255, np.uint8)], axis=1)
        _send_axes(rec, rr, "/rotations/ground_truth", c.rotations_gt_display, fr,
                   np.broadcast_to(pale, (c.n_frames, 3, 4)), 1.35, 0.022,
                   labels=["x GT", "y GT", "z GT"])

    for name, v in c.errors_per_frame.items():
        _send_scalars(rec, rr, f"/errors/{name}", v, fr, "frame", name)

    # ADMM history: on its own timeline (raw, exact) and as static bar charts, one per
    # quantity, which show on any timeline (log10 where the values span decades)
    for name, v in c.admm.items():
        it = np.arange(v.size)
        _send_scalars(rec, rr, f"/admm/{name}", v, it, "admm_iteration", name)
        if name in ADMM_KEYS:
            _bars(rec, rr, f"/admm_history/{name}", _log10(v) if name in ADMM_LOG else v,
                  abscissa=it, color=ESTIMATE_COLOR if name == "cost" else (90, 90, 200, 255))

    for name, v in c.singular_values.items():
        rec.log(f"/singular_values/{name}", rr.BarChart(v), static=True)
    if "theta" in c.singular_values:
        _bars(rec, rr, "/singular_values/log10_theta", _log10(c.singular_values["theta"]))

    rec.log("/run/report", rr.TextDocument(c.report, media_type=rr.MediaType.MARKDOWN),
            static=True)


def _new_stream(application_id, recording_id):
    import rerun as rr

    return rr.RecordingStream(application_id,
                              recording_id=recording_id or str(uuid.uuid4()))


def _release_streams():
    """Free the native resources (2 threads each) of recording streams no longer referenced.

    rerun-sdk keeps a dropped stream's batcher and sink threads alive until a sweep; its
    ``rr.init`` runs one, a plain ``RecordingStream`` never does.
    """
    from rerun import bindings

    sweep = getattr(bindings, "flush_and_cleanup_orphaned_recordings", None)
    if sweep is not None:
        sweep()


_BLUEPRINT_STREAMS = {}     # application id -> the one blueprint stream of this process


def _blueprint_storage(application_id, blueprint):
    """The blueprint as rerun's in-memory storage, or None if rerun's internals moved.

    rerun-sdk 0.41 turns every blueprint into a new blueprint stream (``save``'s
    ``default_blueprint``, ``send_blueprint``) whose 2 threads are never released; one
    stream per application id, given a fresh memory sink per blueprint, keeps the count
    bounded. Relies on internals of the pinned rerun-sdk, hence the fallback.
    """
    try:
        from rerun import bindings
        from rerun.recording_stream import RecordingStream

        stream = _BLUEPRINT_STREAMS.get(application_id)
        if stream is None:
            stream = RecordingStream._from_native(bindings.new_blueprint(
                application_id=application_id, make_default=False,
                make_thread_default=False, default_enabled=True))
            _BLUEPRINT_STREAMS[application_id] = stream
        memory = stream.memory_recording()        # a new sink: this blueprint only
        stream.set_time("blueprint", sequence=0)
        blueprint.to_blueprint()._log_to_stream(stream)
        stream.flush()
        return memory.storage
    except (AttributeError, ImportError, TypeError):
        return None


def _send_blueprint(rec, blueprint):
    from rerun import bindings

    storage = _blueprint_storage(rec.get_application_id(), blueprint)
    if storage is None:
        rec.send_blueprint(blueprint)
    else:
        bindings.send_blueprint(storage, True, True, recording=rec.to_native())


def build_recording(result, sequence=None, *, application_id="nrsfm", recording_id=None):
    """A ``rerun.RecordingStream`` holding the whole run (buffered until a sink is set).

    Attach a sink afterwards: ``rec.save("run.rrd")``, ``rec.notebook_show()``,
    ``rec.spawn()``; the buffered data is forwarded to it. The default blueprint is sent.

    Parameters
    ----------
    result : nrsfm.Reconstruction
    sequence : data_tools.Sequence, optional
        Ground truth to overlay (shapes, rotations, skeleton).
    application_id, recording_id : str
        Rerun identifiers; a random recording id by default.
    """
    content = recording_content(result, sequence)
    rec = _new_stream(application_id, recording_id)
    _send_blueprint(rec, make_blueprint(content))
    log_content(rec, content)
    return rec


def save_recording(result, path, sequence=None, **kw):
    """Write the recording of ``result`` to an ``.rrd`` file; returns its Path.

    Keyword arguments go to :func:`build_recording` (``application_id``,
    ``recording_id``). Parent folders are created. The stream is closed and its threads
    released, so repeated calls do not accumulate threads.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    content = recording_content(result, sequence)
    application_id = kw.pop("application_id", "nrsfm")
    rec = _new_stream(application_id, kw.pop("recording_id", None))
    if kw:
        raise TypeError(f"unexpected keyword arguments {sorted(kw)}")
    try:
        blueprint = make_blueprint(content)
        storage = _blueprint_storage(application_id, blueprint)
        if storage is None:
            rec.save(path, default_blueprint=blueprint)
        else:
            from rerun import bindings

            bindings.save(path=str(path), default_blueprint=storage,
                          recording=rec.to_native(), write_footer=True)
        log_content(rec, content)
        rec.flush()
    finally:
        rec.disconnect()
        del rec
        _release_streams()
    return path


# --------------------------------------------------------------------------- notebooks

def output_path(name, subdir="notebooks"):
    """Where notebooks and scripts write files: ``output_dir(subdir) / name``, i.e. under
    ``$NRSFM_OUT`` if set, else ``out/<subdir>/`` in the folder the user started in (never
    inside the installed package). The folder is created."""
    from .paths import output_dir

    return output_dir(subdir) / name


def shown_path(path):
    """``path`` relative to the folder the user started in when it lies below it (for
    messages and rendered notebooks), else as given."""
    from .paths import user_folder

    path = Path(path)
    try:
        return path.resolve().relative_to(user_folder().resolve())
    except ValueError:
        return path


def _interactive():
    """Whether a notebook front end will show an embedded viewer.

    ``NRSFM_VIEWER=1`` forces it, ``NRSFM_VIEWER=0`` (or ``NRSFM_NO_VIEWER``, ``CI``, a
    pytest run) turns it off. Otherwise: an IPython kernel started by a Jupyter server
    (JupyterLab, Notebook: ``JPY_SESSION_NAME`` set) or by VS Code. A kernel run by
    ``jupyter nbconvert --execute`` has no front end: it only prints the path.
    """
    import os
    import sys

    flag = os.environ.get("NRSFM_VIEWER")
    if flag in ("0", "1"):
        return flag == "1"
    if os.environ.get("CI") or os.environ.get("PYTEST_CURRENT_TEST") or os.environ.get(
            "NRSFM_NO_VIEWER"):
        return False
    ipy = sys.modules.get("IPython")
    shell = ipy.get_ipython() if ipy is not None else None
    if shell is None or getattr(shell, "kernel", None) is None:
        return False
    return bool(os.environ.get("JPY_SESSION_NAME") or os.environ.get("VSCODE_PID"))


def _offline_widget_assets():
    """Make rerun-notebook inline its viewer (JS + wasm) instead of loading it from the web,
    unless the user chose otherwise with ``RERUN_NOTEBOOK_ASSET``. Must run before
    ``rerun_notebook`` is imported."""
    import os

    os.environ.setdefault("RERUN_NOTEBOOK_ASSET", "inline")


def show_recording(path, width=1000, height=720, blueprint=None):
    """Embed a viewer of the ``.rrd`` at ``path`` in a live notebook; else print how to open it.

    The file is sent to the embedded viewer as it is, so the viewer shows the recording
    with its blueprint under the recording's own application id. The viewer's code is
    inlined from the installed ``rerun-notebook`` package (works offline; set
    ``RERUN_NOTEBOOK_ASSET`` to override). Needs the ``notebook`` extra. Headless runs
    (``CI``, pytest, ``jupyter nbconvert --execute``; see :func:`_interactive`) embed
    nothing.
    ``width``, ``height``: pixels.
    ``blueprint``: an optional layout that replaces the recording's own.
    Returns True when a viewer was embedded.
    """
    path = Path(path)
    if _interactive():
        try:
            _offline_widget_assets()
            from rerun.notebook import Viewer

            viewer = Viewer(width=width, height=height, use_global_recording=False)
            if blueprint is not None:
                from rerun.chunk import RrdReader

                app_ids = {s.application_id for s in RrdReader(path).recordings()}
                for app in app_ids:
                    viewer.set_application_blueprint(app, blueprint)
            viewer.display()
            viewer._viewer.send_rrd(path.read_bytes())
            return True
        except Exception as exc:  # viewer is optional: never break a run for it
            print(f"(no embedded viewer: {exc})")
    shown = shown_path(path)
    print(f"open the recording with: rerun {shown}   (headless or remote: rerun --web-viewer "
          f"{shown})")
    return False
