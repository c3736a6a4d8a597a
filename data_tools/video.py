"""2D tracks from video with OpenCV: sparse (corners + pyramidal Lucas-Kanade) and dense
(optical flow chained over a grid), both with a forward-backward consistency check.

Every track starts in the first frame, or, with ``detect_every``, in a later frame (NaN
before it). A track whose forward-backward error exceeds the threshold, whose tracker
reports failure, or that leaves the image, is *lost*: it is NaN from that frame on (missing
data), never silently dropped. ``Tracks.W`` is the (2F, P)
measurement matrix with those NaNs.

Video input: a video file OpenCV can decode, or a folder of images (sorted by name).
"""

from __future__ import annotations

import numpy as np

from .frames import IMAGE_SUFFIXES, _gray, load_frames, read_frames, texture_mask
from .track_state import Tracks, _advance, _as_frames, _detect_due, _inside, _TrackSet

__all__ = [
    "IMAGE_SUFFIXES",
    "Tracks",
    "load_frames",
    "read_frames",
    "texture_mask",
    "track_dense",
    "track_sparse",
    "tracks_from_frames",
    "tracks_from_video",
]


# --------------------------------------------------------------------------- sparse


def track_sparse(
    frames,
    max_points=2000,
    quality=0.01,
    min_distance=5,
    window=15,
    levels=3,
    fb_threshold=1.0,
    max_residual=25.0,
    neighbour_px=2.0,
    n_neighbours=8,
    mask=None,
    min_points=8,
    keep_raw=False,
    detect_every=0,
):
    """Corners of the first frame (and, with ``detect_every``, of later frames) tracked by
    pyramidal Lucas-Kanade with a forward-backward check.

    Parameters
    ----------
    frames : sequence of (H, W) or (H, W, 3) uint8 images
        At least two, all of one size.
    max_points, quality, min_distance : detector settings (``cv2.goodFeaturesToTrack``).
        Only corners whose structure tensor passes :data:`TEXTURE_THRESHOLD` are kept.
    window, levels : int
        Lucas-Kanade window size and pyramid levels.
    fb_threshold : float
        A step whose forward-backward error (track f -> f+1, then back) exceeds this many
        pixels loses the track from frame f+1 on.
    max_residual : float
        A step whose Lucas-Kanade residual (mean absolute grey-level difference over the
        window) exceeds this loses the track too: an occluded patch can be followed
        consistently forwards and backwards, but it no longer looks the same. On the
        synthetic videos the residual of good steps stays below 7-15 grey levels; a patch
        replaced by another texture gives about 40.
    neighbour_px, n_neighbours : float, int
        Motion consistency: a track farther than ``neighbour_px`` pixels from where the
        affine motion (first frame -> now) of its ``n_neighbours`` nearest live neighbours
        puts it is lost (a slow drift or a jump onto another feature passes the other two
        checks). ``neighbour_px=None`` turns the check off.
    mask : (H, W) bool array, optional
        Where to look for corners in the first frame.
    min_points : int
        Fewer trackable corners than this: the video is called textureless.
    keep_raw : bool
        Keep tracking lost points and return their positions in ``Tracks.raw``.
    detect_every : int
        Every this many frames (0: never), detect new corners in the textured parts of the
        frame farther than ``min_distance`` from every live track, while fewer than
        ``max_points`` tracks are live; a new track is NaN before its frame
        (``Tracks.started_at``). ``mask`` applies to the first frame only.

    Returns
    -------
    Tracks

    Raises
    ------
    ValueError
        Fewer than 2 frames, bad settings, or a textureless first frame.
    """
    import cv2

    frames = _as_frames(frames)
    if fb_threshold <= 0:
        raise ValueError(f"fb_threshold must be positive; got {fb_threshold}")
    prev = _gray(frames[0])
    H, W = prev.shape
    m = texture_mask(prev)
    if mask is not None:
        mask = np.asarray(mask, bool)
        if mask.shape != (H, W):
            raise ValueError(f"mask has shape {mask.shape} but the frames are {(H, W)}")
        m &= mask
    pts = cv2.goodFeaturesToTrack(
        prev,
        maxCorners=int(max_points),
        qualityLevel=quality,
        minDistance=min_distance,
        mask=m.astype(np.uint8),
    )
    n = 0 if pts is None else len(pts)
    if n < min_points:
        raise ValueError(
            f"textureless video: the first frame has {n} trackable corners "
            f"(need at least {min_points})"
        )
    ts = _TrackSet(pts, frames[0], len(frames), n_neighbours, neighbour_px is not None)
    lk = dict(
        winSize=(window, window),
        maxLevel=levels,
        criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01),
    )

    def move(prev, cur, p):  # pyramidal Lucas-Kanade, both ways
        p = p.reshape(-1, 1, 2)
        q, st, res = cv2.calcOpticalFlowPyrLK(prev, cur, p, None, **lk)
        b, st2, _ = cv2.calcOpticalFlowPyrLK(cur, prev, q, None, **lk)
        e = np.linalg.norm((b - p).reshape(-1, 2), axis=1)
        bad = (
            (st.ravel() == 0)
            | (st2.ravel() == 0)
            | ~(e <= fb_threshold)
            | ~(res.ravel() <= max_residual)
        )
        return q.reshape(-1, 2), e, bad

    _follow(
        frames,
        ts,
        move,
        lambda f, cur: _detect_corners(ts, f, cur, frames[f], max_points, quality, min_distance),
        keep_raw,
        neighbour_px,
        detect_every,
    )
    params = dict(
        max_points=max_points,
        quality=quality,
        min_distance=min_distance,
        window=window,
        levels=levels,
        fb_threshold=fb_threshold,
        max_residual=max_residual,
        neighbour_px=neighbour_px,
        n_neighbours=n_neighbours,
        detect_every=detect_every,
    )
    return ts.finish("sparse", (H, W), params, keep_raw)


