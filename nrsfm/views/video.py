"""Rerun recording of a video run: the frames with their tracks beside the 3D result.

Entity paths (timeline ``frame``):

* ``/video/frame``: the frame, JPEG-encoded (downscaled to at most ``max_width`` pixels).
* ``/video/tracks``: Points2D, tracks observed in this frame (a decimated subset for dense
  input; a track that starts late appears from its first frame), green where the
  reconstruction used the track, orange where it used it but the data leave its 3D
  undetermined (``Reconstruction.undetermined``: seen in too few frames), yellow where it
  did not use it.
* ``/video/lost``: Points2D, red dots (larger) at the last position of every (shown) track lost
  at or before this frame.
* ``/world/estimate``: Points3D, the reconstructed shape of the tracks the data determine
  (decimated; the undetermined ones are extrapolations), coloured from the video;
  similarity-aligned per frame onto the ground truth when one is given (as ``e3d``).
* ``/world/ground_truth``: Points3D, the true shape (same points), blue.
* ``/errors/e3d``: per-frame error when a ground truth is given; ``/tracks/alive``: number
  of tracks still observed.
* ``/run/report``: TextDocument (markdown) with counts, errors and timings [static].

Sizes: positions are float32 and the colours are logged once (static), so a 30,000-point,
100-frame run with the default ``max_points_3d = 5000`` costs about 6 MB per point cloud.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from . import rerun_log as rl
from .blueprint import make_video_blueprint

__all__ = ["VIDEO_ENTITY_PATHS", "decimate", "aligned_subset", "save_video_recording"]

VIDEO_ENTITY_PATHS = ("/video", "/world", "/errors", "/tracks", "/run")
USED_COLOR = (60, 230, 60, 255)
UNUSED_COLOR = (250, 220, 40, 255)
UNDETERMINED_COLOR = (255, 140, 0, 255)
LOST_COLOR = (255, 40, 40, 255)
GT_COLOR = (70, 130, 255, 160)


def decimate(n, max_n):
    """Indices of at most ``max_n`` of ``n`` items, evenly spread (deterministic)."""
    if max_n is None or n <= max_n:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, int(max_n)).astype(int))


def aligned_subset(X, G, sel):
    """Per-frame e3d of ``X`` against ``G`` and the display subset ``sel`` of both.

    The alignment is the metric's (:func:`nrsfm.geometry.align_similarity`, reflection
    allowed), applied one frame at a time so that memory stays O(P).

    Parameters
    ----------
    X, G : (F, 3, P) ndarray
        Estimate and ground truth.
    sel : (n,) int ndarray
        Points to display.

    Returns
    -------
    per_frame : (F,) ndarray
        ``||G_f - aligned X_f|| / ||G_f||`` (both centred).
    X_disp, G_disp : (F, n, 3) float32 ndarray
        The aligned estimate and the centred ground truth at ``sel``.
    """
    from ..geometry import align_similarity as similarity_align

    F = X.shape[0]
    per = np.empty(F)
    Xd = np.empty((F, len(sel), 3), np.float32)
    Gd = np.empty((F, len(sel), 3), np.float32)
    for f in range(F):
        A = similarity_align(X[f:f + 1], G[f:f + 1])[0]
        B = G[f] - G[f].mean(axis=1, keepdims=True)
        per[f] = np.linalg.norm(B - A) / np.linalg.norm(B)
        Xd[f] = A[:, sel].T
        Gd[f] = B[:, sel].T
    return per, Xd, Gd


def _log_frames(rec, rr, frames, zoom, jpeg_quality):
    import cv2

    for f in range(frames.shape[0]):
        img = frames[f]
        if zoom < 1:
            img = cv2.resize(img, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        if not ok:
            raise ValueError(f"cannot JPEG-encode frame {f}")
        rec.set_time("frame", sequence=f)
        rec.log("/video/frame", rr.EncodedImage(contents=buf.tobytes(),
                                                media_type="image/jpeg"))


def _track_colors(used, undetermined):
    """(P, 4) uint8 colour per track: used, used but undetermined, or not used."""
    colors = np.where(used[:, None], np.array(USED_COLOR), np.array(UNUSED_COLOR))
    colors[undetermined] = UNDETERMINED_COLOR
    return colors.astype(np.uint8)


def _undetermined(result, used):
    """(P,) bool over all tracks: used tracks the reconstruction reports undetermined."""
    out = np.zeros(len(used), bool)
    if result is not None:
        out[np.flatnonzero(used)] = result.undetermined
    return out


def _log_tracks(rec, rr, tracks, colors, zoom, max_points):
    """Tracks over the frames (decimated), in the displayed image's pixels, coloured by
    ``colors`` (P, 4); returns how many were drawn."""
    F, P = tracks.n_frames, tracks.n_points
    sel = decimate(P, max_points)
    T = tracks.tracks[:, :, sel].transpose(0, 2, 1) * zoom       # (F, n, 2)
    alive = np.isfinite(T).all(axis=2)
    lost_at = tracks.lost_at[sel]
    last = T[np.clip(lost_at - 1, 0, F - 1), np.arange(len(sel))]   # (n, 2)
    colors = colors[sel]
    r2 = max(1.0, 1.5 * zoom)
    for f in range(F):
        rec.set_time("frame", sequence=f)
        a = alive[f]
        rec.log("/video/tracks", rr.Points2D(T[f, a], colors=colors[a],
                                             radii=r2, draw_order=10))
        gone = lost_at <= f
        rec.log("/video/lost", rr.Points2D(last[gone], colors=[LOST_COLOR],
                                           radii=2 * r2, draw_order=11))
    rl.send_scalars(rec, rr, "/tracks/alive", np.isfinite(tracks.tracks[:, 0]).sum(axis=1),
                    np.arange(F))
    return len(sel)


def _log_world(rec, rr, result, tracks, used, shapes_gt, max_points):
    """The 3D estimate of the tracks the data determine (and their ground truth); returns
    (points drawn, errors)."""
    det = ~result.undetermined
    X = np.asarray(result.shapes)[:, :, det]
    if shapes_gt is not None:
        shapes_gt = np.asarray(shapes_gt)[:, :, det]
    fr = np.arange(X.shape[0])
    sel3 = decimate(X.shape[2], max_points)
    errs = {}
    if shapes_gt is not None:
        per, X_disp, G_disp = aligned_subset(X, np.asarray(shapes_gt), sel3)
        errs["e3d"] = float(per.mean())
        rl.send_scalars(rec, rr, "/errors/e3d", per, fr)
        rl.send_points(rec, rr, "/world/ground_truth", G_disp, fr)
        rec.log("/world/ground_truth",
                rr.Points3D.from_fields(colors=[GT_COLOR], radii=[-1.5]), static=True)
    else:
        X_disp = X[:, :, sel3] - X.mean(axis=2, keepdims=True)
        X_disp = X_disp.transpose(0, 2, 1).astype(np.float32)
    rl.send_points(rec, rr, "/world/estimate", X_disp, fr)
    col = tracks.colors[np.flatnonzero(used)[det]][sel3]
    rec.log("/world/estimate", rr.Points3D.from_fields(colors=col, radii=[-2.0]),
            static=True)
    return len(sel3), errs


def _video_report(tracks, result, frames, zoom, n2, n3, errs, report):
    F, H, W = frames.shape[:3]
    lines = ["# nrsfm video run", "",
             f"{tracks.summary()}.", "",
             f"Frames {F} ({W}x{H}), drawn at {zoom:.2f} scale; {n2} tracks drawn "
             f"over the frames, {n3} points in 3D."]
    if result is not None:
        lines += ["", f"Reconstruction: method {result.method}, K = {result.K}, "
                      f"{result.n_points} tracks used of {tracks.n_points}, "
                      f"{int(result.undetermined.sum())} of them undetermined (seen in "
                      f"too few frames: their 3D is an extrapolation, drawn orange in 2D "
                      f"and left out of the 3D view)."]
        lines += [f"- {k}: {v:.4g}" for k, v in errs.items()]
        lines += [f"- time {k}: {v:.2f} s" for k, v in result.timings.items()]
    if report:
        lines += ["", report]
    return "\n".join(lines)


def save_video_recording(path, frames, tracks, result=None, used=None, shapes_gt=None, *,
                         max_points_2d=3000, max_points_3d=5000, max_width=640,
                         jpeg_quality=80, report="", application_id="nrsfm-video"):
    """Write the recording of a video run to an ``.rrd`` file.

    Parameters
    ----------
    path : str or Path
    frames : (F, H, W, 3) uint8 ndarray
        BGR frames.
    tracks : data_tools.video.Tracks
    result : nrsfm.Reconstruction, optional
        Reconstruction of the tracks ``used``.
    used : (P,) bool ndarray, optional
        Which tracks the reconstruction used (default: all, if ``result`` is given).
    shapes_gt : (F, 3, P_used) ndarray, optional
        Ground truth of the used tracks (any frame; compared per frame after similarity
        alignment, as ``e3d``).
    max_points_2d, max_points_3d : int
        Decimation: at most this many tracks drawn over the frames / points in 3D.
    max_width : int
        Frames wider than this are downscaled before JPEG encoding.
    jpeg_quality : int
    report : str
        Extra markdown appended to the report.

    Returns
    -------
    dict
        ``path``, ``bytes`` (file size), ``seconds`` (logging and writing time),
        ``points_3d`` and ``points_2d`` (how many were drawn).
    """
    import rerun as rr

    t0 = time.perf_counter()
    frames = np.asarray(frames)
    F, P = tracks.n_frames, tracks.n_points
    if frames.shape[0] != F:
        raise ValueError(f"{frames.shape[0]} frames but the tracks have {F}")
    used = (np.ones(P, bool) if used is None else np.asarray(used, bool))
    if used.shape != (P,):
        raise ValueError(f"used must have shape ({P},); got {used.shape}")
    path = Path(path)
    zoom = min(1.0, max_width / frames.shape[2])
    blueprint = make_video_blueprint(shapes_gt is not None and result is not None)
    with rl.rrd_stream(path, blueprint, application_id) as rec:
        _log_frames(rec, rr, frames, zoom, jpeg_quality)
        colors = _track_colors(used, _undetermined(result, used))
        n2 = _log_tracks(rec, rr, tracks, colors, zoom, max_points_2d)
        n3, errs = 0, {}
        if result is not None:
            n3, errs = _log_world(rec, rr, result, tracks, used, shapes_gt, max_points_3d)
        rec.log("/run/report", rr.TextDocument(
            _video_report(tracks, result, frames, zoom, n2, n3, errs, report),
            media_type=rr.MediaType.MARKDOWN), static=True)
    return dict(path=path, bytes=path.stat().st_size, seconds=time.perf_counter() - t0,
                points_3d=n3, points_2d=n2)
