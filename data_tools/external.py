"""Loaders for public real sequences with per-frame 3D ground truth beyond the MoCap set.

The files are not part of this project (see ``docs/validation_data.md`` for where each comes
from and its terms). ``load_external(name, folder)`` reads ``<name>/<file>`` or ``<file>`` in
``folder``, which is the folder that holds ``external/`` or ``external/`` itself (as for the
MoCap files). All of them hold 3D points in the frame of the camera that filmed them
(perspective images); the measurements returned here are the **orthographic** projections
``(X, Y)`` of that ground truth, centred per frame, as the benchmark does for face, walking
and shark. The shipped image tracks are kept in ``extra["image_tracks"]`` (perspective,
pixels or normalised coordinates, not used by the benchmark).

Formats:

``struct``  MATLAB struct arrays of per-frame ground truth ``Pgth(i).P`` (3, P), as in the
            Kinect-based sets of Varol et al. / Chhatkuli et al. (``scene.Pgth`` or a
            top-level ``Pgth``). Points missing (NaN) in any frame are dropped.
``tracks3d`` an array ``track3D`` (3, P, F) with all-zero columns where a point is missing
            (the "back" sequence); only points present in every frame are kept.
"""

from __future__ import annotations

import numpy as np
import scipy.io

from nrsfm.paths import find_data_file
from nrsfm.sequence import Sequence

#: name -> (file, format, suggested K). K is a suggestion for the benchmark (3K must not
#: exceed min(2F, P - 1)); see docs/validation_data.md.
EXTERNAL = {
    "back": ("back_L_3D.mat", "tracks3d", 3),
    "kinect_paper": ("data_kinectPaper.mat", "struct", 2),
    "hulk": ("data_hulk.mat", "struct", 2),
    "tshirt": ("data_whiteCartoonTshirt.mat", "struct", 2),
}


def external_file(name, folder=None):
    """Path of sequence ``name``'s file under ``folder``.

    Parameters
    ----------
    name : str
        A key of :data:`EXTERNAL`.
    folder : str or Path, optional
        The folder that holds ``external/``, or ``external/`` itself (both accepted, as
        for the MoCap files); in it, ``<name>/<file>`` or ``<file>``. Default
        ``$NRSFM_EXTERNAL_DATA``, else ``$NRSFM_DATA``.

    Returns
    -------
    path : Path

    Raises
    ------
    ValueError
        Unknown name.
    FileNotFoundError
        No folder given, or the file is missing (the message names the folders searched).
    """
    if name not in EXTERNAL:
        raise ValueError(f"unknown external sequence {name!r}; expected one of {sorted(EXTERNAL)}")
    file = EXTERNAL[name][0]
    return find_data_file(
        (f"{name}/{file}", file),
        "external",
        folder,
        env=("NRSFM_EXTERNAL_DATA", "NRSFM_DATA"),
        what=f"{file} for {name!r}",
    )


