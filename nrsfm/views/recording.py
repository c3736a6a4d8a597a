"""Rerun recording of a reconstruction: every stage's intermediates, for inspection.

:func:`log_content` sends a :class:`nrsfm.views.content.RecordingContent` (what to draw,
computed without rerun) to a ``rerun.RecordingStream``; :func:`build_recording` computes
the content and returns the stream (buffered in memory until a sink is attached, e.g.
``rec.save(path)`` or ``rec.notebook_show()``); :func:`save_recording` writes an ``.rrd``
file. The layout is :func:`nrsfm.views.blueprint.make_blueprint`; the display alignment is
described in :mod:`nrsfm.views.content`.

Entity paths (timeline in brackets)
-----------------------------------
* ``/world/shapes/estimate`` Points3D, the aligned estimate [frame];
  ``/world/shapes/estimate/skeleton`` LineStrips3D where the sequence has edges [frame]
* ``/world/shapes/filled`` Points3D, with missing data: the points not observed in the
  frame (their 3D is a fill), larger, coloured by their fill's reliability: for a point
  filled from its neighbours, how far its fills stray from their median
  (``Reconstruction.fill_spread``: yellow at 0, orange at ``SPREAD_MAX`` where it becomes
  ``unreliable``, red at twice that and above); for the others their fill's noise gain
  (``Reconstruction.fill_gain``: yellow at 1, orange at ``MAX_GAIN`` where a track becomes
  undetermined) [frame]
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
* ``/admm/cost``, ``/admm/data_term``, ``/admm/residual``, ``/admm/rho``,
  ``/admm/grad_norm``: the raw shape-stage history (ADMM or bilinear solver), Scalars
  [admm_iteration]
* ``/admm_history/cost`` and ``/admm_history/{data_term,residual,rho,grad_norm}`` (log10):
  the same history as BarCharts over the iteration, shown in the default layout whatever
  the timeline [static]
* ``/singular_values/W`` (of ``W / scale``), ``/singular_values/X_init`` (of
  ``X_init# / scale``), ``/singular_values/theta`` (the weights) and
  ``/singular_values/log10_theta``: BarChart [static]
* ``/run/report``: TextDocument, markdown: parameters, errors, timings [static]

The blueprint opens on the timeline ``frame``; every view in it shows data there. Parts of
a stage that did not run (``rotation_stage`` / ``shape_stage`` None) and ground truth that
is not given are left out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import rerun_log as rl
from .blueprint import HISTORY_LOG, make_blueprint
from .content import HISTORY_KEYS, recording_content

__all__ = ["log_content", "build_recording", "save_recording", "ENTITY_PATHS"]

#: Top-level entity paths written (sub-paths depend on the stages that ran).
ENTITY_PATHS = ("/world", "/rotations", "/rotation_samples", "/errors", "/image", "/admm",
                "/admm_history", "/singular_values", "/run")

ESTIMATE_COLOR = (255, 140, 0, 255)
GT_COLOR = (70, 130, 255, 255)
AXIS_COLORS = np.array([(230, 60, 60, 255), (60, 200, 60, 255), (70, 110, 255, 255)],
                       dtype=np.uint8)
DROPPED_COLOR = (140, 140, 140, 110)
#: Point radius, in multiples of the camera distance; lines are 0.4 of it.
POINT_RADIUS = 0.016
LINE_RADIUS = 0.4


def fill_colors(gain, spread=None):
    """(n, 4) uint8 from yellow (reliable) through orange (the flag's threshold) to red,
    for the points of :func:`_log_filled`: by the fill gain (yellow at 1, orange at
    ``MAX_GAIN``, red at ``MAX_GAIN^2`` and above, log scale), or where ``spread`` is
    finite (a point filled from its neighbours) by that reliability (yellow at 0, orange
    at ``SPREAD_MAX``, red at ``2 SPREAD_MAX`` and above): it predicts a fill's error
    better than the gain (docs/missing_data_scale.md)."""
    from ..stages.completion import MAX_GAIN
    from ..stages.fill import SPREAD_MAX

    gain = np.asarray(gain, float)
    t = np.clip(np.log(np.maximum(gain, 1.0)) / (2.0 * np.log(MAX_GAIN)), 0.0, 1.0)
    if spread is not None:
        spread = np.asarray(spread, float)
        by_spread = np.isfinite(spread)
        t = np.where(by_spread, np.clip(np.where(by_spread, spread, 0.0) / (2.0 * SPREAD_MAX),
                                        0.0, 1.0), t)
    out = np.empty((t.size, 4), np.uint8)
    out[:, 0], out[:, 1], out[:, 2], out[:, 3] = 255, (230 * (1.0 - t)).astype(int), 30, 255
    return out


def _log_filled(rec, rr, c, radius):
    """The points not observed in each frame, where the input had missing data."""
    if c.filled is None or not c.filled.any():
        return
    gain = np.broadcast_to(c.fill_gain, c.filled.shape)[c.filled]
    spread = (None if c.fill_spread is None
              else np.broadcast_to(c.fill_spread, c.filled.shape)[c.filled])
    rl.send_masked_points(rec, rr, "/world/shapes/filled", c.shapes_est, c.filled, c.frames,
                          fill_colors(gain, spread), radius)


def _log_shapes(rec, rr, c, r_pt, r_ln):
    """Estimate: small bright points; ground truth: small dots inside wireframe rings, so
    an estimate that sits on it stays visible and one that misses it shows as a blue dot
    outside an orange one."""
    fr = c.frames
    rl.send_points(rec, rr, "/world/shapes/estimate", c.shapes_est, fr, ESTIMATE_COLOR, r_pt)
    has_edges = c.edges is not None and len(c.edges)
    if has_edges:
        rl.send_skeleton(rec, rr, "/world/shapes/estimate/skeleton", c.shapes_est, c.edges,
                         fr, ESTIMATE_COLOR, r_ln)
    _log_filled(rec, rr, c, 1.8 * r_pt)
    if c.shapes_gt is None:
        return
    path = "/world/shapes/ground_truth"
    rl.send_points(rec, rr, path, c.shapes_gt, fr, GT_COLOR, 0.6 * r_pt)
    F, P = c.shapes_gt.shape[:2]
    rec.send_columns(f"{path}/rings", indexes=[rr.TimeColumn("frame", sequence=fr)],
                     columns=rr.Ellipsoids3D.columns(
                         centers=c.shapes_gt.reshape(-1, 3)).partition([P] * F))
    rec.log(f"{path}/rings", rr.Ellipsoids3D.from_fields(
        half_sizes=[[2.0 * r_pt] * 3], colors=[GT_COLOR], line_radii=[0.12 * r_pt],
        fill_mode=rr.components.FillMode.MajorWireframe), static=True)
    if has_edges:
        rl.send_skeleton(rec, rr, f"{path}/skeleton", c.shapes_gt, c.edges, fr, GT_COLOR,
                         0.6 * r_ln)


def _log_cameras_and_image(rec, rr, c, r_ln):
    for name, R, color in (("estimate", c.cameras_est, ESTIMATE_COLOR),
                           ("ground_truth", c.cameras_gt, GT_COLOR)):
        if R is None:
            continue
        # the ground truth's frustum is the larger one: both show when they coincide
        centres = rl.send_camera(rec, rr, f"/world/cameras/{name}", R, c.frames,
                                 c.camera_distance, c.axis_length, color,
                                 1.0 if name == "estimate" else 1.5)
        rec.log(f"/world/trajectory/{name}",
                rr.LineStrips3D([centres], colors=[color], radii=[r_ln]), static=True)
    # 2D image: measured tracks (large, blue) and reprojection of the estimate (small);
    # radii in screen points (negative in rerun): the same size at any zoom and data scale
    for name, pts, color, rad in (("measured", c.tracks, GT_COLOR, -7.0),
                                  ("reprojected", c.reprojected, ESTIMATE_COLOR, -4.0)):
        rl.send_points_2d(rec, rr, f"/image/{name}", pts, c.frames)
        rec.log(f"/image/{name}", rr.Points2D.from_fields(
            colors=[color], radii=[rad], draw_order=1.0 if name == "measured" else 2.0),
            static=True)


def _log_triplets(rec, rr, c):
    """Registered rotation samples per triplet and the filter's choice."""
    fr = c.frames
    for k in range(c.triplet_rotations.shape[0]):
        colors = np.broadcast_to(AXIS_COLORS, (c.n_frames, 3, 4)).copy()
        colors[~c.triplet_kept[k]] = DROPPED_COLOR
        name = f"triplet_{k + 1}"
        rl.send_axes(rec, rr, f"/rotations/{name}", c.triplet_rotations[k], fr, colors, 1.0,
                     0.004)
        rl.send_scalars(rec, rr, f"/rotation_samples/kept/{name}",
                        c.triplet_kept[k].astype(float), fr)
        rl.send_scalars(rec, rr, f"/rotation_samples/distance/{name}", c.triplet_distance[k],
                        fr, name=f"triplet {k + 1}")
        if c.triplet_coefficients is not None:
            rl.send_scalars(rec, rr, f"/rotation_samples/coefficient/{name}",
                            c.triplet_coefficients[k], fr, name=f"triplet {k + 1}")
    rl.send_scalars(rec, rr, "/rotation_samples/n_kept", c.triplet_kept.sum(axis=0), fr,
                    name="samples kept by the filter", color=[(60, 160, 60)])


def _log_rotations(rec, rr, c):
    fr = c.frames
    if c.triplet_rotations is not None:
        _log_triplets(rec, rr, c)
    if c.sign_from_smoothness is not None:
        rl.send_scalars(rec, rr, "/rotation_samples/sign_from_smoothness",
                        c.sign_from_smoothness.astype(float), fr,
                        name="depth sign flipped (1)", color=[(200, 60, 200)])
    if c.averaged is not None:
        rl.send_axes(rec, rr, "/rotations/averaged", c.averaged, fr,
                     np.broadcast_to(AXIS_COLORS, (c.n_frames, 3, 4)), 1.15, 0.014)
    if c.rotations_gt_display is not None:
        pale = (0.45 * AXIS_COLORS[:, :3] + 0.55 * 255).astype(np.uint8)
        pale = np.concatenate([pale, np.full((3, 1), 255, np.uint8)], axis=1)
        rl.send_axes(rec, rr, "/rotations/ground_truth", c.rotations_gt_display, fr,
                     np.broadcast_to(pale, (c.n_frames, 3, 4)), 1.35, 0.022,
                     labels=["x GT", "y GT", "z GT"])


def _log_series(rec, rr, c):
    """Per-frame errors, shape-stage history, spectra and the report."""
    for name, v in c.errors_per_frame.items():
        rl.send_scalars(rec, rr, f"/errors/{name}", v, c.frames, name=name)
    # history: on its own timeline (raw, exact) and as static bar charts, one per
    # quantity, which show on any timeline (log10 where the values span decades)
    for name, v in c.admm.items():
        it = np.arange(v.size)
        rl.send_scalars(rec, rr, f"/admm/{name}", v, it, "admm_iteration", name)
        if name in HISTORY_KEYS:
            rl.send_bars(rec, rr, f"/admm_history/{name}",
                         rl.log10(v) if name in HISTORY_LOG else v, abscissa=it,
                         color=ESTIMATE_COLOR if name == "cost" else (90, 90, 200, 255))
    for name, v in c.singular_values.items():
        rec.log(f"/singular_values/{name}", rr.BarChart(v), static=True)
    if "theta" in c.singular_values:
        rl.send_bars(rec, rr, "/singular_values/log10_theta",
                     rl.log10(c.singular_values["theta"]))
    rec.log("/run/report", rr.TextDocument(c.report, media_type=rr.MediaType.MARKDOWN),
            static=True)


def log_content(rec, content):
    """Send a :class:`~nrsfm.views.content.RecordingContent` to the recording stream ``rec``."""
    import rerun as rr

    r_pt = POINT_RADIUS * content.camera_distance
    r_ln = LINE_RADIUS * r_pt
    _log_shapes(rec, rr, content, r_pt, r_ln)
    _log_cameras_and_image(rec, rr, content, r_ln)
    _log_rotations(rec, rr, content)
    _log_series(rec, rr, content)


def build_recording(result, sequence=None, *, application_id="nrsfm", recording_id=None):
    """A ``rerun.RecordingStream`` holding the whole run (buffered until a sink is set).

    Attach a sink afterwards: ``rec.save("run.rrd")``, ``rec.notebook_show()``,
    ``rec.spawn()``; the buffered data is forwarded to it. The default blueprint is sent.

    Parameters
    ----------
    result : nrsfm.Reconstruction
    sequence : nrsfm.sequence.Sequence, optional
        Ground truth to overlay (shapes, rotations, skeleton).
    application_id, recording_id : str
        Rerun identifiers; a random recording id by default.
    """
    content = recording_content(result, sequence)
    rec = rl.new_stream(application_id, recording_id)
    rl.send_blueprint(rec, make_blueprint(content))
    log_content(rec, content)
    return rec


def save_recording(result, path, sequence=None, *, application_id="nrsfm",
                   recording_id=None):
    """Write the recording of ``result`` to an ``.rrd`` file; returns its Path.

    Parent folders are created. The stream is closed and its threads released, so
    repeated calls do not accumulate threads.

    Parameters
    ----------
    result : nrsfm.Reconstruction
    path : str or Path
    sequence : nrsfm.sequence.Sequence, optional
        Ground truth to overlay.
    application_id, recording_id : str
        Rerun identifiers; a random recording id by default.
    """
    content = recording_content(result, sequence)
    with rl.rrd_stream(path, make_blueprint(content), application_id, recording_id) as rec:
        log_content(rec, content)
    return Path(path)

