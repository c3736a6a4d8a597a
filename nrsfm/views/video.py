"""Rerun recording of a video run: the frames with their tracks beside the 3D result.

Entity paths (timeline ``frame``):

* ``/video/frame``: the frame, JPEG (downscaled to at most :data:`MAX_WIDTH` pixels).
* ``/video/tracks``: Points2D, the tracks observed in the frame (decimated), green where the
  reconstruction used the track, orange where it used it but the data leave its 3D
  undetermined (``Reconstruction.undetermined``), yellow where it did not use it.
* ``/video/lost``: Points2D, red, the last position of every shown track lost by the frame.
* ``/world/estimate``: Points3D, the shape of the tracks the data determine (decimated),
  coloured from the video; similarity-aligned per frame onto the ground truth when given.
* ``/world/ground_truth``: Points3D, the true shape (same points), blue.
* ``/errors/e3d``: per-frame error with a ground truth; ``/tracks/alive``: tracks observed.
* ``/run/report``: TextDocument (markdown) with counts, errors and timings [static].

A perspective run (``result.perspective``: ``nrsfm video --focal`` / ``--intrinsics``) is
drawn in the refinement's world frame (as :mod:`.recording` draws it), so that the cameras
show:

* ``/world/estimate``: the shapes as returned (units of each frame's centroid depth), not
  aligned; ``/world/ground_truth``: the truth similarity-aligned per frame onto them (e3d
  still aligns the estimate onto the truth).
* ``/world/cameras/estimate``: Transform3D of each frame's camera at its centre
  ``-R_f' t_f``, with axes and the intrinsics' frustum of the full-resolution frame;
  ``/world/trajectory/estimate``: LineStrips3D of the centres [static].
* ``/video/perspective``: Points2D, magenta, the perspective projection of the drawn tracks
  that are used and determined, in every frame (over the tracks).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from . import rerun_log as rl
from .blueprint import make_video_blueprint

VIDEO_ENTITY_PATHS = ("/video", "/world", "/errors", "/tracks", "/run")
USED_COLOR = (60, 230, 60, 255)
UNUSED_COLOR = (250, 220, 40, 255)
UNDETERMINED_COLOR = (255, 140, 0, 255)
LOST_COLOR = (255, 40, 40, 255)
#: a perspective run's cameras and their projection of the tracks' 3D
PERSPECTIVE_COLOR = (255, 40, 230, 255)
GT_COLOR = (70, 130, 255, 160)
#: frames wider than this (pixels) are downscaled before JPEG encoding, at this quality
MAX_WIDTH, JPEG_QUALITY = 640, 80


def decimate(n, max_n):
    """Indices of at most ``max_n`` of ``n`` items, evenly spread."""
    if max_n is None or n <= max_n:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, int(max_n)).astype(int))


def aligned_subset(X, G, sel, onto_estimate=False):
    """Per-frame e3d of ``X`` against ``G`` ((F, 3, P) each) and, at the points ``sel``, the
    aligned estimate and the centred ground truth ((F, n, 3) float32 each); aligned one frame
    at a time as :func:`nrsfm.geometry.align_similarity`, so that memory stays O(P).

    ``onto_estimate``: instead, the estimate as given and the ground truth similarity-aligned
    per frame onto it (the e3d are the same: the estimate aligned onto the truth)."""
    from ..geometry import align_similarity

    F = X.shape[0]
    per = np.empty(F)
    Xd, Gd = np.empty((F, len(sel), 3), np.float32), np.empty((F, len(sel), 3), np.float32)
    for f in range(F):
        A = align_similarity(X[f : f + 1], G[f : f + 1])[0]
        B = G[f] - G[f].mean(axis=1, keepdims=True)
        per[f] = np.linalg.norm(B - A) / np.linalg.norm(B)
        if onto_estimate:
            A = X[f]
            B = align_similarity(G[f : f + 1], A[None])[0] + A.mean(axis=1, keepdims=True)
        Xd[f], Gd[f] = A[:, sel].T, B[:, sel].T
    return per, Xd, Gd


def _log_frames(rec, rr, frames, zoom):
    import cv2

    for f, img in enumerate(frames):
        if zoom < 1:
            img = cv2.resize(img, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_AREA)
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if not ok:
            raise ValueError(f"cannot JPEG-encode frame {f}")
        rec.set_time("frame", sequence=f)
        rec.log("/video/frame", rr.EncodedImage(contents=buf.tobytes(), media_type="image/jpeg"))


def _track_colors(used, undetermined):
    """(P, 4) uint8 colour per track: used, used but undetermined, or not used."""
    colors = np.where(used[:, None], np.array(USED_COLOR), np.array(UNUSED_COLOR))
    colors[undetermined] = UNDETERMINED_COLOR
    return colors.astype(np.uint8)


def _log_tracks(rec, rr, tracks, colors, zoom, max_points):
    """Tracks over the frames (decimated), in the displayed image's pixels; returns how many
    were drawn."""
    F, sel = tracks.n_frames, decimate(tracks.n_points, max_points)
    T = tracks.tracks[:, :, sel].transpose(0, 2, 1) * zoom  # (F, n, 2)
    alive = np.isfinite(T).all(axis=2)
    lost_at = tracks.lost_at[sel]
    last = T[np.clip(lost_at - 1, 0, F - 1), np.arange(len(sel))]  # (n, 2)
    colors, r2 = colors[sel], max(1.0, 1.5 * zoom)
    for f in range(F):
        rec.set_time("frame", sequence=f)
        a, gone = alive[f], lost_at <= f
        rec.log("/video/tracks", rr.Points2D(T[f, a], colors=colors[a], radii=r2, draw_order=10))
        lost = rr.Points2D(last[gone], colors=[LOST_COLOR], radii=2 * r2, draw_order=11)
        rec.log("/video/lost", lost)
    alive = np.isfinite(tracks.tracks[:, 0]).sum(axis=1)
    rl.send_scalars(rec, rr, "/tracks/alive", alive, np.arange(F))
    return len(sel)


def _log_world(rec, rr, result, tracks, used, shapes_gt, max_points):
    """The 3D estimate of the tracks the data determine (and their ground truth); returns
    (points drawn, errors). A perspective result's shapes are drawn as returned."""
    det, perspective = ~result.undetermined, getattr(result, "perspective", None) is not None
    X = np.asarray(result.shapes)[:, :, det]
    fr, sel = np.arange(X.shape[0]), decimate(int(det.sum()), max_points)
    errs = {}
    if shapes_gt is not None:
        G = np.asarray(shapes_gt)[:, :, det]
        per, X_disp, G_disp = aligned_subset(X, G, sel, onto_estimate=perspective)
        errs["e3d"] = float(per.mean())
        rl.send_scalars(rec, rr, "/errors/e3d", per, fr)
        rl.send_points(rec, rr, "/world/ground_truth", G_disp, fr)
        style = rr.Points3D.from_fields(colors=[GT_COLOR], radii=[-1.5])
        rec.log("/world/ground_truth", style, static=True)
    else:
        X_disp = X[:, :, sel] if perspective else X[:, :, sel] - X.mean(axis=2, keepdims=True)
        X_disp = X_disp.transpose(0, 2, 1).astype(np.float32)
    rl.send_points(rec, rr, "/world/estimate", X_disp, fr)
    col = tracks.colors[np.flatnonzero(used)[det]][sel]
    rec.log("/world/estimate", rr.Points3D.from_fields(colors=col, radii=[-2.0]), static=True)
    return len(sel), errs


