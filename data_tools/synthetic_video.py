"""Synthetic videos with ground truth: a textured, deforming surface under a moving
orthographic or pinhole camera, rendered with OpenCV.

The surface is a triangle mesh over the parameter square ``(u, v) in [0, 1]^2`` whose
vertices move with a low-rank deformation (``X_f = B_0 + sum_k c_fk B_k``, the shape model of
the paper's Eq. 1). Every frame is rendered by rasterising the triangles far to near into an
id buffer (``cv2.fillConvexPoly``), mapping each pixel to its texture coordinate through its
triangle's affine map (exact for an orthographic view of a planar triangle) and sampling a
texture with ``cv2.remap``. A tracked point is located on the mesh in its first frame
(triangle and barycentric coordinates); its true 3D position in every frame is then the
same barycentric combination of the moved vertices, exactly what was rendered.

With a pinhole camera (``make_video(..., camera=PerspectiveCamera(...))``) a triangle's image
is still a triangle (the id buffer is exact) but the map from pixels to the triangle is no
longer affine: the image barycentric coordinates ``b_i`` are corrected to the triangle's own
(perspective-correct) ``l_i = (b_i / z_i) / sum_j (b_j / z_j)``, with ``z_i`` the vertices'
depths, for the texture lookup and for locating tracks alike, so that the ground truth is again
exactly what was rendered.

Surfaces: ``"sheet"``, a bent waving flag (a travelling wave, rank 2, and a slow twist on top
of the rest shape),
and ``"face"``, a face-like relief (dome, nose, brows, chin) that breathes (scaled depth)
and opens its mouth.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from nrsfm.sequence import Sequence

from .synthetic import PerspectiveCamera

SURFACES = ("sheet", "face")

__all__ = ["SURFACES", "SyntheticVideo", "make_texture", "make_video", "tracking_errors"]


def make_texture(size=1024, seed=0):
    """A colourful, corner-rich texture, (size, size, 3) uint8 BGR.

    Multi-octave smooth noise (for dense optical flow) plus random rectangles, discs and
    lines (for corners).
    """
    import cv2

    rng = np.random.default_rng(seed)
    tex = np.zeros((size, size, 3), np.float32)
    for octave, weight in ((8, 0.5), (32, 0.3), (128, 0.2)):
        small = rng.random((octave, octave, 3)).astype(np.float32)
        tex += weight * cv2.resize(small, (size, size), interpolation=cv2.INTER_CUBIC)
    tex = np.clip(tex * 255, 0, 255).astype(np.uint8)
    n = size * size // 2500
    for _ in range(n):
        colour = tuple(int(c) for c in rng.integers(0, 256, 3))
        kind = rng.integers(0, 3)
        x, y = (int(c) for c in rng.integers(0, size, 2))
        r = int(rng.integers(size // 200 + 2, size // 40 + 4))
        if kind == 0:
            cv2.rectangle(tex, (x - r, y - r // 2), (x + r, y + r), colour, -1)
        elif kind == 1:
            cv2.circle(tex, (x, y), r, colour, -1)
        else:
            dx, dy = (int(c) for c in rng.integers(-3 * r, 3 * r, 2))
            cv2.line(tex, (x, y), (x + dx, y + dy), colour, max(1, r // 4))
    return tex


def _grid(n):
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)  # (V, 2), index i = row*n+col
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    tris = np.concatenate(
        [np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)]
    )
    return uv, tris


def _surface(kind, uv, F, rng):
    """World vertices (F, 3, V) of a low-rank deforming surface, and its basis (K, 3, V)."""
    u, v = uv[:, 0], uv[:, 1]
    x, y = 2 * u - 1, 1.5 * v - 0.75
    t = np.arange(F) / max(F - 1, 1)
    phase = rng.uniform(0, 2 * np.pi)
    zero = np.zeros_like(x)
    if kind == "sheet":
        # Travelling wave sin(k x - w t) = sin(k x) cos(w t) - cos(k x) sin(w t): rank 2,
        # its amplitude growing away from the left edge (where a flag is held).
        # The rest shape is bent (a flat sheet would make the rigid factorisation
        # degenerate: its mean shape has rank 2).
        k, amp = 1.6 * np.pi, 0.15 * (0.3 + 0.7 * u)
        bend = 0.35 * (1 - x**2) + 0.15 * (y / 0.75) ** 2
        B = np.stack(
            [
                np.stack([x, y, bend]),
                np.stack([zero, zero, amp * np.sin(k * x)]),
                np.stack([zero, zero, amp * np.cos(k * x)]),
                np.stack([zero, zero, 0.12 * np.sin(np.pi * v) * x]),
            ]
        )
        w = 2 * np.pi * 1.5
        coeff = np.stack(
            [
                np.ones(F),
                np.cos(w * t + phase),
                -np.sin(w * t + phase),
                np.sin(2 * np.pi * t + 0.5 * phase),
            ],
            axis=1,
        )
    elif kind == "face":
        r2 = (x / 0.95) ** 2 + (y / 0.8) ** 2
        dome = 0.45 * np.sqrt(np.clip(1 - r2, 0, None))
        nose = 0.22 * np.exp(-((x / 0.12) ** 2 + ((y - 0.05) / 0.22) ** 2))
        brows = 0.07 * np.exp(-(((np.abs(x) - 0.32) / 0.2) ** 2 + ((y + 0.25) / 0.06) ** 2))
        eyes = -0.08 * np.exp(-(((np.abs(x) - 0.32) / 0.14) ** 2 + ((y + 0.12) / 0.08) ** 2))
        chin = 0.08 * np.exp(-((x / 0.3) ** 2 + ((y - 0.6) / 0.12) ** 2))
        mean_z = dome + nose + brows + eyes + chin
        jaw = np.clip((y - 0.25) / 0.5, 0, 1) ** 1.5 * np.exp(-((x / 0.6) ** 2))
        B = np.stack(
            [
                np.stack([x, y, mean_z]),
                np.stack([0.05 * x, 0.05 * y, mean_z]),  # breathing
                np.stack([zero, 0.25 * jaw, -0.1 * jaw]),
            ]
        )  # mouth opening
        coeff = np.stack(
            [
                np.ones(F),
                0.6 * np.sin(2 * np.pi * 2 * t + phase),
                0.5 + 0.5 * np.sin(2 * np.pi * 1.3 * t + 0.7 * phase),
            ],
            axis=1,
        )
    else:
        raise ValueError(f"unknown surface {kind!r}; expected one of {SURFACES}")
    return np.einsum("fk,kiv->fiv", coeff, B), B, coeff


def _cameras(F, rng, yaw=28.0, pitch=14.0, roll=5.0):
    t = np.arange(F) / max(F - 1, 1)
    ph = rng.uniform(0, 2 * np.pi, 3)
    angles = np.stack(
        [
            pitch * np.sin(2 * np.pi * 0.8 * t + ph[0]),
            yaw * np.sin(2 * np.pi * 1.0 * t + ph[1]),
            roll * np.sin(2 * np.pi * 0.6 * t + ph[2]),
        ],
        axis=1,
    )
    return Rotation.from_euler("xyz", angles, degrees=True).as_matrix()


@dataclass
class SyntheticVideo:
    """A rendered video of a deforming textured mesh, with everything needed for ground truth.

    Attributes
    ----------
    frames : (F, H, W, 3) uint8 ndarray or None
        BGR frames; None for a ground truth read by
        :func:`data_tools.video_truth.load_ground_truth`.
    surface : str
    uv : (V, 2) ndarray
        Surface (texture) coordinates of the mesh vertices.
    triangles : (T, 3) int ndarray
    vertices : (F, 3, V) ndarray
        World coordinates of the vertices per frame.
    rotations : (F, 3, 3) ndarray
        World-to-camera rotations.
    pixel_scale : float
        Pixels per world unit (orthographic camera); with a pinhole camera, ``focal /
        depth``: the pixels per world unit at the world origin's depth (nominal only).
    offsets : (F, 2) ndarray
        Image position of the world origin per frame: ``pixel = s (R_f X)[:2] + offset_f``
        (orthographic camera).
    id0 : (H, W) int32 ndarray
        Triangle index + 1 visible at each pixel of frame 0 (0: background).
    affine0 : (T, 3, 3) ndarray
        Per triangle, the map from homogeneous pixel (x, y, 1) in frame 0 to its (image)
        barycentric coordinates.
    extra : dict
        ``basis`` (K, 3, V), ``coefficients`` (F, K), ``seed``; with a pinhole camera also
        ``intrinsics`` (3, 3) and ``depth``.
    camera : PerspectiveCamera or None
        None: orthographic. Else the pinhole camera the frames were rendered through (its
        principal point the one used); ``pixel = camera.project(R_f X + t_f)``.
    translations : (F, 3) ndarray or None
        With a pinhole camera, the world-to-camera translations ``t_f``.
    """

    frames: np.ndarray
    surface: str
    uv: np.ndarray
    triangles: np.ndarray
    vertices: np.ndarray
    rotations: np.ndarray
    pixel_scale: float
    offsets: np.ndarray
    id0: np.ndarray
    affine0: np.ndarray
    extra: dict = field(default_factory=dict)
    camera: PerspectiveCamera | None = None
    translations: np.ndarray | None = None

    @property
    def n_frames(self):
        """Number of frames (also without ``frames``)."""
        return self.vertices.shape[0]

    @property
    def intrinsics(self):
        """(3, 3) ndarray: the pinhole camera's matrix; None for an orthographic video."""
        return None if self.camera is None else self.camera.intrinsics

    def to_camera(self, X_world):
        """Camera-frame points (F, 3, P) of world points (F, 3, P): ``R_f X`` (orthographic),
        ``R_f X + t_f`` (pinhole; metric, depth along z)."""
        cam = self.rotations @ X_world
        if self.camera is not None:
            cam = cam + self.translations[:, :, None]
        return cam

    def project(self, X_world):
        """Pixel positions (F, 2, P) of world points (F, 3, P)."""
        if self.camera is not None:
            return self.camera.project(self.to_camera(X_world))
        cam = self.rotations @ X_world
        return self.pixel_scale * cam[:, :2] + self.offsets[:, :, None]

    def _frame_view(self, frame):
        """Pixels (V, 2) and camera-frame depths (V,) of the vertices in one frame."""
        t = None if self.camera is None else self.translations[frame]
        args = (self.pixel_scale, self.offsets[frame], self.camera, t)
        return _view(self.rotations[frame] @ self.vertices[frame], *args)

    def locate(self, points, frame=0):
        """Mesh location of pixel positions in a frame.

        Parameters
        ----------
        points : (P, 2) array_like
            (x, y) pixel positions in ``frame``.
        frame : int
            The frame the positions are in (frame 0's id buffer is stored; another frame's
            is rasterised again).

        Returns
        -------
        triangle : (P,) int ndarray
            Triangle index, -1 where the pixel shows the background.
        bary : (P, 3) ndarray
            Barycentric coordinates in that triangle (NaN where ``triangle == -1``); with a
            pinhole camera the triangle's own (perspective-correct) ones, so that
            :meth:`world_points` projects back onto ``points``.
        """
        p = np.asarray(points, float).reshape(-1, 2)
        view = None if frame == 0 and self.camera is None else self._frame_view(frame)
        if frame == 0:
            ids, affine = self.id0, self.affine0
        else:
            ids, affine = _id_buffer(self.triangles, *view, self.id0.shape)
        H, W = ids.shape
        xi = np.clip(np.rint(np.nan_to_num(p[:, 0])).astype(int), 0, W - 1)
        yi = np.clip(np.rint(np.nan_to_num(p[:, 1])).astype(int), 0, H - 1)
        inside = (
            np.isfinite(p).all(1)
            & (p[:, 0] > -0.5)
            & (p[:, 0] < W - 0.5)
            & (p[:, 1] > -0.5)
            & (p[:, 1] < H - 0.5)
        )
        tri = np.where(inside, ids[yi, xi] - 1, -1)
        hom = np.concatenate([p, np.ones((len(p), 1))], axis=1)
        bary = np.full((len(p), 3), np.nan)
        ok = tri >= 0
        bary[ok] = np.einsum("pij,pj->pi", affine[tri[ok]], hom[ok])
        if self.camera is not None:  # view: the frame's pixels and vertex depths
            bary[ok] = _perspective_correct(bary[ok], 1.0 / view[1][self.triangles[tri[ok]]])
        return tri, bary

    def world_points(self, triangle, bary):
        """True world 3D (F, 3, P) of mesh locations; NaN where ``triangle == -1``."""
        triangle = np.asarray(triangle)
        ok = triangle >= 0
        X = np.full((self.n_frames, 3, len(triangle)), np.nan)
        verts = self.vertices[:, :, self.triangles[triangle[ok]]]  # (F, 3, P', 3)
        X[:, :, ok] = np.einsum("fipj,pj->fip", verts, bary[ok])
        return X

    def ground_truth(self, tracks):
        """Ground truth of tracks, each located on the mesh in its first observed frame
        (frame 0, or later for a track that starts late; NaN before).

        Parameters
        ----------
        tracks : (F, 2, P) ndarray or data_tools.video.Tracks
            Pixel tracks (NaN where not observed).

        Returns
        -------
        dict
            ``world`` (F, 3, P) true 3D in the world frame, ``camera`` (F, 3, P) in the
            camera frame (``R_f X``; with a pinhole camera ``R_f X + t_f``, metric),
            ``pixels`` (F, 2, P) true image positions, ``valid`` (P,) bool: the track
            started on the surface (not the background).
        """
        tracks = np.asarray(getattr(tracks, "tracks", tracks), float)
        seen = np.isfinite(tracks).all(axis=1)  # (F, P)
        first = np.where(seen.any(axis=0), seen.argmax(axis=0), 0)
        tri = np.full(tracks.shape[2], -1)
        bary = np.full((tracks.shape[2], 3), np.nan)
        for f in np.unique(first):
            cols = np.flatnonzero(first == f)
            tri[cols], bary[cols] = self.locate(tracks[f][:, cols].T, frame=int(f))
        world = self.world_points(tri, bary)
        return dict(
            world=world, camera=self.to_camera(world), pixels=self.project(world), valid=tri >= 0
        )

    def sequence(self, tracks, name=None):
        """A :class:`Sequence` of the valid tracks' pixel coordinates with 3D ground truth.

        ``tracks``: (F, 2, P) array or ``Tracks``, as for :meth:`ground_truth`.

        Orthographic camera: ``W`` holds the row-centred tracks of the points with ground
        truth (NaN kept); ``shapes`` the true camera-frame 3D, scaled to pixels and centred
        per frame.

        Pinhole camera: ``W`` holds the tracks in pixels as they are (not centred: the
        perspective refinement needs them so); ``shapes`` the true camera-frame 3D in world
        units (metric, not scaled to pixels), centred per frame, ``world_shapes`` the world
        3D; ``extra["intrinsics"]`` the camera matrix, so that
        ``nrsfm.reconstruct(seq.W, K, intrinsics=seq.extra["intrinsics"])`` runs on it.
        """
        gt = self.ground_truth(tracks)
        ok = gt["valid"]
        F = self.n_frames
        T = np.asarray(getattr(tracks, "tracks", tracks), float)[:, :, ok]
        W = T.reshape(2 * F, -1)
        extra = dict(valid=ok)
        if self.camera is None:
            W = W - np.nanmean(W, axis=1, keepdims=True)
            scale = self.pixel_scale
        else:
            scale = 1.0
            extra.update(intrinsics=self.intrinsics, translations=self.translations)
        cam = scale * gt["camera"][:, :, ok]
        cam = cam - cam.mean(axis=2, keepdims=True)
        return Sequence(
            name=name or f"video-{self.surface}",
            W=W,
            shapes=cam,
            rotations=self.rotations,
            K=None,
            world_shapes=scale * gt["world"][:, :, ok],
            extra=extra,
        )