def _follow(frames, ts, move, detect, keep_raw, neighbour_px, detect_every):
    """The frame loop both trackers share: the live tracks of frame f - 1 moved to frame f
    by ``move(prev, cur, p) -> (q, forward-backward error, bad)`` (a point leaving the
    image is bad too), the track set advanced, and ``detect(f, cur)`` every
    ``detect_every`` frames."""
    prev = _gray(frames[0])
    H, W = prev.shape
    for f in range(1, len(frames)):
        cur = _gray(frames[f])
        if cur.shape != (H, W):
            raise ValueError(f"frame {f} is {cur.shape[::-1]} but frame 0 is {(W, H)}")
        idx, nxt, err = ts.moving(keep_raw)
        if len(idx):
            q, e, bad = move(prev, cur, ts.pts[idx])
            _advance(f, idx, q, e, bad | ~_inside(q, W, H), nxt, err, ts.active, ts.lost_at)
        ts.step(f, nxt, err, neighbour_px)
        prev = cur
        if _detect_due(f, len(frames), detect_every):
            detect(f, cur)


def _detect_corners(ts, f, gray, frame, max_points, quality, min_distance):
    """Start tracks at corners of frame f in textured space that no live track covers."""
    import cv2

    room = int(max_points) - int(ts.active.sum())
    if room <= 0:  # (maxCorners = 0 would mean "no limit" to OpenCV)
        return
    free = texture_mask(gray).astype(np.uint8)
    live = np.rint(ts.pts[ts.active]).astype(int)
    H, W = free.shape
    live = live[_inside(live, W, H)]
    taken = np.zeros_like(free)
    taken[live[:, 1], live[:, 0]] = 1
    d = 2 * int(min_distance) + 1
    taken = cv2.dilate(taken, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (d, d)))
    pts = cv2.goodFeaturesToTrack(
        gray,
        maxCorners=room,
        qualityLevel=quality,
        minDistance=min_distance,
        mask=free & (1 - taken),
    )
    if pts is not None and len(pts):
        ts.add(pts.reshape(-1, 2), f, frame)


