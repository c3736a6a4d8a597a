"""Rerun recording of a video run: the frames with their tracks beside the 3D result.

Entity paths (timeline ``frame``):

* ``/video/frame``: the frame, JPEG-encoded (downscaled to at most ``max_width`` pixels).
* ``/video/tracks``: Points2D, tracks observed in this frame (a decimated subset for dense
  input), green where the reconstruction used the track, yellow where it did not.
* ``/video/lost``: Points2D, red dots (larger) at the last position of every (shown) track lost
  at or before this frame.
* ``/world/estimate``: Points3D, the reconstructed shape (decimated), coloured from the
  video; similarity-aligned per frame onto the ground truth when one is given (as ``e3d``).
* ``/world/ground_truth``: Points3D, the true shape (same points), blue.
* ``/errors/e3d``: per-frame error when a ground truth is given; ``/tracks/alive``: number
  of tracks still observed.
* ``/run/report``: TextDocument (markdown) with counts, errors and timings [static].

Sizes: positions are float32 and the colours are logged once (static), so a 30,000-point,
100-frame run with the default ``max_points_3d = 5000`` costs about 6 MB per point cloud.
"""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import numpy as np

__all__ = ["ENTITY_PATHS", "decimate", "make_video_blueprint", "save_video_recording"]

ENTITY_PATHS = ("/video", "/world", "/errors", "/tracks", "/run")
USED_COLOR = (60, 230, 60, 255)
UNUSED_COLOR = (250, 220, 40, 255)
LOST_COLOR = (255, 40, 40, 255)
GT_COLOR = (70, 130, 255, 160)


def decimate(n, max_n):
    """Indices of at most ``max_n`` of ``n`` items, evenly spread (deterministic)."""
    if max_n is None or n <= max_n:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, int(max_n)).astype(int))


def make_video_blueprint(has_gt=False):
    """Frames with tracks left, 3D result right; per-frame series and report below."""
    import rerun.blueprint as rrb

    series = [rrb.TimeSeriesView(origin="/tracks", name="tracks observed")]
    if has_gt:
        series.insert(0, rrb.TimeSeriesView(origin="/errors", name="per-frame e3d"))
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(rrb.Spatial2DView(origin="/video", name="video and tracks"),
                           rrb.Spatial3DView(origin="/world", name="3D reconstruction")),
            rrb.Horizontal(rrb.Tabs(*series),
                           rrb.TextDocumentView(origin="/run/report", name="report")),
            row_shares=[3, 1]),
        collapse_panels=True)