def _view(cam, scale, offset, camera, t):
    """Pixels (V, 2) and camera-frame depths (V,) of one frame's rotated vertices ``cam`` (3,
    V): orthographic (``scale``, ``offset``), or through the pinhole ``camera`` after the
    translation ``t``."""
    if camera is None:
        return (scale * cam[:2] + offset[:, None]).T, cam[2]
    cam = cam + t[:, None]
    return camera.project(cam[None])[0].T, cam[2]


def _perspective_correct(bary, zinv):
    """A triangle's own barycentric coordinates (P, 3) from the image ones (P, 3), given its
    vertices' inverse depths (P, 3): ``(b_i / z_i) / sum_j (b_j / z_j)``."""
    w = bary * zinv
    return w / w.sum(axis=1, keepdims=True)


def _id_buffer(tris, pix, depth, size):
    """Triangle index + 1 at every pixel (H, W) and the per-triangle maps (T, 3, 3) from
    homogeneous pixels to barycentric coordinates, of one frame."""
    import cv2

    H, W = size
    ids = np.zeros((H, W), np.int32)
    corners = pix[tris]  # (T, 3, 2)
    order = np.argsort(-depth[tris].mean(axis=1), kind="stable")  # far (large z) first
    fixed = np.rint(corners * 16).astype(np.int32)
    for t in order:
        cv2.fillConvexPoly(ids, fixed[t], int(t) + 1, lineType=cv2.LINE_8, shift=4)
    # barycentric map per triangle: inverse of [[x0 x1 x2], [y0 y1 y2], [1 1 1]]
    Mt = np.concatenate([corners.transpose(0, 2, 1), np.ones((len(tris), 1, 3))], axis=1)
    det = np.linalg.det(Mt)
    safe = np.abs(det) > 1e-9
    affine = np.zeros_like(Mt)
    affine[safe] = np.linalg.inv(Mt[safe])
    return ids, affine


