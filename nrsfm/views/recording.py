"""Rerun recording of a reconstruction: every stage's intermediates, for inspection.

:func:`save_recording` writes an ``.rrd``; :func:`build_recording` returns the stream
(buffered until a sink is attached, e.g. ``rec.save(path)``); :func:`log_content` sends a
:class:`~.content.RecordingContent` to a stream. Layout: :func:`.blueprint.make_blueprint`.

Entity paths (timeline in brackets; parts of stages that did not run and ground truth not
given are left out):

* ``/world/shapes/estimate`` Points3D (aligned) and ``.../skeleton`` LineStrips3D [frame]
* ``/world/shapes/filled``: with missing data, the points not observed in the frame,
  coloured by their fill's reliability (:func:`fill_colors`) [frame]
* ``/world/shapes/ground_truth`` (small points), ``.../rings`` (Ellipsoids3D around them)
  and ``.../skeleton`` [frame]
* ``/world/cameras/{estimate,ground_truth}``: Transform3D camera -> world with axes and a
  Pinhole frustum [frame]; ``/world/trajectory/{estimate,ground_truth}``: LineStrips3D of
  the camera centres [static]
* ``/rotations/triplet_k`` (k = 1..K): Arrows3D, the registered ``R^k_f``, grey where the
  filter dropped it; ``/rotations/averaged``, ``/rotations/ground_truth`` [frame]
* ``/rotation_samples/{kept,angle,coefficient}/triplet_k`` (angle: the geodesic angle to
  the average, radians, which the filter compares with delta), ``/rotation_samples/n_kept``,
  ``/rotation_samples/sign_from_smoothness``: Scalars [frame]
* ``/errors/e3d``, ``/errors/e_R``: Scalars [frame]
* ``/image/measured``, ``/image/reprojected``: Points2D, ``W_f`` and ``R_f X_f`` [frame]
* ``/shape_history/{cost,data_term,residual,rho,grad_norm}``: the shape-stage history, Scalars
  [shape_iteration]; ``/shape_history_bars/...``: the same as BarCharts (log10 but the cost)
  [static]
* ``/singular_values/{W,X_init,theta,log10_theta}``: BarChart [static]
* ``/run/report``: TextDocument, markdown [static]

A perspective result (``result.perspective``) is drawn in the refinement's world frame
(:mod:`.content`): ``/world/shapes/estimate`` as returned, ``/world/shapes/ground_truth``
aligned onto it, ``/world/cameras/estimate`` at the centres ``-R_f' t_f`` with the
intrinsics' frustum (no ground-truth cameras), and in place of ``/image/reprojected``:

* ``/image/measured``, ``/image/orthographic``, ``/image/perspective``: Points2D in pixels,
  the tracks, the orthographic start's projection and the perspective one [frame]
* ``/reprojection/{orthographic,perspective}``: their RMS distance to the tracks, pixels,
  Scalars [frame]
* ``/perspective_history/{cost,data_term}``: the refinement's history, Scalars
  [perspective_iteration]; ``/perspective_history_bars/...``: the same, log10, as BarCharts
  [static]
"""

from __future__ import annotations

import hashlib
import uuid
from pathlib import Path

import numpy as np

from . import rerun_log as rl
from .blueprint import HISTORY_LOG, make_blueprint
from .content import HISTORY_KEYS, recording_content

#: Top-level entity paths written (sub-paths depend on the stages that ran).
ENTITY_PATHS = ("/world", "/rotations", "/rotation_samples", "/errors", "/image")
ENTITY_PATHS += ("/shape_history", "/shape_history_bars", "/singular_values", "/run")
#: Top-level entity paths a perspective result writes besides those.
PERSPECTIVE_ENTITY_PATHS = ("/reprojection", "/perspective_history", "/perspective_history_bars")

ESTIMATE_COLOR = (255, 140, 0, 255)
GT_COLOR = (70, 130, 255, 255)
ORTHOGRAPHIC_COLOR = (40, 170, 90, 255)
AXIS_COLORS = np.array([(230, 60, 60, 255), (60, 200, 60, 255), (70, 110, 255, 255)], np.uint8)
DROPPED_COLOR = (140, 140, 140, 110)
#: Point radius, in multiples of the camera distance; lines are 0.4 of it.
POINT_RADIUS, LINE_RADIUS = 0.016, 0.4


