"""Loader for the 8-sequence MoCap NRSfM benchmark (Akhter et al. and Torresani et al. files).

The files are not part of this project: they are read from ``data_dir`` (default
``$NRSFM_DATA``), the folder that holds ``mocap/`` or ``mocap/`` itself, both accepted (a
relative path resolves against the folder the user started in; see
:func:`nrsfm.paths.find_data_file`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.io

from nrsfm import paths
from nrsfm.sequence import Sequence

#: The shape-basis sizes K the organic-priors paper uses (its Table 2).
MOCAP_K = {
    "drink": 12,
    "pickup": 12,
    "yoga": 10,
    "stretch": 11,
    "dance": 4,
    "face": 7,
    "walking": 8,
    "shark": 3,
}

#: Dai et al.'s own K (BMM), which differs on dance and shark.
DAI_K = dict(MOCAP_K, dance=10, shark=4)

AKHTER = ("drink", "pickup", "stretch", "yoga", "dance")
TORRESANI = ("face", "walking", "shark")
MOCAP_NAMES = ("drink", "pickup", "yoga", "stretch", "dance", "face", "walking", "shark")

#: Dance is seen by the fixed camera [[0, 1, 0], [0, 0, 1]]; completed with r1 x r2.
DANCE_CAMERA = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def mocap_dir(data_dir=None) -> Path:
    """Folder holding the ``.mat`` files (:func:`nrsfm.paths.mocap_dir`).

    Parameters
    ----------
    data_dir : str or Path, optional
        The folder that holds ``mocap/``, or ``mocap/`` itself; default ``$NRSFM_DATA``.

    Returns
    -------
    folder : Path
        ``data_dir/mocap`` when that folder exists, else ``data_dir``.

    Raises
    ------
    FileNotFoundError
        Neither ``data_dir`` nor ``$NRSFM_DATA`` is given.
    """
    return paths.mocap_dir(data_dir)


def _interleaved_to_frames(A, rows):
    """(rows*F, P) interleaved per frame -> (F, rows, P)."""
    F = A.shape[0] // rows
    return A.reshape(F, rows, A.shape[1])


def _complete_rotations(Rs):
    """(F, 2, 3) orthographic cameras -> (F, 3, 3) rotations with r3 = r1 x r2."""
    r3 = np.cross(Rs[:, 0], Rs[:, 1])
    return np.concatenate([Rs, r3[:, None, :]], axis=1)


def load_mocap(name: str, data_dir=None) -> Sequence:
    """Load one MoCap benchmark sequence.

    Parameters
    ----------
    name : str
        One of ``drink, pickup, yoga, stretch, dance, face, walking, shark``.
    data_dir : str or Path, optional
        The folder that holds ``mocap/<name>.mat``, or ``mocap/`` itself (both accepted);
        default ``$NRSFM_DATA`` (either form too).

    Returns
    -------
    seq : Sequence
        ``W`` (2F, P) row-centred; ``shapes`` (F, 3, P) ground truth in the camera frame,
        centred per frame; ``rotations`` (F, 3, 3) for the Akhter sequences (dance: its
        fixed camera), None for face, walking and shark (their motion is inside the
        shape); ``K`` the paper's K; ``edges`` the skeleton where the file has one.

    Raises
    ------
    ValueError
        Unknown name.
    FileNotFoundError
        No folder given, or the file is missing; the message names the folders searched
        and the folder to give.
    """
    if name not in MOCAP_K:
        raise ValueError(f"unknown MoCap sequence {name!r}; expected one of {MOCAP_NAMES}")
    path = paths.find_data_file(f"{name}.mat", "mocap", data_dir, what=f"MoCap file {name}.mat")
    try:
        mat = scipy.io.loadmat(str(path))
    except Exception as exc:  # MatReadError, ValueError, OSError, zlib errors, ...
        raise ValueError(
            f"cannot read {path}: not a valid .mat file ({type(exc).__name__}: {_one_line(exc)})"
        ) from exc
    try:
        load = _load_akhter if name in AKHTER else _load_torresani
        seq = load(name, mat, MOCAP_K[name])
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        layout = "Akhter et al. (W, S, Rs)" if name in AKHTER else "Torresani et al. (P3_gt)"
        raise ValueError(
            f"{path} does not hold the {layout} layout expected for {name} "
            f"({type(exc).__name__}: {_one_line(exc)})"
        ) from exc
    if not (np.all(np.isfinite(seq.W)) and np.all(np.isfinite(seq.shapes))):
        raise ValueError(f"{path} holds non-finite values")
    return seq


def _one_line(exc):
    text = " ".join(str(exc).split())
    return text[:200] if text else "no message"


def load_mat(path):
    """Any ``.mat`` file of measurements: the benchmark's layouts (Akhter et al.: ``W``,
    ``S`` and ``Rs`` where the camera moves; Torresani et al.: ``P3_gt``) with their ground
    truth, or a file with a ``W`` (2F, P) (and optionally ``K``) alone.

    Returns
    -------
    Sequence
        ``K`` from the file's ``K`` where it has one, else None; ``shapes`` and
        ``rotations`` where the layout holds them.

    Raises
    ------
    ValueError
        Not a readable MATLAB file, or none of the layouts (the arrays found are named).
    """
    path = Path(path)
    try:
        mat = scipy.io.loadmat(str(path))
    except Exception as exc:  # MatReadError, ValueError, OSError, zlib errors, ...
        raise ValueError(f"cannot read {path}: not a valid .mat file ({_one_line(exc)})") from exc
    K = mat.get("K")
    K = int(np.asarray(K).ravel()[0]) if K is not None and np.size(K) == 1 else None
    arrays = sorted(k for k in mat if not k.startswith("__"))
    try:
        if "P3_gt" in mat and "W" not in mat:
            return _load_torresani(path.stem, mat, K)
        if "W" in mat and "S" in mat:
            return _load_akhter(path.stem, mat, K)
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise ValueError(f"{path}: {_one_line(exc)}") from exc
    if "W" not in mat:
        raise ValueError(f"{path} has no array 'W' nor a benchmark layout (found: {arrays})")
    return Sequence(name=path.stem, W=np.asarray(mat["W"]), K=K)


def _load_akhter(name, mat, K):
    W = np.asarray(mat["W"], dtype=float)
    S_raw = np.asarray(mat["S"], dtype=float)
    if W.ndim != 2 or W.shape[0] % 2 or W.shape[0] == 0:
        raise ValueError(f"W has shape {W.shape}, expected (2F, P)")
    F, P = W.shape[0] // 2, W.shape[1]
    if S_raw.shape != (3 * F, P):
        raise ValueError(f"S has shape {S_raw.shape}, expected (3F, P) = {(3 * F, P)}")
    S = _interleaved_to_frames(S_raw, 3)
    if "Rs" in mat:
        Rs = np.asarray(mat["Rs"], float)
        if Rs.shape != (2 * F, 3):
            raise ValueError(f"Rs has shape {Rs.shape}, expected (2F, 3) = {(2 * F, 3)}")
        rotations = _complete_rotations(_interleaved_to_frames(Rs, 2))
    else:  # dance: fixed camera
        rotations = np.broadcast_to(DANCE_CAMERA, (F, 3, 3)).copy()
    shapes = rotations @ S
    W = W - W.mean(axis=1, keepdims=True)
    edges = None
    if "list" in mat:
        edges = np.asarray(mat["list"], dtype=int) - 1
    return Sequence(
        name=name,
        W=W,
        shapes=shapes,
        rotations=rotations,
        K=K,
        edges=edges,
        world_shapes=S,
    )


def _load_torresani(name, mat, K):
    P3 = np.asarray(mat["P3_gt"], dtype=float)
    if P3.ndim != 2 or P3.shape[0] % 3 or P3.shape[0] == 0:
        raise ValueError(f"P3_gt has shape {P3.shape}, expected (3F, P)")
    F = P3.shape[0] // 3
    shapes = np.stack([P3[:F], P3[F : 2 * F], P3[2 * F :]], axis=1)  # (F, 3, P)
    shapes = shapes - shapes.mean(axis=2, keepdims=True)
    W = shapes[:, :2, :].reshape(2 * F, -1).copy()
    return Sequence(name=name, W=W, shapes=shapes, rotations=None, K=K, world_shapes=None)


def load_all(data_dir=None):
    """All 8 sequences as a dict name -> Sequence, in the paper's order.

    Parameters
    ----------
    data_dir : str or Path, optional
        As for :func:`load_mocap`.

    Returns
    -------
    dict
    """
    return {n: load_mocap(n, data_dir) for n in MOCAP_NAMES}