def _render(texture, uv_pix, tris, pix, depth, size, background, pinhole=False):
    """One frame: id buffer, per-triangle affine maps, textured image (with ``pinhole``,
    the texture coordinates interpolated perspective-correctly; ``depth`` then the vertices'
    positive depths)."""
    import cv2

    H, W = size
    ids, affine = _id_buffer(tris, pix, depth, size)
    yy, xx = np.nonzero(ids)
    tri = ids[yy, xx] - 1
    hom = np.stack([xx, yy, np.ones_like(xx)], axis=1).astype(float)
    bary = np.einsum("pij,pj->pi", affine[tri], hom)
    if pinhole:
        bary = _perspective_correct(bary, 1.0 / depth[tris[tri]])
    tex_xy = np.einsum("pj,pjk->pk", bary, uv_pix[tris[tri]])
    map_x = np.full((H, W), -1.0, np.float32)
    map_y = np.full((H, W), -1.0, np.float32)
    map_x[yy, xx], map_y[yy, xx] = tex_xy[:, 0], tex_xy[:, 1]
    img = cv2.remap(
        texture,
        map_x,
        map_y,
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=background,
    )
    img[ids == 0] = background
    return img, ids, affine


def make_video(
    surface="sheet",
    n_frames=100,
    size=(480, 640),
    grid=61,
    seed=0,
    noise=0.0,
    texture_size=None,
    fill=0.7,
    camera=None,
):
    """Render a synthetic video of a deforming textured surface with ground truth.

    Parameters
    ----------
    surface : {"sheet", "face"}
        ``sheet``: a waving flag; ``face``: a breathing face-like relief with a moving jaw.
    n_frames : int
        At least 2.
    size : (H, W)
        Image size in pixels.
    grid : int
        Mesh resolution: ``grid x grid`` vertices (thousands of surface points),
        ``2 (grid - 1)^2`` triangles.
    seed : int
        Seeds the texture, the deformation phases and the camera path.
    noise : float
        Standard deviation of Gaussian pixel noise (grey levels) added to each frame.
    texture_size : int, optional
        Side of the square texture in pixels; default about the surface's size in the
        image (a texture much finer than the pixels aliases, which biases the trackers).
    fill : float
        Fraction of the image's smaller side that the surface's height spans (orthographic
        camera; also sets the default ``texture_size``).
    camera : PerspectiveCamera, optional
        None: an orthographic camera. A :class:`~data_tools.PerspectiveCamera`: a pinhole
        camera. Each frame's world vertices are rotated as without it (the same camera
        path), placed ``camera.distance`` times the surface's radius (the largest distance
        of a vertex from the world origin, about which the surface turns, over all frames)
        in front of the camera, and projected with ``camera.focal``; the orthographic
        video's image drift becomes a lateral translation of the same pixels at that depth.
        The principal point is the camera's when it lies inside the image, else the image
        centre (``(W / 2, H / 2)``); the video's ``camera`` holds the one used. The focal
        length is not adapted to the image: ``focal = 800 * min(H, W) / 480`` frames the
        sheet about as the orthographic video does.

    Returns
    -------
    SyntheticVideo
    """
    if surface not in SURFACES:
        raise ValueError(f"unknown surface {surface!r}; expected one of {SURFACES}")
    if int(n_frames) < 2:
        raise ValueError(f"n_frames must be at least 2; got {n_frames}")
    H, W = (int(s) for s in size)
    if H < 32 or W < 32:
        raise ValueError(f"size must be at least 32 x 32 pixels; got {size}")
    if int(grid) < 3:
        raise ValueError(f"grid must be at least 3; got {grid}")
    if camera is not None and not isinstance(camera, PerspectiveCamera):
        raise TypeError(f"camera must be a PerspectiveCamera or None; got {type(camera).__name__}")
    F = int(n_frames)
    rng = np.random.default_rng(seed)
    s = fill * min(H, W) / 1.5
    if texture_size is None:
        texture_size = int(max(64, round(2.0 * s)))
    texture = make_texture(texture_size, seed)
    uv, tris = _grid(int(grid))
    vertices, basis, coeff = _surface(surface, uv, F, rng)
    if surface == "face":  # an oval outline: keep the inner triangles
        x, y = 2 * uv[:, 0] - 1, 1.5 * uv[:, 1] - 0.75
        inner = (x / 0.95) ** 2 + (y / 0.8) ** 2 <= 1.0
        tris = tris[inner[tris].all(axis=1)]
    R = _cameras(F, rng)
    t = np.arange(F) / max(F - 1, 1)
    drift = np.stack(
        [
            0.04 * W * np.sin(2 * np.pi * 0.7 * t + rng.uniform(0, 6)),
            0.03 * H * np.sin(2 * np.pi * 0.9 * t + rng.uniform(0, 6)),
        ],
        axis=1,
    )
    offsets = np.array([W / 2, H / 2]) + drift
    translations, extra = None, {}
    if camera is not None:
        cx, cy = (float(c) for c in camera.principal)
        if not (0 < cx < W and 0 < cy < H):
            cx, cy = W / 2, H / 2
        camera = PerspectiveCamera(camera.distance, float(camera.focal), (cx, cy))
        depth = camera.distance * float(np.sqrt(np.sum(vertices**2, axis=1)).max())
        translations = np.zeros((F, 3))
        translations[:, :2] = drift * depth / camera.focal
        translations[:, 2] = depth
        offsets = camera.project(translations[:, :, None])[:, :, 0]  # the world origin
        s = camera.focal / depth
        extra = dict(intrinsics=camera.intrinsics, depth=depth)
    uv_pix = uv * (texture_size - 1)
    background = (60, 60, 60)
    frames = np.empty((F, H, W, 3), np.uint8)
    id0 = affine0 = None
    for f in range(F):
        t = None if camera is None else translations[f]
        pix, depth = _view(R[f] @ vertices[f], s, offsets[f], camera, t)
        img, ids, affine = _render(
            texture, uv_pix, tris, pix, depth, (H, W), background, pinhole=camera is not None
        )
        if noise:
            img = np.clip(img + rng.normal(0, noise, img.shape), 0, 255).astype(np.uint8)
        frames[f] = img
        if f == 0:
            id0, affine0 = ids, affine
    return SyntheticVideo(
        frames=frames,
        surface=surface,
        uv=uv,
        triangles=tris,
        vertices=vertices,
        rotations=R,
        pixel_scale=float(s),
        offsets=offsets,
        id0=id0,
        affine0=affine0,
        extra=dict(basis=basis, coefficients=coeff, seed=seed, noise=noise, **extra),
        camera=camera,
        translations=translations,
    )