def fill_colors(gain, spread=None):
    """(n, 4) uint8 from yellow (reliable) through orange (the flag's threshold) to red: by
    the fill gain (yellow at 1, orange at ``MAX_GAIN``, red from ``MAX_GAIN^2``, log scale)
    or, where ``spread`` is finite (a point filled from its neighbours), by that spread
    (yellow at 0, orange at ``SPREAD_MAX``, red from ``2 SPREAD_MAX``)."""
    from ..stages.completion import MAX_GAIN
    from ..stages.fill import SPREAD_MAX

    gain = np.asarray(gain, float)
    t = np.clip(np.log(np.maximum(gain, 1.0)) / (2.0 * np.log(MAX_GAIN)), 0.0, 1.0)
    if spread is not None:
        spread = np.asarray(spread, float)
        by_spread = np.isfinite(spread)
        t_spread = np.clip(np.where(by_spread, spread, 0.0) / (2.0 * SPREAD_MAX), 0.0, 1.0)
        t = np.where(by_spread, t_spread, t)
    out = np.empty((t.size, 4), np.uint8)
    out[:, 0], out[:, 1], out[:, 2], out[:, 3] = 255, (230 * (1.0 - t)).astype(int), 30, 255
    return out


def _log_shapes(rec, rr, c, r_pt, r_ln):
    """Estimate: small bright points; ground truth: small dots inside wireframe rings, so an
    estimate on it stays visible and one that misses it shows as a blue dot outside."""
    fr, has_edges = c.frames, c.edges is not None and len(c.edges)
    rl.send_points(rec, rr, "/world/shapes/estimate", c.shapes_est, fr, ESTIMATE_COLOR, r_pt)
    if has_edges:
        path = "/world/shapes/estimate/skeleton"
        rl.send_skeleton(rec, rr, path, c.shapes_est, c.edges, fr, ESTIMATE_COLOR, r_ln)
    if c.filled is not None and c.filled.any():
        gain = np.broadcast_to(c.fill_gain, c.filled.shape)[c.filled]
        spread = c.fill_spread
        spread = None if spread is None else np.broadcast_to(spread, c.filled.shape)[c.filled]
        colors = fill_colors(gain, spread)
        path = "/world/shapes/filled"
        rl.send_masked_points(rec, rr, path, c.shapes_est, c.filled, fr, colors, 1.8 * r_pt)
    if c.shapes_gt is None:
        return
    path = "/world/shapes/ground_truth"
    rl.send_points(rec, rr, path, c.shapes_gt, fr, GT_COLOR, 0.6 * r_pt)
    F, P = c.shapes_gt.shape[:2]
    rings = rr.Ellipsoids3D.columns(centers=c.shapes_gt.reshape(-1, 3)).partition([P] * F)
    index = [rr.TimeColumn("frame", sequence=fr)]
    rec.send_columns(f"{path}/rings", indexes=index, columns=rings)
    kw = dict(half_sizes=[[2.0 * r_pt] * 3], colors=[GT_COLOR], line_radii=[0.12 * r_pt])
    rings = rr.Ellipsoids3D.from_fields(fill_mode=rr.components.FillMode.MajorWireframe, **kw)
    rec.log(f"{path}/rings", rings, static=True)
    if has_edges:
        skeleton = f"{path}/skeleton"
        rl.send_skeleton(rec, rr, skeleton, c.shapes_gt, c.edges, fr, GT_COLOR, 0.6 * r_ln)


def log_perspective_cameras(rec, rr, R, centres, frames, sizes, pinhole, color, r_ln):
    """``/world/cameras/estimate``: camera f at its centre ``centres[f]`` (rotation ``R_f``
    world -> camera) with the frustum of ``pinhole`` = (camera matrix, (width, height)),
    ``sizes`` = (camera distance, axis length) (:func:`.content.perspective_cameras`); and
    ``/world/trajectory/estimate``, the line strip of the centres (radius ``r_ln``)."""
    args = (R, frames, *sizes, color, 3.0)
    path = "/world/cameras/estimate"
    centres = rl.send_camera(rec, rr, path, *args, centres=centres, pinhole=pinhole)
    strip = rr.LineStrips3D([centres], colors=[color], radii=[r_ln])
    rec.log("/world/trajectory/estimate", strip, static=True)


def _log_perspective_cameras_and_image(rec, rr, c, r_ln):
    """Cameras at their centres with the intrinsics' frusta; the image in pixels: the tracks
    (large, blue), the orthographic start's projection (green), the perspective one (small,
    orange)."""
    sizes, pinhole = (c.camera_distance, c.axis_length), (c.intrinsics, c.image_size)
    args = (c.cameras_est, c.camera_centres, c.frames, sizes, pinhole, ESTIMATE_COLOR, r_ln)
    log_perspective_cameras(rec, rr, *args)
    images = [("measured", c.tracks, GT_COLOR, -7.0, 1.0)]
    images.append(("orthographic", c.orthographic_image, ORTHOGRAPHIC_COLOR, -5.0, 2.0))
    images.append(("perspective", c.perspective_image, ESTIMATE_COLOR, -3.0, 3.0))
    _log_images(rec, rr, c, images)


