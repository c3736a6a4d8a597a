"""2D tracks from video with OpenCV (Shi-Tomasi corners + pyramidal Lucas-Kanade).

Only points tracked through every frame are kept, so the result is a complete W.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _gray(frame):
    import cv2

    frame = np.asarray(frame)
    if frame.ndim == 3:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    if frame.dtype != np.uint8:
        frame = np.clip(frame, 0, 255).astype(np.uint8)
    return frame


def tracks_from_frames(frames, max_points=200, quality=0.01, min_distance=7,
                       window=21, max_error=30.0):
    """Track corners through a sequence of images.

    Parameters
    ----------
    frames : iterable of (H, W) or (H, W, 3) uint8 images
        At least two.
    max_points, quality, min_distance : detector settings (``cv2.goodFeaturesToTrack``).
    window : int
        Lucas-Kanade window size.
    max_error : float
        Tracks whose LK error exceeds this in any frame are dropped.

    Returns
    -------
    tracks : (F, 2, P) ndarray
        Pixel coordinates (x, y) of the P points that survived every frame.

    Raises
    ------
    ValueError
        Fewer than two frames, or no point survives.
    """
    import cv2

    it = iter(frames)
    try:
        prev = _gray(next(it))
    except StopIteration:
        raise ValueError("no frames given") from None
    pts = cv2.goodFeaturesToTrack(prev, maxCorners=max_points, qualityLevel=quality,
                                  minDistance=min_distance)
    if pts is None:
        raise ValueError("no trackable corners in the first frame")
    pts = pts.astype(np.float32)
    history = [pts[:, 0].copy()]
    alive = np.ones(len(pts), bool)
    lk = dict(winSize=(window, window), maxLevel=3,
              criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01))
    for frame in it:
        cur = _gray(frame)
        nxt, status, err = cv2.calcOpticalFlowPyrLK(prev, cur, pts, None, **lk)
        ok = (status[:, 0] == 1) & (err[:, 0] < max_error)
        h, w = cur.shape
        inside = ((nxt[:, 0, 0] >= 0) & (nxt[:, 0, 0] < w) & (nxt[:, 0, 1] >= 0)
                  & (nxt[:, 0, 1] < h))
        alive &= ok & inside
        history.append(nxt[:, 0].copy())
        pts, prev = nxt, cur
    if len(history) < 2:
        raise ValueError("need at least two frames")
    if not alive.any():
        raise ValueError("no point was tracked through every frame")
    tracks = np.stack(history)[:, alive, :]          # (F, P, 2)
    return tracks.transpose(0, 2, 1).astype(float)


def read_frames(path):
    """Yield the frames of a video file (BGR uint8)."""
    import cv2

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"video {path} not found")
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise ValueError(f"OpenCV cannot open {path}")
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            yield frame
    finally:
        cap.release()


def tracks_from_video(path, **kw):
    """(F, 2, P) tracks from a video file; see :func:`tracks_from_frames`."""
    return tracks_from_frames(read_frames(path), **kw)