# --------------------------------------------------------------------------- dense


def _sample(field_, pts):
    """Bilinear sample of an (H, W, C) or (H, W) field at (P, 2) points -> (P, C) or (P,)."""
    import cv2

    P = len(pts)
    cols = 1024
    rows = -(-P // cols)
    pad = np.zeros((rows * cols, 2), np.float32)
    pad[:P] = pts
    mx = pad[:, 0].reshape(rows, cols)
    my = pad[:, 1].reshape(rows, cols)
    out = cv2.remap(field_, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    if field_.ndim == 2:
        return out.reshape(-1)[:P]
    return out.reshape(-1, field_.shape[2])[:P]


def _flow_engine(name):
    import cv2

    if name in ("dis", "dis-fast"):
        dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
        if name == "dis":  # refine down to full resolution, denser patches
            dis.setFinestScale(0)
            dis.setPatchStride(2)
        return lambda a, b: dis.calc(a, b, None)
    if name == "farneback":
        return lambda a, b: cv2.calcOpticalFlowFarneback(a, b, None, 0.5, 4, 21, 5, 7, 1.5, 0)
    raise ValueError(f"unknown flow {name!r}; expected 'dis', 'dis-fast' or 'farneback'")


def _dense_mask(gray, erode):
    """Textured pixels of a frame, closed and eroded by ``erode`` pixels (bool (H, W))."""
    import cv2

    m = texture_mask(gray).astype(np.uint8)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * erode + 1, 2 * erode + 1))
    m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, k)
    return cv2.erode(m, k) > 0


def _detect_grid(ts, f, gray, frame, step, erode, max_points):
    """Start tracks at the textured grid points of frame f that no live track covers."""
    m = _dense_mask(gray, erode)
    ys, xs = np.mgrid[0 : m.shape[0] : int(step), 0 : m.shape[1] : int(step)]
    keep = m[ys, xs]
    cand = np.stack([xs[keep], ys[keep]], axis=1).astype(np.float32)
    cand = cand[ts.free_space(cand, float(step))]
    if max_points is not None:
        cand = cand[: max(int(max_points) - int(ts.active.sum()), 0)]
    if len(cand):
        ts.add(cand, f, frame)


