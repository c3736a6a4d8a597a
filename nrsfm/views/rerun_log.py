"""Rerun logging helpers of both recordings (:mod:`.recording`, :mod:`.video`): columns over
the ``frame`` timeline, cameras, bar charts, and an ``.rrd`` written with its blueprint
without leaking rerun's threads. rerun is imported lazily: callers pass the module as ``rr``.
"""

from __future__ import annotations

import functools
import uuid
from contextlib import contextmanager
from pathlib import Path

import numpy as np


def _index(rr, frames, timeline="frame"):
    return [rr.TimeColumn(timeline, sequence=frames)]


def send_points(rec, rr, path, pts, frames, color=None, radius=None):
    """(F, P, 3) points over ``frames``; colour and radius logged once (static) if given."""
    F, P = pts.shape[:2]
    columns = rr.Points3D.columns(positions=pts.reshape(-1, 3)).partition([P] * F)
    rec.send_columns(path, indexes=_index(rr, frames), columns=columns)
    if color is not None:
        rec.log(path, rr.Points3D.from_fields(colors=[color], radii=[radius]), static=True)


def send_masked_points(rec, rr, path, pts, mask, frames, colors, radius):
    """The points of (F, P, 3) ``pts`` where the (F, P) ``mask`` is True, coloured by
    ``colors`` ((mask.sum(), 4), in frame order); radius logged once."""
    columns = rr.Points3D.columns(positions=pts[mask], colors=colors).partition(mask.sum(axis=1))
    rec.send_columns(path, indexes=_index(rr, frames), columns=columns)
    rec.log(path, rr.Points3D.from_fields(radii=[radius]), static=True)


def send_points_2d(rec, rr, path, pts, frames):
    """(F, P, 2) image points over ``frames``."""
    F, P = pts.shape[:2]
    columns = rr.Points2D.columns(positions=pts.reshape(-1, 2)).partition([P] * F)
    rec.send_columns(path, indexes=_index(rr, frames), columns=columns)


def send_skeleton(rec, rr, path, pts, edges, frames, color, radius):
    """(F, P, 3) points joined by the (E, 2) ``edges`` as line segments, per frame."""
    strips = list(pts[:, edges].reshape(-1, 2, 3))
    columns = rr.LineStrips3D.columns(strips=strips).partition([len(edges)] * pts.shape[0])
    rec.send_columns(path, indexes=_index(rr, frames), columns=columns)
    rec.log(path, rr.LineStrips3D.from_fields(colors=[color], radii=[radius]), static=True)


def send_scalars(rec, rr, path, values, index, timeline="frame", name=None, color=None):
    """One scalar per ``index`` on ``timeline``; series name / colour logged once if given."""
    columns = rr.Scalars.columns(scalars=np.asarray(values, float))
    rec.send_columns(path, indexes=_index(rr, index, timeline), columns=columns)
    if name or color is not None:
        rec.log(path, rr.SeriesLines(names=name, colors=color), static=True)


def send_camera(
    rec, rr, path, R, frames, distance, axis_length, color, frustum=1.0, centres=None, pinhole=None
):
    """Camera f as a transform camera -> world (rotation R_f', centre -distance r3_f or the
    given (F, 3) ``centres``), drawn as RGB axes (x, y, viewing direction z) and a frustum in
    ``color`` (of ``pinhole`` = (camera matrix, (width, height)) if given, else a generic
    one); returns the (F, 3) camera centres."""
    centres = -distance * R[:, 2, :] if centres is None else np.asarray(centres, float)
    columns = rr.Transform3D.columns(mat3x3=R.transpose(0, 2, 1), translation=centres)
    rec.send_columns(path, indexes=_index(rr, frames), columns=columns)
    rec.log(path, rr.TransformAxes3D(axis_length), static=True)
    kw = dict(fov_y=0.7, aspect_ratio=1.3) if pinhole is None else {}
    if pinhole is not None:
        kw.update(image_from_camera=pinhole[0], resolution=pinhole[1])
    kw.update(camera_xyz=rr.ViewCoordinates.RDF, color=color)
    kw.update(image_plane_distance=frustum * axis_length, line_width=0.006 * distance)
    rec.log(path, rr.Pinhole(**kw), static=True)
    return centres