def _points_columns(rec, rr, path, pts, frames, kind):
    F, P = pts.shape[:2]
    arch = rr.Points3D if kind == 3 else rr.Points2D
    rec.send_columns(path, indexes=[rr.TimeColumn("frame", sequence=frames)],
                     columns=arch.columns(positions=pts.reshape(-1, kind)).partition([P] * F))


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
    import cv2
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
    path.parent.mkdir(parents=True, exist_ok=True)
    H, W = frames.shape[1:3]
    zoom = min(1.0, max_width / W)
    fr = np.arange(F)

    rec = rr.RecordingStream(application_id, recording_id=str(uuid.uuid4()))
    rec.save(path, default_blueprint=make_video_blueprint(shapes_gt is not None
                                                          and result is not None))
    try:
        # frames
        for f in range(F):
            img = frames[f]
            if zoom < 1:
                img = cv2.resize(img, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_AREA)
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
            if not ok:
                raise ValueError(f"cannot JPEG-encode frame {f}")
            rec.set_time("frame", sequence=f)
            rec.log("/video/frame", rr.EncodedImage(contents=buf.tobytes(),
                                                    media_type="image/jpeg"))
        # tracks over the frames (decimated), in the displayed image's pixels
        sel = decimate(P, max_points_2d)
        T = tracks.tracks[:, :, sel].transpose(0, 2, 1) * zoom       # (F, n, 2)
        alive = np.isfinite(T).all(axis=2)
        lost_at = tracks.lost_at[sel]
        last = T[np.clip(lost_at - 1, 0, F - 1), np.arange(len(sel))]   # (n, 2)
        colors = np.where(used[sel][:, None], np.array(USED_COLOR), np.array(UNUSED_COLOR))
        r2 = max(1.0, 1.5 * zoom)
        for f in range(F):
            rec.set_time("frame", sequence=f)
            a = alive[f]
            rec.log("/video/tracks", rr.Points2D(T[f, a], colors=colors[a].astype(np.uint8),
                                                 radii=r2, draw_order=10))
            gone = lost_at <= f
            rec.log("/video/lost", rr.Points2D(last[gone], colors=[LOST_COLOR],
                                               radii=2 * r2, draw_order=11))
        _scalars(rec, rr, "/tracks/alive", np.isfinite(tracks.tracks[:, 0]).sum(axis=1), fr)

        n3 = 0
        errs = {}
        if result is not None:
            X = np.asarray(result.shapes)
            sel3 = decimate(X.shape[2], max_points_3d)
            n3 = len(sel3)
            if shapes_gt is not None:
                G = np.asarray(shapes_gt)
                per, X_disp, G_disp = _aligned(X, G, sel3)
                errs["e3d"] = float(per.mean())
                _scalars(rec, rr, "/errors/e3d", per, fr)
                _points_columns(rec, rr, "/world/ground_truth", G_disp, fr, 3)
                rec.log("/world/ground_truth",
                        rr.Points3D.from_fields(colors=[GT_COLOR], radii=[-1.5]), static=True)
            else:
                X_disp = X[:, :, sel3] - X.mean(axis=2, keepdims=True)
                X_disp = X_disp.transpose(0, 2, 1).astype(np.float32)
            _points_columns(rec, rr, "/world/estimate", X_disp, fr, 3)
            col = tracks.colors[np.flatnonzero(used)][sel3]
            rec.log("/world/estimate", rr.Points3D.from_fields(colors=col, radii=[-2.0]),
                    static=True)
        lines = ["# nrsfm video run", "",
                 f"{tracks.summary()}.", "",
                 f"Frames {F} ({W}x{H}), drawn at {zoom:.2f} scale; {len(sel)} tracks drawn "
                 f"over the frames, {n3} points in 3D."]
        if result is not None:
            lines += ["", f"Reconstruction: method {result.method}, K = {result.K}, "
                          f"{result.n_points} tracks used of {P}."]
            lines += [f"- {k}: {v:.4g}" for k, v in errs.items()]
            lines += [f"- time {k}: {v:.2f} s" for k, v in result.timings.items()]
        if report:
            lines += ["", report]
        rec.log("/run/report", rr.TextDocument("\n".join(lines),
                                               media_type=rr.MediaType.MARKDOWN), static=True)
        rec.flush()
    finally:
        rec.disconnect()
    return dict(path=path, bytes=path.stat().st_size, seconds=time.perf_counter() - t0,
                points_3d=n3, points_2d=len(sel))


def _aligned(X, G, sel):
    """Per frame (memory O(P)): e3d of X against G (the metric's similarity Procrustes,
    reflection allowed, as :func:`nrsfm.metrics.e3d`), and the display subset ``sel`` of the
    aligned estimate and of the centred ground truth, (F, n, 3) float32 each."""
    F = X.shape[0]
    per = np.empty(F)
    Xd = np.empty((F, len(sel), 3), np.float32)
    Gd = np.empty((F, len(sel), 3), np.float32)
    for f in range(F):
        A = X[f] - X[f].mean(axis=1, keepdims=True)
        B = G[f] - G[f].mean(axis=1, keepdims=True)
        U, sig, Vt = np.linalg.svd(B @ A.T)
        nA = float(np.sum(A * A))
        c = sig.sum() / nA if nA > 0 else 0.0
        Q = c * (U @ Vt)
        per[f] = np.linalg.norm(B - Q @ A) / np.linalg.norm(B)
        Xd[f] = (Q @ A[:, sel]).T
        Gd[f] = B[:, sel].T
    return per, Xd, Gd


def _scalars(rec, rr, path, values, frames):
    rec.send_columns(path, indexes=[rr.TimeColumn("frame", sequence=frames)],
                     columns=rr.Scalars.columns(scalars=np.asarray(values, float)))
