"""2D tracks from video with OpenCV: sparse (corners + pyramidal Lucas-Kanade) and dense
(optical flow chained over a grid), both with a forward-backward consistency check.

Every track starts in the first frame. A track whose forward-backward error exceeds the
threshold, whose tracker reports failure, or that leaves the image, is *lost*: it is NaN from
that frame on (missing data), never silently dropped. ``Tracks.W`` is the (2F, P)
measurement matrix with those NaNs.

Video input: a video file OpenCV can decode, or a folder of images (sorted by name).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["IMAGE_SUFFIXES", "Tracks", "load_frames", "read_frames", "texture_mask",
           "track_dense", "track_sparse", "tracks_from_frames", "tracks_from_video"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".ppm", ".pgm", ".webp")

#: Minimum eigenvalue of the structure tensor (``cv2.cornerMinEigenVal``, 7 x 7 block, grey
#: levels 0-255) above which a pixel counts as textured. Pixel noise of 2 grey levels on a
#: flat image stays below 1.1e-4; the synthetic textures have a median of 7e-4.
TEXTURE_THRESHOLD = 2e-4


# --------------------------------------------------------------------------- reading

def _gray(frame):
    import cv2

    frame = np.asarray(frame)
    if frame.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if frame.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        frame = cv2.cvtColor(frame, code)
    if frame.dtype != np.uint8:
        frame = np.clip(frame, 0, 255).astype(np.uint8)
    return frame


def _bgr(frame):
    import cv2

    frame = np.asarray(frame)
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    return frame


def read_frames(path, max_frames=None):
    """Yield the frames (BGR uint8) of a video file or of a folder of images.

    Raises
    ------
    FileNotFoundError
        The path does not exist.
    ValueError
        OpenCV cannot open the file, an image of the folder cannot be decoded, or the
        images differ in size.
    """
    import cv2

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"video {path} not found")
    count = 0
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise ValueError(f"folder {path} holds no images ({', '.join(IMAGE_SUFFIXES)})")
        shape = None
        for p in files:
            if max_frames is not None and count >= max_frames:
                return
            img = cv2.imread(str(p), cv2.IMREAD_COLOR)
            if img is None:
                raise ValueError(f"cannot decode image {p}")
            if shape is not None and img.shape != shape:
                raise ValueError(f"image {p} is {img.shape[1]}x{img.shape[0]} but the first "
                                 f"image is {shape[1]}x{shape[0]}")
            shape = img.shape
            count += 1
            yield img
        return
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise ValueError(f"cannot read {path}: OpenCV cannot open it as a video")
    try:
        while max_frames is None or count < max_frames:
            ok, frame = cap.read()
            if not ok:
                break
            count += 1
            yield _bgr(frame)
    finally:
        cap.release()


def load_frames(source, max_frames=None):
    """All frames of a video file, a folder of images, or an array, as (F, H, W, 3) uint8.

    Raises
    ------
    FileNotFoundError, ValueError
        Unreadable input (see :func:`read_frames`), fewer than 2 frames, frames of
        different sizes.
    """
    if isinstance(source, (str, Path)):
        frames = list(read_frames(source, max_frames))
        where = f"{source}"
    else:
        frames = [_bgr(f) for f in source]
        if max_frames is not None:
            frames = frames[:max_frames]
        where = "the input"
    if len(frames) == 0 and isinstance(source, (str, Path)) and Path(source).is_file():
        raise ValueError(f"cannot decode any frame from {where}: not a video OpenCV can read")
    if len(frames) < 2:
        raise ValueError(f"{where} has {len(frames)} frame(s); tracking needs at least 2")
    shapes = {f.shape for f in frames}
    if len(shapes) > 1:
        raise ValueError(f"frames of {where} differ in size: {sorted(shapes)}")
    return np.stack(frames)


# --------------------------------------------------------------------------- results

@dataclass
class Tracks:
    """Tracks from a video.

    Attributes
    ----------
    tracks : (F, 2, P) ndarray
        Pixel coordinates (x, y); NaN from the frame a track was lost on.
    lost_at : (P,) int ndarray
        First frame at which the track is NaN (F for a track kept to the end).
    fb_error : (F, P) ndarray
        Forward-backward error (pixels) of the step into frame f (0 in frame 0; NaN after
        the track was lost unless ``raw`` was kept).
    colors : (P, 3) uint8 ndarray
        RGB colour of each track's pixel in the first frame.
    method : str
        ``"sparse"`` or ``"dense"``.
    image_size : (H, W)
    params : dict
        Settings used.
    raw : (F, 2, P) ndarray or None
        With ``keep_raw=True``: positions as if no track were ever stopped (for studies of
        what the check catches).
    started_at : (P,) int ndarray or None
        First frame of each track (NaN before it): 0, or the frame where it was detected
        (``detect_every``); None means every track starts in frame 0.
    """

    tracks: np.ndarray
    lost_at: np.ndarray
    fb_error: np.ndarray
    colors: np.ndarray
    method: str
    image_size: tuple
    params: dict = field(default_factory=dict)
    raw: np.ndarray | None = None
    started_at: np.ndarray | None = None

    @property
    def n_frames(self):
        return self.tracks.shape[0]

    @property
    def n_points(self):
        return self.tracks.shape[2]

    @property
    def W(self):
        """(2F, P) measurement matrix, rows x_f, y_f interleaved, NaN where lost."""
        return self.tracks.reshape(2 * self.n_frames, self.n_points)

    @property
    def complete(self):
        """(P,) bool: tracks observed in every frame."""
        return (self.lost_at >= self.n_frames) & (self.start == 0)

    @property
    def start(self):
        """(P,) int: first frame of each track."""
        if self.started_at is None:
            return np.zeros(self.n_points, int)
        return np.asarray(self.started_at)

    def summary(self):
        F, P = self.n_frames, self.n_points
        n = int(self.complete.sum())
        late = int((self.start > 0).sum())
        lost = int((self.lost_at < F).sum())
        return (f"{self.method} tracks: {P} points over {F} frames, {n} complete, "
                f"{lost} lost before the last frame, {late} starting after frame 0")

    def save(self, path):
        """Write an .npz with ``W`` (2F, P, NaN where lost), ``tracks``, ``lost_at``,
        ``fb_error``, ``colors``, ``image_size`` and ``method``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, W=self.W, tracks=self.tracks, lost_at=self.lost_at,
                            started_at=self.start,
                            fb_error=self.fb_error.astype(np.float32), colors=self.colors,
                            image_size=np.asarray(self.image_size),
                            method=np.array(self.method))
        return path