def _log_perspective_series(rec, rr, c):
    """Per-frame reprojection RMS (pixels) and the refinement's history."""
    names = dict(orthographic="orthographic start", perspective="perspective refinement")
    colors = dict(orthographic=ORTHOGRAPHIC_COLOR[:3], perspective=ESTIMATE_COLOR[:3])
    for name, v in c.reprojection_per_frame.items():
        path = f"/reprojection/{name}"
        rl.send_scalars(rec, rr, path, v, c.frames, name=names[name], color=[colors[name]])
    for name, v in c.perspective_history.items():
        it = np.arange(v.size)
        rl.send_scalars(rec, rr, f"/perspective_history/{name}", v, it, "perspective_iteration")
        color = ESTIMATE_COLOR if name == "cost" else (90, 90, 200, 255)
        path = f"/perspective_history_bars/{name}"
        rl.send_bars(rec, rr, path, rl.log10(v), abscissa=it, color=color)


def _log_cameras_and_image(rec, rr, c, r_ln):
    if c.perspective:
        _log_perspective_cameras_and_image(rec, rr, c, r_ln)
        return
    # the ground truth's frustum is the larger one: both show when they coincide
    cameras = [("estimate", c.cameras_est, ESTIMATE_COLOR, 1.0)]
    for name, R, color, frustum in cameras + [("ground_truth", c.cameras_gt, GT_COLOR, 1.5)]:
        if R is None:
            continue
        args = (R, c.frames, c.camera_distance, c.axis_length, color, frustum)
        centres = rl.send_camera(rec, rr, f"/world/cameras/{name}", *args)
        strip = rr.LineStrips3D([centres], colors=[color], radii=[r_ln])
        rec.log(f"/world/trajectory/{name}", strip, static=True)
    # measured tracks (large, blue) and reprojected estimate (small); radii in screen points
    # (negative in rerun): the same size at any zoom and data scale
    images = [("measured", c.tracks, GT_COLOR, -7.0, 1.0)]
    images.append(("reprojected", c.reprojected, ESTIMATE_COLOR, -4.0, 2.0))
    _log_images(rec, rr, c, images)


def _log_images(rec, rr, c, images):
    """Point sets ``(name, points, color, radius, draw order)`` under ``/image/name``, per
    frame, each with its static style."""
    for name, pts, color, radius, order in images:
        rl.send_points_2d(rec, rr, f"/image/{name}", pts, c.frames)
        style = rr.Points2D.from_fields(colors=[color], radii=[radius], draw_order=order)
        rec.log(f"/image/{name}", style, static=True)


def _log_rotations(rec, rr, c):
    """Registered rotation samples per triplet, the filter's choice, average, ground truth."""
    fr, F = c.frames, c.n_frames
    for k in range(0 if c.triplet_rotations is None else c.triplet_rotations.shape[0]):
        colors = np.broadcast_to(AXIS_COLORS, (F, 3, 4)).copy()
        colors[~c.triplet_kept[k]] = DROPPED_COLOR
        name, label = f"triplet_{k + 1}", f"triplet {k + 1}"
        R = c.triplet_rotations[k]
        rl.send_axes(rec, rr, f"/rotations/{name}", R, fr, colors, 1.0, 0.004)
        kept = c.triplet_kept[k].astype(float)
        rl.send_scalars(rec, rr, f"/rotation_samples/kept/{name}", kept, fr)
        angle = c.triplet_angle[k]
        rl.send_scalars(rec, rr, f"/rotation_samples/angle/{name}", angle, fr, name=label)
        if c.triplet_coefficients is not None:
            path = f"/rotation_samples/coefficient/{name}"
            rl.send_scalars(rec, rr, path, c.triplet_coefficients[k], fr, name=label)
    if c.triplet_rotations is not None:
        n_kept, name = c.triplet_kept.sum(axis=0), "samples kept by the filter"
        path = "/rotation_samples/n_kept"
        rl.send_scalars(rec, rr, path, n_kept, fr, name=name, color=[(60, 160, 60)])
    if c.sign_from_smoothness is not None:
        flips, name = c.sign_from_smoothness.astype(float), "depth sign flipped (1)"
        path = "/rotation_samples/sign_from_smoothness"
        rl.send_scalars(rec, rr, path, flips, fr, name=name, color=[(200, 60, 200)])
    if c.averaged is not None:
        colors = np.broadcast_to(AXIS_COLORS, (F, 3, 4))
        rl.send_axes(rec, rr, "/rotations/averaged", c.averaged, fr, colors, 1.15, 0.014)
    if c.rotations_gt_display is not None:
        pale = (0.45 * AXIS_COLORS[:, :3] + 0.55 * 255).astype(np.uint8)
        pale = np.concatenate([pale, np.full((3, 1), 255, np.uint8)], axis=1)
        pale = np.broadcast_to(pale, (F, 3, 4))
        labels = ["x GT", "y GT", "z GT"]
        path = "/rotations/ground_truth"
        rl.send_axes(rec, rr, path, c.rotations_gt_display, fr, pale, 1.35, 0.022, labels=labels)