def track_dense(
    frames,
    step=4,
    mask=None,
    fb_threshold=1.0,
    max_residual=25.0,
    neighbour_px=2.0,
    n_neighbours=8,
    flow="dis",
    erode=7,
    window=15,
    min_points=8,
    max_points=None,
    keep_raw=False,
    detect_every=0,
):
    """Grid points of the first frame (and, with ``detect_every``, of later frames) carried
    through the video by chained optical flow, with a forward-backward check at every step.

    Parameters
    ----------
    frames : sequence of (H, W) or (H, W, 3) uint8 images
    step : int
        Grid spacing in pixels.
    mask : (H, W) bool array, optional
        Where to place points; by default the textured pixels of the first frame
        (:func:`texture_mask`, closed and eroded by ``erode`` pixels so that points sit
        inside textured regions, not on their outline).
    fb_threshold : float
        Pixels: a step whose forward flow followed by the backward flow misses the start by
        more loses the track from that frame on.
    max_residual : float
        A step whose photometric residual (mean absolute grey-level difference between the
        previous frame and the flow-warped current frame over a ``window`` x ``window`` box)
        exceeds this loses the track too (occlusions can pass the forward-backward check).
    neighbour_px, n_neighbours : float, int
        Motion consistency with the nearest grid neighbours, as in :func:`track_sparse`.
    flow : {"dis", "dis-fast", "farneback"}
        OpenCV optical flow: DIS (medium preset refined down to full resolution, patch
        stride 2), ``dis-fast`` (DIS medium preset as is: about 4 x faster, but on notebook
        08's video its chained tracks drift beyond 3 px 3.6 x as often: 198 against 55 of
        1,622) or Farneback (629 of 1,622).
    max_points : int, optional
        Keep at most this many grid points (evenly subsampled).
    keep_raw : bool
        Keep carrying lost points (``Tracks.raw``).
    detect_every : int
        Every this many frames (0: never), start tracks at the grid points of the frame's
        textured pixels (closed and eroded as for the first frame) farther than ``step``
        from every live track, while fewer than ``max_points`` are live; a new track is NaN
        before its frame (``Tracks.started_at``). ``mask`` applies to the first frame only.

    Returns
    -------
    Tracks
        One track per grid point kept (dense: ``step`` pixels apart).

    Raises
    ------
    ValueError
        Fewer than 2 frames, bad settings, or too few textured grid points (textureless).
    """
    import cv2

    frames = _as_frames(frames)
    if int(step) < 1:
        raise ValueError(f"step must be a positive integer; got {step}")
    if fb_threshold <= 0:
        raise ValueError(f"fb_threshold must be positive; got {fb_threshold}")
    calc = _flow_engine(flow)
    prev = _gray(frames[0])
    H, W = prev.shape
    if mask is None:
        m = _dense_mask(prev, erode)
    else:
        m = np.asarray(mask, bool)
        if m.shape != (H, W):
            raise ValueError(f"mask has shape {m.shape} but the frames are {(H, W)}")
    gy, gx = np.mgrid[0:H, 0:W].astype(np.float32)
    ys, xs = np.mgrid[0 : H : int(step), 0 : W : int(step)]
    keep = m[ys, xs]
    pts = np.stack([xs[keep], ys[keep]], axis=1).astype(np.float32)
    if len(pts) < min_points:
        raise ValueError(
            f"textureless video: {len(pts)} textured grid points in the first "
            f"frame (need at least {min_points})"
        )
    if max_points is not None and len(pts) > max_points:
        pts = pts[np.linspace(0, len(pts) - 1, int(max_points)).astype(int)]
    ts = _TrackSet(pts, frames[0], len(frames), n_neighbours, neighbour_px is not None)

    def move(prev, cur, p):  # dense flow both ways, sampled at p
        fw, bw = calc(prev, cur), calc(cur, prev)
        q = p + _sample(fw, p)
        e = np.linalg.norm(q + _sample(bw, q) - p, axis=1)
        warped = cv2.remap(
            cur, gx + fw[..., 0], gy + fw[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        diff = cv2.blur(cv2.absdiff(prev, warped).astype(np.float32), (window, window))
        return q, e, ~(e <= fb_threshold) | ~(_sample(diff, p) <= max_residual)

    _follow(
        frames,
        ts,
        move,
        lambda f, cur: _detect_grid(ts, f, cur, frames[f], step, erode, max_points),
        keep_raw,
        neighbour_px,
        detect_every,
    )
    params = dict(
        step=step,
        fb_threshold=fb_threshold,
        max_residual=max_residual,
        neighbour_px=neighbour_px,
        n_neighbours=n_neighbours,
        window=window,
        flow=flow,
        erode=erode,
        max_points=max_points,
        detect_every=detect_every,
    )
    return ts.finish("dense", (H, W), params, keep_raw)


# --------------------------------------------------------------------------- compatibility


def tracks_from_frames(
    frames, max_points=200, quality=0.01, min_distance=7, window=21, fb_threshold=1.0
):
    """Complete sparse tracks only, (F, 2, P): :func:`track_sparse` without the lost ones.

    Raises
    ------
    ValueError
        Fewer than two frames, a textureless first frame, or no complete track.
    """
    t = track_sparse(
        frames,
        max_points=max_points,
        quality=quality,
        min_distance=min_distance,
        window=window,
        fb_threshold=fb_threshold,
    )
    if not t.complete.any():
        raise ValueError("no point was tracked through every frame")
    return t.tracks[:, :, t.complete]


def tracks_from_video(path, **kw):
    """(F, 2, P) complete tracks from a video file or folder; see :func:`tracks_from_frames`."""
    return tracks_from_frames(load_frames(path), **kw)