def texture_mask(gray, block=7, threshold=TEXTURE_THRESHOLD):
    """(H, W) bool: pixels whose structure tensor's smaller eigenvalue exceeds ``threshold``."""
    import cv2

    return cv2.cornerMinEigenVal(_gray(gray), block) > threshold


def _as_frames(frames):
    F = list(frames) if not isinstance(frames, np.ndarray) else frames
    if len(F) < 2:
        raise ValueError(f"tracking needs at least 2 frames; got {len(F)}")
    first = np.asarray(F[0])
    if first.ndim not in (2, 3):
        raise ValueError(f"frames must be (H, W) or (H, W, 3) images; got shape {first.shape}")
    return F


def _colors(frame, pts):
    img = _bgr(np.asarray(frame))
    H, W = img.shape[:2]
    xi = np.clip(np.rint(pts[:, 0]).astype(int), 0, W - 1)
    yi = np.clip(np.rint(pts[:, 1]).astype(int), 0, H - 1)
    return img[yi, xi][:, ::-1].astype(np.uint8).copy()


class _TrackSet:
    """The tracks while a tracker runs: positions, state, and the batches started later.

    Every batch (the first frame's points, then each detection) keeps its points' positions
    at detection (``pts0``) and neighbours within the batch, so the neighbour check maps
    each point's own first frame to now.
    """

    def __init__(self, pts, frame, n_frames, n_neighbours, check):
        self.n_frames, self.k, self.check = n_frames, n_neighbours, check
        self.pts = np.zeros((0, 2), np.float32)
        self.pts0 = self.pts.copy()
        self.born = np.zeros(0, int)
        self.lost_at = np.zeros(0, int)
        self.active = np.zeros(0, bool)
        self.colors = np.zeros((0, 3), np.uint8)
        self.nbrs = np.zeros((0, max(n_neighbours, 1)), int)
        self.history, self.fb = [], []
        self.add(pts, 0, frame)

    @property
    def P(self):
        return len(self.pts)

    def add(self, new, f, frame):
        """Start tracks at ``new`` (n, 2) in frame ``f`` (NaN before it)."""
        new = np.asarray(new, np.float32).reshape(-1, 2)
        n, P = len(new), self.P
        nb = _neighbours(new, self.k) if self.check else None
        if nb is None or nb.shape[1] < self.nbrs.shape[1]:
            nb = np.repeat(np.arange(n)[:, None], self.nbrs.shape[1], axis=1)  # no check
        self.nbrs = np.concatenate([self.nbrs, nb[:, :self.nbrs.shape[1]] + P])
        self.pts = np.concatenate([self.pts, new])
        self.pts0 = np.concatenate([self.pts0, new])
        self.born = np.concatenate([self.born, np.full(n, f)])
        self.lost_at = np.concatenate([self.lost_at, np.full(n, self.n_frames)])
        self.active = np.concatenate([self.active, np.ones(n, bool)])
        self.colors = np.concatenate([self.colors, _colors(frame, new)])
        if f == 0:
            self.history.append(self.pts.copy())
            self.fb.append(np.zeros(self.P))
        else:
            self.history[-1] = np.concatenate([self.history[-1], new])
            self.fb[-1] = np.concatenate([self.fb[-1], np.zeros(n)])

    def free_space(self, cand, radius):
        """(n,) bool: candidate points (n, 2) farther than ``radius`` from every live track."""
        from scipy.spatial import cKDTree

        live = self.pts[self.active]
        if len(live) == 0 or len(cand) == 0:
            return np.ones(len(cand), bool)
        d, _ = cKDTree(live).query(cand, 1)
        return d > radius

    def finish(self, method, size, params, keep_raw):
        F, P = len(self.history), self.P
        raw = np.full((F, P, 2), np.nan, np.float32)
        fb = np.full((F, P), np.nan)
        for f, (h, e) in enumerate(zip(self.history, self.fb)):
            raw[f, :len(h)], fb[f, :len(e)] = h, e
        raw = raw.transpose(0, 2, 1)                          # (F, 2, P)
        tracks = raw.astype(float)
        frame_idx = np.arange(F)[:, None]
        gone = (frame_idx >= self.lost_at[None, :]) | (frame_idx < self.born[None, :])
        tracks[np.broadcast_to(gone[:, None, :], tracks.shape)] = np.nan
        if not keep_raw:
            fb[gone] = np.nan
        late = self.born.any()
        return Tracks(tracks=tracks, lost_at=self.lost_at, fb_error=fb, colors=self.colors,
                      method=method, image_size=size, params=params,
                      raw=raw if keep_raw else None,
                      started_at=self.born.copy() if late else None)