def _log_perspective(rec, rr, result, tracks, used, frames, zoom, max_points):
    """A perspective result's cameras (:func:`.recording.log_perspective_cameras`) and, over
    the frames, the perspective projection of the drawn tracks that are used and determined."""
    from .content import _pixels, perspective_cameras
    from .recording import log_perspective_cameras

    p, F = result.perspective, frames.shape[0]
    A = np.asarray(p.intrinsics, float)
    centres, distance, axis_length = perspective_cameras(result)
    pinhole = (A, (float(frames.shape[2]), float(frames.shape[1])))
    R = np.asarray(p.rotations, float)
    # the trajectory's radius in screen points (negative), as the points': the camera centres
    # pass near the viewer's eye, where a radius in scene units swells
    args = (R, centres, np.arange(F), (distance, axis_length), pinhole, PERSPECTIVE_COLOR, -1.0)
    log_perspective_cameras(rec, rr, *args)
    # the result's column of each used track; the drawn ones (as _log_tracks) determined
    column = np.cumsum(used) - 1
    sel = decimate(tracks.n_points, max_points)
    determined = np.zeros(tracks.n_points, bool)
    determined[np.flatnonzero(used)] = ~np.asarray(result.undetermined, bool)
    cols = column[sel[determined[sel]]]
    Y = p.camera_points[:, :, cols]
    pix = (_pixels(Y[:, :2] / Y[:, 2:3], A) * zoom).astype(np.float32)
    rl.send_points_2d(rec, rr, "/video/perspective", pix, np.arange(F))
    r2 = 0.6 * max(1.0, 1.5 * zoom)  # smaller than the tracks', above them
    style = rr.Points2D.from_fields(colors=[PERSPECTIVE_COLOR], radii=[r2], draw_order=12)
    rec.log("/video/perspective", style, static=True)