def send_axes(rec, rr, path, R, frames, colors, length, radius, labels=None):
    """Rows of R_f (the camera axes in the world) as three arrows from the origin."""
    vectors, colors = (length * R).reshape(-1, 3), colors.reshape(-1, 4)
    columns = rr.Arrows3D.columns(vectors=vectors, colors=colors).partition([3] * R.shape[0])
    rec.send_columns(path, indexes=_index(rr, frames), columns=columns)
    rec.log(path, rr.Arrows3D.from_fields(radii=[radius], labels=labels), static=True)


def send_bars(rec, rr, path, values, abscissa=None, color=None):
    """A static bar chart (abscissa 1..n by default)."""
    v = np.asarray(values, float)
    x = np.arange(1, v.size + 1) if abscissa is None else np.asarray(abscissa, float)
    rec.log(path, rr.BarChart(v, abscissa=x, color=color), static=True)


def log10(v):
    """log10 of the positive entries, NaN elsewhere."""
    v = np.asarray(v, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log10(np.where(v > 0, v, np.nan))


def new_stream(application_id, recording_id=None):
    """A buffered ``rerun.RecordingStream`` (a random recording id by default)."""
    import rerun as rr

    return rr.RecordingStream(application_id, recording_id=recording_id or str(uuid.uuid4()))


def release_streams():
    """Free the threads (2 each) of recording streams no longer referenced: rerun-sdk keeps
    them until a sweep, which ``rr.init`` runs and a plain ``RecordingStream`` never does."""
    from rerun import bindings

    sweep = getattr(bindings, "flush_and_cleanup_orphaned_recordings", None)
    if sweep is not None:
        sweep()


@functools.cache
def _blueprint_stream(application_id):
    """The one blueprint stream of this process for ``application_id``: rerun-sdk 0.41 makes
    every blueprint a new stream whose 2 threads are never released; one per application id,
    given a fresh memory sink per blueprint, keeps the count bounded."""
    from rerun import bindings
    from rerun.recording_stream import RecordingStream

    flags = dict(make_default=False, make_thread_default=False, default_enabled=True)
    return RecordingStream._from_native(
        bindings.new_blueprint(application_id=application_id, **flags)
    )


def _blueprint_storage(application_id, blueprint):
    """The blueprint as rerun's in-memory storage, or None where the internals of the
    pinned rerun-sdk that this relies on moved."""
    try:
        stream = _blueprint_stream(application_id)
        memory = stream.memory_recording()  # a new sink: this blueprint only
        stream.set_time("blueprint", sequence=0)
        blueprint.to_blueprint()._log_to_stream(stream)
        stream.flush()
        return memory.storage
    except (AttributeError, ImportError, TypeError):
        return None


def send_blueprint(rec, blueprint):
    """Send ``blueprint`` to the stream ``rec`` as its default layout."""
    from rerun import bindings

    storage = _blueprint_storage(rec.get_application_id(), blueprint)
    if storage is None:
        rec.send_blueprint(blueprint)
    else:
        bindings.send_blueprint(storage, True, True, recording=rec.to_native())


@contextmanager
def rrd_stream(path, blueprint, application_id, recording_id=None):
    """Yield a recording stream writing to the ``.rrd`` file ``path`` (parent folders
    created) with ``blueprint`` as its default layout; flushed, closed and its threads
    released on exit."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rec = new_stream(application_id, recording_id)
    try:
        storage = _blueprint_storage(application_id, blueprint)
        if storage is None:
            rec.save(path, default_blueprint=blueprint)
        else:
            from rerun import bindings

            kw = dict(default_blueprint=storage, recording=rec.to_native(), write_footer=True)
            bindings.save(path=str(path), **kw)
        yield rec
        rec.flush()
    finally:
        rec.disconnect()
        del rec
        release_streams()
