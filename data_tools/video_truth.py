"""A synthetic video on disk, with its ground truth, and the score of a reconstruction of
its tracks: the route from :func:`data_tools.make_video` to ``nrsfm video`` and back.

:func:`write_video` writes the frames as PNG images (lossless: ``nrsfm video FOLDER`` tracks
exactly the frames :func:`~data_tools.make_video` rendered) and :func:`save_ground_truth`
the mesh, its motion and the camera (orthographic or pinhole), from which the true 3D of
*any* track can be found (:meth:`SyntheticVideo.ground_truth`: a track is located on the
mesh in its first frame).
:func:`load_ground_truth` reads it back as a :class:`SyntheticVideo` without frames, and
:func:`score_tracks` scores a reconstruction of tracks against it, on the tracks the
reconstruction used that started on the surface (the others have no ground truth).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nrsfm.io import load_npz, save_npz

from .synthetic import PerspectiveCamera
from .synthetic_video import SyntheticVideo

__all__ = [
    "GROUND_TRUTH_FORMAT",
    "write_video",
    "save_ground_truth",
    "load_ground_truth",
    "score_tracks",
]

#: The ``format`` array of a ground-truth file, checked on reading.
GROUND_TRUTH_FORMAT = "nrsfm synthetic video ground truth v1"

_ARRAYS = ("uv", "triangles", "vertices", "rotations", "pixel_scale", "offsets", "id0", "affine0")
_EXPECTED = "a synthetic-video ground truth written by data_tools.save_ground_truth"


def write_video(video, folder):
    """Write a synthetic video's frames and ground truth into ``folder``.

    Parameters
    ----------
    video : SyntheticVideo
        With its frames (from :func:`data_tools.make_video`).
    folder : str or os.PathLike
        Created if absent; receives ``frames/000000.png ...`` and ``ground_truth.npz``.

    Returns
    -------
    frames : Path
        The folder of PNG frames (what ``nrsfm video`` reads).
    truth : Path
        The ground-truth file (what ``nrsfm video --ground-truth`` reads).

    Raises
    ------
    ValueError
        ``video`` has no frames.
    OSError
        A file cannot be written.
    """
    import cv2

    if video.frames is None:
        raise ValueError(
            "this SyntheticVideo has no frames (loaded from a ground-truth "
            "file?); render one with data_tools.make_video"
        )
    frames = Path(folder) / "frames"
    frames.mkdir(parents=True, exist_ok=True)
    for old in frames.glob("*.png"):  # a shorter video must not keep old frames
        old.unlink()
    for f, img in enumerate(video.frames):
        path = frames / f"{f:06d}.png"
        if not cv2.imwrite(str(path), img):
            raise OSError(f"cannot write the frame {path}")
    return frames, save_ground_truth(video, Path(folder) / "ground_truth.npz")


def save_ground_truth(video, path):
    """Write what :meth:`SyntheticVideo.ground_truth` needs (no frames) to ``path``.

    Parameters
    ----------
    video : SyntheticVideo
    path : str or os.PathLike
        The ``.npz`` file, written exactly there, atomically.

    Returns
    -------
    path : Path
    """
    arrays = {k: np.asarray(getattr(video, k)) for k in _ARRAYS}
    if video.camera is not None:  # a pinhole camera: (distance, focal, cx, cy), t_f
        c = video.camera
        arrays["pinhole"] = np.array([c.distance, c.focal, *c.principal], float)
        arrays["translations"] = np.asarray(video.translations, float)
    extra = {
        f"extra_{k}": np.asarray(v)
        for k, v in video.extra.items()
        if isinstance(v, (np.ndarray, int, float, np.number))
    }
    return save_npz(
        path,
        format=np.array(GROUND_TRUTH_FORMAT),
        surface=np.array(video.surface),
        **arrays,
        **extra,
    )


def load_ground_truth(path):
    """Read a file written by :func:`save_ground_truth`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    video : SyntheticVideo
        With ``frames=None``: everything :meth:`~SyntheticVideo.ground_truth`,
        :meth:`~SyntheticVideo.sequence` and :func:`score_tracks` need.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not an ``.npz`` (:func:`nrsfm.io.load_npz`), or not a ground-truth file: the
        message names the file and what is missing or inconsistent.
    """
    data = load_npz(path, "ground truth", _EXPECTED)
    fmt = data.get("format")
    if fmt is None or fmt.shape != () or str(fmt) != GROUND_TRUTH_FORMAT:
        raise ValueError(
            f"ground truth {path} has no format {GROUND_TRUTH_FORMAT!r} "
            f"(found arrays: {sorted(data)}); expected {_EXPECTED}"
        )
    missing = [k for k in _ARRAYS + ("surface",) if k not in data]
    if missing:
        raise ValueError(f"ground truth {path} lacks the arrays {missing}")
    V, F = data["vertices"], data["rotations"]
    if (
        V.ndim != 3
        or V.shape[1] != 3
        or F.shape != (V.shape[0], 3, 3)
        or data["offsets"].shape != (V.shape[0], 2)
        or data["id0"].ndim != 2
    ):
        raise ValueError(
            f"ground truth {path}: inconsistent shapes (vertices {V.shape}, "
            f"rotations {F.shape}, offsets {data['offsets'].shape}, id0 "
            f"{data['id0'].shape})"
        )
    extra = {k[len("extra_") :]: v for k, v in data.items() if k.startswith("extra_")}
    camera = translations = None
    if "pinhole" in data or "translations" in data:
        pin, translations = data.get("pinhole"), data.get("translations")
        if (
            pin is None
            or translations is None
            or pin.shape != (4,)
            or translations.shape != (V.shape[0], 3)
        ):
            raise ValueError(
                f"ground truth {path}: a pinhole camera needs 'pinhole' (4,) and "
                f"'translations' ({V.shape[0]}, 3); found "
                f"{None if pin is None else pin.shape} and "
                f"{None if translations is None else translations.shape}"
            )
        camera = PerspectiveCamera(float(pin[0]), float(pin[1]), (float(pin[2]), float(pin[3])))
    return SyntheticVideo(
        frames=None,
        surface=str(data["surface"]),
        uv=data["uv"],
        triangles=data["triangles"],
        vertices=V,
        rotations=F,
        pixel_scale=float(data["pixel_scale"]),
        offsets=data["offsets"],
        id0=data["id0"],
        affine0=data["affine0"],
        extra=extra,
        camera=camera,
        translations=translations,
    )


def score_tracks(truth, tracks, vr):
    """Errors of a reconstruction of tracks against a synthetic video's ground truth.

    Parameters
    ----------
    truth : SyntheticVideo
        From :func:`data_tools.make_video` or :func:`load_ground_truth`.
    tracks : (F, 2, P) or (2F, P) ndarray, or data_tools.video.Tracks
        Every track given to the reconstruction (pixels, NaN where not observed).
    vr : nrsfm.tracks.VideoReconstruction
        :func:`nrsfm.tracks.reconstruct_tracks` of those tracks.

    Returns
    -------
    dict
        ``n_tracks``, ``n_used`` (tracks in the reconstruction), ``n_scored`` (of those,
        the ones that started on the surface), ``e3d``, ``e3d_akhter`` and ``e_R`` over the
        scored tracks, computed as :meth:`nrsfm.Reconstruction.errors` computes them (the
        cameras move: world-frame shapes for ``e3d_akhter``). With a pinhole camera the
        truth is metric (world units): ``e3d`` ignores the scale, ``e3d_akhter`` does not
        (it expects the reconstruction in the truth's units).

    Raises
    ------
    ValueError
        The tracks and the ground truth differ in frames, or fewer than 3 used tracks
        have ground truth.
    """
    from nrsfm.metrics import e3d, e3d_akhter, rotation_error

    T = np.asarray(getattr(tracks, "tracks", tracks), float)
    if T.ndim == 2:
        T = T.reshape(T.shape[0] // 2, 2, T.shape[1])
    if T.shape[0] != truth.n_frames:
        raise ValueError(
            f"the tracks have {T.shape[0]} frames but the ground truth {truth.n_frames}"
        )
    gt = truth.ground_truth(T)
    cols = np.flatnonzero(vr.used)
    scored = cols[gt["valid"][cols]]
    if scored.size < 3:
        raise ValueError(
            f"only {scored.size} of the {cols.size} used tracks have ground "
            "truth (started on the surface); at least 3 are needed"
        )
    X = vr.result.shapes[:, :, gt["valid"][cols]]
    if truth.camera is None:
        G = truth.pixel_scale * gt["camera"][:, :, scored]
        world = truth.rotations.transpose(0, 2, 1) @ G  # as Reconstruction.errors
    else:  # metric camera-frame points; the world frame without the translations
        G, world = gt["camera"][:, :, scored], gt["world"][:, :, scored]
    return dict(
        n_tracks=int(T.shape[2]),
        n_used=int(cols.size),
        n_scored=int(scored.size),
        e3d=e3d(X, G),
        e3d_akhter=e3d_akhter(X, world),
        e_R=rotation_error(vr.result.rotations, truth.rotations),
    )