def _detect_due(f, n_frames, detect_every):
    """New tracks are detected in frame f every ``detect_every`` frames (not the last)."""
    return bool(detect_every) and f % int(detect_every) == 0 and f < n_frames - 1


# --------------------------------------------------------------------------- neighbours

def _neighbours(pts0, k):
    """(P, k) indices of each point's k nearest other points in the first frame."""
    from scipy.spatial import cKDTree

    k = min(k, len(pts0) - 1)
    if k < 3:
        return None
    _, idx = cKDTree(pts0).query(pts0, k + 1)
    return idx[:, 1:]


def _inside(q, W, H):
    """(n,) bool: the (n, 2) pixel positions lie inside a W x H image."""
    return (q[:, 0] >= 0) & (q[:, 0] <= W - 1) & (q[:, 1] >= 0) & (q[:, 1] <= H - 1)


def _advance(f, idx, q, e, bad, nxt, err, active, lost_at):
    """Move tracks ``idx`` to ``q`` (forward-backward error ``e``); an active track that
    fails a check (``bad``) is lost at frame ``f``. Updates the arrays in place."""
    nxt[idx] = q
    err[idx] = e
    newly = active[idx] & bad
    lost_at[idx[newly]] = f
    active[idx[newly]] = False


def _check_neighbours(f, pts0, nxt, active, lost_at, nbrs, neighbour_px):
    """Lose, at frame ``f``, active tracks farther than ``neighbour_px`` from where their
    neighbours' motion puts them (identity swaps that pass the other checks)."""
    if nbrs is None or not active.any():
        return
    newly = active & (_neighbour_residual(pts0, nxt, active, nbrs) > neighbour_px)
    lost_at[newly] = f
    active[newly] = False