def _log_series(rec, rr, c):
    """Per-frame errors, shape-stage history, spectra and the report."""
    for name, v in c.errors_per_frame.items():
        rl.send_scalars(rec, rr, f"/errors/{name}", v, c.frames, name=name)
    # the history on its own timeline (exact) and as static bar charts, which show on any
    # timeline (log10 where the values span decades)
    for name, v in c.admm.items():
        it = np.arange(v.size)
        rl.send_scalars(rec, rr, f"/shape_history/{name}", v, it, "shape_iteration", name)
        if name in HISTORY_KEYS:
            bars = rl.log10(v) if name in HISTORY_LOG else v
            color = ESTIMATE_COLOR if name == "cost" else (90, 90, 200, 255)
            rl.send_bars(rec, rr, f"/shape_history_bars/{name}", bars, abscissa=it, color=color)
    for name, v in c.singular_values.items():
        rec.log(f"/singular_values/{name}", rr.BarChart(v), static=True)
    if "theta" in c.singular_values:
        theta = rl.log10(c.singular_values["theta"])
        rl.send_bars(rec, rr, "/singular_values/log10_theta", theta)
    if c.perspective:
        _log_perspective_series(rec, rr, c)
    report = rr.TextDocument(c.report, media_type=rr.MediaType.MARKDOWN)
    rec.log("/run/report", report, static=True)


def log_content(rec, content):
    """Send a :class:`~.content.RecordingContent` to the recording stream ``rec``."""
    import rerun as rr

    r_pt = POINT_RADIUS * (content.point_scale or content.camera_distance)
    _log_shapes(rec, rr, content, r_pt, LINE_RADIUS * r_pt)
    _log_cameras_and_image(rec, rr, content, LINE_RADIUS * r_pt)
    _log_rotations(rec, rr, content)
    _log_series(rec, rr, content)


def recording_id_of(result):
    """The recording id of a run: the same W, K, settings and seed give the same id (the
    bytes of two recordings differ still: Rerun stamps every row with its own id and time)."""
    h = hashlib.sha256(np.ascontiguousarray(result.W).tobytes())
    h.update(repr((result.K, getattr(result, "settings", None), result.seed)).encode())
    return str(uuid.UUID(h.hexdigest()[:32]))


def build_recording(
    result,
    sequence=None,
    *,
    application_id="nrsfm",
    recording_id=None,
    blueprint=None,
    image_size=None,
):
    """A ``rerun.RecordingStream`` holding the run of ``result`` (a :class:`nrsfm.
    Reconstruction`, with the ground truth ``sequence`` overlaid), its blueprint sent (the
    default layout, or ``blueprint``), buffered until a sink is attached
    (``rec.save(path)``, ``rec.spawn()``); more can be logged to it before. ``image_size``:
    (height, width) of a perspective run's images (:func:`.content.recording_content`)."""
    content = recording_content(result, sequence, image_size=image_size)
    rec = rl.new_stream(application_id, recording_id or recording_id_of(result))
    rl.send_blueprint(rec, make_blueprint(content) if blueprint is None else blueprint)
    log_content(rec, content)
    return rec


def save_recording(
    result,
    path,
    sequence=None,
    *,
    application_id="nrsfm",
    recording_id=None,
    blueprint=None,
    extra=None,
    image_size=None,
):
    """Write the recording of ``result`` (with the ground truth ``sequence``) to the ``.rrd``
    file ``path`` (parent folders created) and return its Path; the stream is closed and its
    threads released, so repeated calls do not accumulate threads.

    ``blueprint`` (a ``rerun.blueprint.Blueprint``) replaces the default layout; ``extra``,
    a function of the open stream, logs more entities (a lesson's own series);
    ``image_size``: (height, width) of a perspective run's images (default: twice the
    principal point, or ``sequence.extra["image_size"]``)."""
    content = recording_content(result, sequence, image_size=image_size)
    rid = recording_id or recording_id_of(result)
    layout = make_blueprint(content) if blueprint is None else blueprint
    with rl.rrd_stream(path, layout, application_id, rid) as rec:
        log_content(rec, content)
        if extra is not None:
            extra(rec)
    return Path(path)