def load_external(name, folder=None, K=None):
    """Load one external sequence as a :class:`Sequence` with camera-frame ground truth.

    Parameters
    ----------
    name : str
        A key of :data:`EXTERNAL`.
    folder : str or Path, optional
        Folder holding ``<name>/<file>`` or ``<file>``; defaults to
        ``$NRSFM_EXTERNAL_DATA``, else ``$NRSFM_DATA``; it may also be the folder that holds
        ``external/`` (see :func:`external_file`).
    K : int, optional
        Overrides the suggested K.

    Returns
    -------
    Sequence
        ``W`` (2F, P) the orthographic projection of the ground truth, rows centred;
        ``shapes`` (F, 3, P) centred per frame; ``rotations`` identity (F, 3, 3);
        ``extra`` with ``file``, ``format`` and ``image_tracks`` when shipped, and
        ``intrinsics`` (3, 3), the camera matrix of those tracks, read from the one
        ``intrinsics_*.txt`` beside the file (with ``intrinsics_file``).

    Raises
    ------
    ValueError
        Unknown name, or a file that does not hold the expected layout.
    FileNotFoundError
        The file is missing.
    """
    path = external_file(name, folder)
    _, fmt, K_default = EXTERNAL[name]
    mat = scipy.io.loadmat(str(path), squeeze_me=True, struct_as_record=False)
    try:
        shapes, tracks = _read_struct(mat) if fmt == "struct" else _read_tracks3d(mat)
    except (KeyError, AttributeError, IndexError, TypeError, ValueError) as exc:
        raise ValueError(
            f"{path} does not hold the {fmt!r} layout expected for {name!r} "
            f"({type(exc).__name__}: {exc})"
        ) from exc
    seq = sequence_from_camera_shapes(name, shapes, K=K or K_default)
    seq.extra.update(file=str(path), format=fmt)
    if tracks is not None:
        seq.extra["image_tracks"] = tracks
    found = sorted(path.parent.glob("intrinsics_*.txt"))
    if tracks is not None and len(found) == 1:  # the camera of the image tracks
        text = found[0].read_text().replace(",", " ").split()
        try:
            seq.extra["intrinsics"] = np.array([float(v) for v in text]).reshape(3, 3)
        except ValueError as exc:
            raise ValueError(f"{found[0]} does not hold a 3 x 3 camera matrix ({exc})") from exc
        seq.extra["intrinsics_file"] = str(found[0])
    return seq


def sequence_from_camera_shapes(name, shapes, K=None):
    """Sequence of camera-frame shapes (F, 3, P) seen by an orthographic identity camera."""
    X = np.asarray(shapes, float)
    if X.ndim != 3 or X.shape[1] != 3:
        raise ValueError(f"shapes must have shape (F, 3, P); got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError("shapes hold non-finite values")
    X = X - X.mean(axis=2, keepdims=True)
    F, _, P = X.shape
    W = X[:, :2].reshape(2 * F, P).copy()
    R = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
    return Sequence(name=name, W=W, shapes=X, rotations=R, K=K, world_shapes=X.copy())


def _read_struct(mat):
    """(F, 3, P) shapes and (F, 2, P) image tracks (or None) from ``Pgth`` struct arrays."""
    src = mat["scene"] if "scene" in mat else mat
    get = (lambda k: getattr(src, k)) if "scene" in mat else (lambda k: src[k])
    frames = np.atleast_1d(get("Pgth"))
    shapes = np.stack([np.asarray(fr.P, float) for fr in frames])
    if shapes.ndim != 3 or shapes.shape[1] != 3:
        raise ValueError(f"Pgth frames must be (3, P); got stack {shapes.shape}")
    keep = np.all(np.isfinite(shapes), axis=(0, 1))
    tracks = None
    for key in ("p", "m"):
        try:
            items = np.atleast_1d(get(key))
        except (KeyError, AttributeError):
            continue
        arrs = [np.asarray(getattr(it, key) if hasattr(it, key) else it, float)[:2] for it in items]
        if len(arrs) == len(shapes) and all(a.shape == (2, shapes.shape[2]) for a in arrs):
            tracks = np.stack(arrs)[:, :, keep]
            break
    return shapes[:, :, keep], tracks


def _read_tracks3d(mat):
    """(F, 3, P) shapes of the points present in every frame, and (F, 2, P) image tracks."""
    T = np.asarray(mat["track3D"], float)
    if T.ndim != 3 or T.shape[0] != 3:
        raise ValueError(f"track3D must have shape (3, P, F); got {T.shape}")
    keep = ~np.all(T == 0, axis=0).any(axis=1)
    if keep.sum() < 4:
        raise ValueError(f"only {int(keep.sum())} points are present in every frame")
    shapes = T[:, keep].transpose(2, 0, 1)
    tracks = None
    if "L_tracks" in mat and np.shape(mat["L_tracks"])[:2] == (2, T.shape[1]):
        tracks = np.asarray(mat["L_tracks"], float)[:, keep].transpose(2, 0, 1)
    return shapes, tracks