def _video_report(tracks, result, frames, zoom, n2, n3, errs):
    F, H, W = frames.shape[:3]
    lines = ["# nrsfm video run", "", f"{tracks.summary()}.", ""]
    drawn = f"{n2} tracks drawn over the frames, {n3} points in 3D"
    lines.append(f"Frames {F} ({W}x{H}), drawn at {zoom:.2f} scale; {drawn}.")
    if result is not None:
        r, n_und = result, int(result.undetermined.sum())
        used = f"{r.n_points} tracks used of {tracks.n_points}, {n_und} of them undetermined"
        why = "seen in too few frames: their 3D is an extrapolation, drawn orange in 2D and left"
        lines += [
            "",
            f"Reconstruction: method {r.method}, K = {r.K}, {used} ({why} out of the 3D view).",
        ]
        lines += [f"- {k}: {v:.4g}" for k, v in errs.items()]
        p = getattr(r, "perspective", None)
        if p is not None:
            rms = f"{p.reprojection_before:.4g} px (orthographic start) -> "
            rms += f"{p.reprojection_after:.4g} px"
            lines.append(f"- perspective refinement: reprojection RMS {rms}; start {p.start}")
        lines += [f"- time {k}: {v:.2f} s" for k, v in r.timings.items()]
    return "\n".join(lines)


def save_video_recording(
    path,
    frames,
    tracks,
    result=None,
    used=None,
    shapes_gt=None,
    *,
    max_points_2d=3000,
    max_points_3d=5000,
):
    """Write the recording of a video run to the ``.rrd`` file ``path``.

    Parameters
    ----------
    frames : (F, H, W, 3) uint8 ndarray
        BGR frames.
    tracks : data_tools.video.Tracks
    result : nrsfm.Reconstruction, optional
        Reconstruction of the tracks ``used`` ((P,) bool; default all). A perspective one
        (``result.perspective``) is drawn with its cameras (module docstring).
    shapes_gt : (F, 3, P_used) ndarray, optional
        Ground truth of the used tracks (compared per frame after similarity alignment).
    max_points_2d, max_points_3d : int or None
        At most this many tracks drawn over the frames / points in 3D (None: all).

    Returns
    -------
    dict
        ``path``, ``bytes``, ``seconds`` (logging and writing), ``points_3d``, ``points_2d``.
    """
    import rerun as rr

    t0 = time.perf_counter()
    frames, P = np.asarray(frames), tracks.n_points
    if frames.shape[0] != tracks.n_frames:
        raise ValueError(f"{frames.shape[0]} frames but the tracks have {tracks.n_frames}")
    used = np.ones(P, bool) if used is None else np.asarray(used, bool)
    if used.shape != (P,):
        raise ValueError(f"used must have shape ({P},); got {used.shape}")
    undetermined = np.zeros(P, bool)
    if result is not None:
        undetermined[np.flatnonzero(used)] = result.undetermined
    path, zoom = Path(path), min(1.0, MAX_WIDTH / frames.shape[2])
    blueprint = make_video_blueprint(shapes_gt is not None and result is not None)
    with rl.rrd_stream(path, blueprint, "nrsfm-video") as rec:
        _log_frames(rec, rr, frames, zoom)
        colors = _track_colors(used, undetermined)
        n2 = _log_tracks(rec, rr, tracks, colors, zoom, max_points_2d)
        n3, errs = 0, {}
        if result is not None:
            n3, errs = _log_world(rec, rr, result, tracks, used, shapes_gt, max_points_3d)
            if getattr(result, "perspective", None) is not None:
                args = (tracks, used, frames, zoom, max_points_2d)
                _log_perspective(rec, rr, result, *args)
        text = _video_report(tracks, result, frames, zoom, n2, n3, errs)
        report = rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN)
        rec.log("/run/report", report, static=True)
    seconds = time.perf_counter() - t0
    info = dict(path=path, bytes=path.stat().st_size, seconds=seconds)
    return dict(info, points_3d=n3, points_2d=n2)