def _neighbour_residual(pts0, cur, alive, nbrs):
    """Distance of each point in ``cur`` from the position predicted by the affine map
    (first frame -> now) fitted to its live neighbours; NaN with fewer than 3 of them."""
    P, k = nbrs.shape
    a = alive[nbrs]                                              # (P, k)
    X = np.concatenate([pts0[nbrs] - pts0[:, None], np.ones((P, k, 1))], axis=2)  # (P,k,3)
    X = X * a[..., None]
    Y = cur[nbrs] * a[..., None]                                 # (P, k, 2)
    A = X.transpose(0, 2, 1) @ X + 1e-6 * np.eye(3)
    B = X.transpose(0, 2, 1) @ Y
    coef = np.linalg.solve(A, B)                                 # (P, 3, 2)
    pred = coef[:, 2, :]                                         # affine map at offset 0
    with np.errstate(invalid="ignore"):
        r = np.linalg.norm(cur - pred, axis=1)
    r[a.sum(axis=1) < 3] = np.nan
    return r


# --------------------------------------------------------------------------- sparse

def track_sparse(frames, max_points=2000, quality=0.01, min_distance=5, window=15,
                 levels=3, fb_threshold=1.0, max_residual=25.0, neighbour_px=2.0,
                 n_neighbours=8, mask=None, min_points=8, keep_raw=False, detect_every=0):
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
    pts = cv2.goodFeaturesToTrack(prev, maxCorners=int(max_points), qualityLevel=quality,
                                  minDistance=min_distance, mask=m.astype(np.uint8))
    n = 0 if pts is None else len(pts)
    if n < min_points:
        raise ValueError(f"textureless video: the first frame has {n} trackable corners "
                         f"(need at least {min_points})")
    ts = _TrackSet(pts, frames[0], len(frames), n_neighbours, neighbour_px is not None)
    lk = dict(winSize=(window, window), maxLevel=levels,
              criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01))
    for f in range(1, len(frames)):
        cur = _gray(frames[f])
        if cur.shape != (H, W):
            raise ValueError(f"frame {f} is {cur.shape[::-1]} but frame 0 is {(W, H)}")
        P = ts.P
        idx = np.arange(P) if keep_raw else np.flatnonzero(ts.active)
        nxt = ts.pts.copy()
        err = np.full(P, np.nan)
        if len(idx):
            p = ts.pts[idx].reshape(-1, 1, 2)
            q, st, res = cv2.calcOpticalFlowPyrLK(prev, cur, p, None, **lk)
            b, st2, _ = cv2.calcOpticalFlowPyrLK(cur, prev, q, None, **lk)
            e = np.linalg.norm((b - p).reshape(-1, 2), axis=1)
            q = q.reshape(-1, 2)
            bad = ((st.ravel() == 0) | (st2.ravel() == 0) | ~_inside(q, W, H)
                   | ~(e <= fb_threshold) | ~(res.ravel() <= max_residual))
            _advance(f, idx, q, e, bad, nxt, err, ts.active, ts.lost_at)
        _check_neighbours(f, ts.pts0, nxt, ts.active, ts.lost_at,
                          ts.nbrs if ts.check else None, neighbour_px)
        ts.history.append(nxt.copy())
        ts.fb.append(err)
        ts.pts, prev = nxt, cur
        if _detect_due(f, len(frames), detect_every):
            _detect_corners(ts, f, cur, frames[f], max_points, quality, min_distance)
    params = dict(max_points=max_points, quality=quality, min_distance=min_distance,
                  window=window, levels=levels, fb_threshold=fb_threshold,
                  max_residual=max_residual, neighbour_px=neighbour_px,
                  n_neighbours=n_neighbours, detect_every=detect_every)
    return ts.finish("sparse", (H, W), params, keep_raw)


def _detect_corners(ts, f, gray, frame, max_points, quality, min_distance):
    """Start tracks at corners of frame f in textured space that no live track covers."""
    import cv2

    room = int(max_points) - int(ts.active.sum())
    if room <= 0:                     # (maxCorners = 0 would mean "no limit" to OpenCV)
        return
    free = texture_mask(gray).astype(np.uint8)
    live = np.rint(ts.pts[ts.active]).astype(int)
    H, W = free.shape
    live = live[_inside(live, W, H)]
    taken = np.zeros_like(free)
    taken[live[:, 1], live[:, 0]] = 1
    d = 2 * int(min_distance) + 1
    taken = cv2.dilate(taken, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (d, d)))
    pts = cv2.goodFeaturesToTrack(gray, maxCorners=room, qualityLevel=quality,
                                  minDistance=min_distance, mask=free & (1 - taken))
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
        if name == "dis":            # refine down to full resolution, denser patches
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
    ys, xs = np.mgrid[0:m.shape[0]:int(step), 0:m.shape[1]:int(step)]
    keep = m[ys, xs]
    cand = np.stack([xs[keep], ys[keep]], axis=1).astype(np.float32)
    cand = cand[ts.free_space(cand, float(step))]
    if max_points is not None:
        cand = cand[:max(int(max_points) - int(ts.active.sum()), 0)]
    if len(cand):
        ts.add(cand, f, frame)


