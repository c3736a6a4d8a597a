"""Tracks from a video: the result type :class:`Tracks` and the state of a running tracker
(positions, lost and start frames, neighbour checks), shared by the sparse and dense
trackers of :mod:`data_tools.video`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .frames import _bgr

__all__ = ["Tracks"]


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
        return (
            f"{self.method} tracks: {P} points over {F} frames, {n} complete, "
            f"{lost} lost before the last frame, {late} starting after frame 0"
        )

    def save(self, path):
        """Write an .npz with ``W`` (2F, P, NaN where lost), ``tracks``, ``lost_at``,
        ``fb_error``, ``colors``, ``image_size`` and ``method``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(
            path,
            W=self.W,
            tracks=self.tracks,
            lost_at=self.lost_at,
            started_at=self.start,
            fb_error=self.fb_error.astype(np.float32),
            colors=self.colors,
            image_size=np.asarray(self.image_size),
            method=np.array(self.method),
        )
        return path


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
        self.nbrs = np.concatenate([self.nbrs, nb[:, : self.nbrs.shape[1]] + P])
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

    def moving(self, keep_raw):
        """Tracks to move into the next frame and the arrays to fill: ``(idx, nxt, err)``."""
        idx = np.arange(self.P) if keep_raw else np.flatnonzero(self.active)
        return idx, self.pts.copy(), np.full(self.P, np.nan)

    def step(self, f, nxt, err, neighbour_px):
        """Close frame ``f``: the neighbour check on ``nxt`` (P, 2), then record it."""
        _check_neighbours(
            f,
            self.pts0,
            nxt,
            self.active,
            self.lost_at,
            self.nbrs if self.check else None,
            neighbour_px,
        )
        self.history.append(nxt.copy())
        self.fb.append(err)
        self.pts = nxt

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
            raw[f, : len(h)], fb[f, : len(e)] = h, e
        raw = raw.transpose(0, 2, 1)  # (F, 2, P)
        tracks = raw.astype(float)
        frame_idx = np.arange(F)[:, None]
        gone = (frame_idx >= self.lost_at[None, :]) | (frame_idx < self.born[None, :])
        tracks[np.broadcast_to(gone[:, None, :], tracks.shape)] = np.nan
        if not keep_raw:
            fb[gone] = np.nan
        late = self.born.any()
        return Tracks(
            tracks=tracks,
            lost_at=self.lost_at,
            fb_error=fb,
            colors=self.colors,
            method=method,
            image_size=size,
            params=params,
            raw=raw if keep_raw else None,
            started_at=self.born.copy() if late else None,
        )


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
    a = alive[nbrs]  # (P, k)
    X = np.concatenate([pts0[nbrs] - pts0[:, None], np.ones((P, k, 1))], axis=2)  # (P,k,3)
    X = X * a[..., None]
    Y = cur[nbrs] * a[..., None]  # (P, k, 2)
    A = X.transpose(0, 2, 1) @ X + 1e-6 * np.eye(3)
    B = X.transpose(0, 2, 1) @ Y
    coef = np.linalg.solve(A, B)  # (P, 3, 2)
    pred = coef[:, 2, :]  # affine map at offset 0
    with np.errstate(invalid="ignore"):
        r = np.linalg.norm(cur - pred, axis=1)
    r[a.sum(axis=1) < 3] = np.nan
    return r
