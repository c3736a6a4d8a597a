"""Loader for the 8-sequence MoCap NRSfM benchmark (Akhter et al. and Torresani et al. files).

The files are not part of this project: they are read from ``data_dir``, which defaults to
``$NRSFM_DATA/mocap``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import scipy.io

from .sequence import Sequence

#: The shape-basis sizes K the organic-priors paper uses (its Table 1).
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
    """Folder holding the ``.mat`` files: ``data_dir`` or ``$NRSFM_DATA/mocap``."""
    if data_dir is not None:
        return Path(data_dir)
    root = os.environ.get("NRSFM_DATA")
    if not root:
        raise FileNotFoundError(
            "no MoCap data folder given: pass data_dir=... or set NRSFM_DATA to the folder "
            "that holds mocap/ (e.g. NRSFM_DATA=../shared/data)")
    return Path(root) / "mocap"


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
        Folder holding ``<name>.mat``. Defaults to ``$NRSFM_DATA/mocap``.

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
        The file is missing; the message says where it looked.
    """
    if name not in MOCAP_K:
        raise ValueError(f"unknown MoCap sequence {name!r}; expected one of {MOCAP_NAMES}")
    folder = mocap_dir(data_dir)
    path = folder / f"{name}.mat"
    if not path.is_file():
        where = f"{folder}" + ("" if folder.is_dir() else " (that folder does not exist)")
        raise FileNotFoundError(f"MoCap file {path.name} not found in {where}")
    mat = scipy.io.loadmat(str(path))
    if name in AKHTER:
        return _load_akhter(name, mat)
    return _load_torresani(name, mat)


def _load_akhter(name, mat):
    W = np.asarray(mat["W"], dtype=float)
    S = _interleaved_to_frames(np.asarray(mat["S"], dtype=float), 3)
    F = W.shape[0] // 2
    if "Rs" in mat:
        rotations = _complete_rotations(_interleaved_to_frames(np.asarray(mat["Rs"], float), 2))
    else:  # dance: fixed camera
        rotations = np.broadcast_to(DANCE_CAMERA, (F, 3, 3)).copy()
    shapes = rotations @ S
    W = W - W.mean(axis=1, keepdims=True)
    edges = None
    if "list" in mat:
        edges = np.asarray(mat["list"], dtype=int) - 1
    return Sequence(name=name, W=W, shapes=shapes, rotations=rotations, K=MOCAP_K[name],
                    edges=edges, world_shapes=S)


def _load_torresani(name, mat):
    P3 = np.asarray(mat["P3_gt"], dtype=float)
    F = P3.shape[0] // 3
    shapes = np.stack([P3[:F], P3[F:2 * F], P3[2 * F:]], axis=1)  # (F, 3, P)
    shapes = shapes - shapes.mean(axis=2, keepdims=True)
    W = shapes[:, :2, :].reshape(2 * F, -1).copy()
    return Sequence(name=name, W=W, shapes=shapes, rotations=None, K=MOCAP_K[name],
                    world_shapes=None)


def load_all(data_dir=None):
    """All 8 sequences as a dict name -> Sequence, in the paper's order."""
    return {n: load_mocap(n, data_dir) for n in MOCAP_NAMES}