def track_dense(frames, step=4, mask=None, fb_threshold=1.0, max_residual=25.0,
                neighbour_px=2.0, n_neighbours=8, flow="dis", erode=7, window=15,
                min_points=8, max_points=None, keep_raw=False, detect_every=0):
    """Grid points of the first frame (and, with ``detect_every``, of later frames) carried through the video by chained optical flow,
    with a forward-backward check at every step.

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
    ys, xs = np.mgrid[0:H:int(step), 0:W:int(step)]
    keep = m[ys, xs]
    pts = np.stack([xs[keep], ys[keep]], axis=1).astype(np.float32)
    if len(pts) < min_points:
        raise ValueError(f"textureless video: {len(pts)} textured grid points in the first "
                         f"frame (need at least {min_points})")
    if max_points is not None and len(pts) > max_points:
        pts = pts[np.linspace(0, len(pts) - 1, int(max_points)).astype(int)]
    ts = _TrackSet(pts, frames[0], len(frames), n_neighbours, neighbour_px is not None)
    for f in range(1, len(frames)):
        cur = _gray(frames[f])
        if cur.shape != (H, W):
            raise ValueError(f"frame {f} is {cur.shape[::-1]} but frame 0 is {(W, H)}")
        fw = calc(prev, cur)
        bw = calc(cur, prev)
        P = ts.P
        idx = np.arange(P) if keep_raw else np.flatnonzero(ts.active)
        nxt = ts.pts.copy()
        err = np.full(P, np.nan)
        if len(idx):
            p = ts.pts[idx]
            q = p + _sample(fw, p)
            back = q + _sample(bw, q)
            e = np.linalg.norm(back - p, axis=1)
            warped = cv2.remap(cur, gx + fw[..., 0], gy + fw[..., 1], cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
            diff = cv2.blur(cv2.absdiff(prev, warped).astype(np.float32), (window, window))
            res = _sample(diff, p)
            bad = ~_inside(q, W, H) | ~(e <= fb_threshold) | ~(res <= max_residual)
            _advance(f, idx, q, e, bad, nxt, err, ts.active, ts.lost_at)
        _check_neighbours(f, ts.pts0, nxt, ts.active, ts.lost_at,
                          ts.nbrs if ts.check else None, neighbour_px)
        ts.history.append(nxt.copy())
        ts.fb.append(err)
        ts.pts, prev = nxt, cur
        if _detect_due(f, len(frames), detect_every):
            _detect_grid(ts, f, cur, frames[f], step, erode, max_points)
    params = dict(step=step, fb_threshold=fb_threshold, max_residual=max_residual,
                  neighbour_px=neighbour_px, n_neighbours=n_neighbours,
                  window=window, flow=flow, erode=erode,
                  max_points=max_points, detect_every=detect_every)
    return ts.finish("dense", (H, W), params, keep_raw)


# --------------------------------------------------------------------------- compatibility

def tracks_from_frames(frames, max_points=200, quality=0.01, min_distance=7, window=21,
                       fb_threshold=1.0):
    """Complete sparse tracks only, (F, 2, P): :func:`track_sparse` without the lost ones.

    Raises
    ------
    ValueError
        Fewer than two frames, a textureless first frame, or no complete track.
    """
    t = track_sparse(frames, max_points=max_points, quality=quality,
                     min_distance=min_distance, window=window, fb_threshold=fb_threshold)
    if not t.complete.any():
        raise ValueError("no point was tracked through every frame")
    return t.tracks[:, :, t.complete]


def tracks_from_video(path, **kw):
    """(F, 2, P) complete tracks from a video file or folder; see :func:`tracks_from_frames`."""
    return tracks_from_frames(load_frames(path), **kw)