def tracking_errors(video, tracks, swap_px=3.0):
    """Compare tracks with the ground-truth projections of the points they started on.

    Parameters
    ----------
    video : SyntheticVideo
    tracks : data_tools.video.Tracks
        Tracks (a late one is compared from its first frame on); ``tracks.raw``
        (``keep_raw=True``) enables the count of identity swaps caught.
    swap_px : float
        A track more than this many pixels from its true position has swapped identity
        (drifted onto another surface point).

    Returns
    -------
    dict
        ``n_tracks``; ``n_on_surface`` (started on the surface: the others have no ground
        truth); ``error_median``, ``error_mean``, ``error_p95``, ``error_max``: pixel error of
        the kept (non-NaN) observations; ``n_swapped_kept``: tracks still kept while more
        than ``swap_px`` off; with ``raw``: ``n_drift`` (tracks that drift beyond ``swap_px``
        if never stopped), ``n_caught`` (of those, stopped at or before the frame they first
        drift), ``caught_fraction``, ``n_stopped_clean`` (stopped although they never drift).
    """
    gt = video.ground_truth(tracks.tracks)
    ok = gt["valid"]
    err = np.linalg.norm(tracks.tracks - gt["pixels"], axis=1)[:, ok]  # (F, P')
    kept = err[np.isfinite(err)]
    out = dict(
        n_tracks=int(tracks.n_points),
        n_on_surface=int(ok.sum()),
        n_complete=int(tracks.complete.sum()),
        n_complete_on_surface=int((tracks.complete & ok).sum()),
    )
    if kept.size:
        out.update(
            error_median=float(np.median(kept)),
            error_mean=float(kept.mean()),
            error_p95=float(np.percentile(kept, 95)),
            error_max=float(kept.max()),
        )
    out["n_swapped_kept"] = int(np.any(np.nan_to_num(err, nan=0.0) > swap_px, axis=0).sum())
    if tracks.raw is not None:
        raw_err = np.linalg.norm(tracks.raw.astype(float) - gt["pixels"], axis=1)[:, ok]
        drifted = np.nan_to_num(raw_err, nan=np.inf) > swap_px
        has = drifted.any(axis=0)
        first = np.where(has, drifted.argmax(axis=0), video.n_frames)
        lost = tracks.lost_at[ok]
        caught = has & (lost <= first)
        out.update(
            n_drift=int(has.sum()),
            n_caught=int(caught.sum()),
            caught_fraction=float(caught.sum() / has.sum()) if has.any() else 1.0,
            n_stopped_clean=int((~has & (lost < video.n_frames)).sum()),
        )
    return out
