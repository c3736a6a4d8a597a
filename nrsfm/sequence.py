"""The sequence type: 2D tracks with optional 3D ground truth (built by the loaders and
generators of :mod:`data_tools`, read by the views and the CLI)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Sequence:
    """A 2D track sequence with optional 3D ground truth.

    Attributes
    ----------
    name : str
    W : (2F, P) ndarray
        Measurement matrix, rows ``x_f, y_f`` interleaved, each row mean-centred.
    shapes : (F, 3, P) ndarray or None
        Ground-truth shape of every frame in the camera frame, centred per frame
        (``W[2f:2f+2] == shapes[f, :2]`` for an orthographic camera).
    rotations : (F, 3, 3) ndarray or None
        Ground-truth camera rotations (world to camera), where the data defines them.
    K : int or None
        Number of shape bases (the paper's K for benchmark sequences).
    edges : (E, 2) int ndarray or None
        0-based skeleton point pairs, for drawing.
    world_shapes : (F, 3, P) ndarray or None
        Ground truth in the world frame (``shapes[f] = rotations[f] @ world_shapes[f]``).
    extra : dict
        Anything else the source provides (basis shapes, coefficients, ...).
    """

    name: str
    W: np.ndarray
    shapes: np.ndarray | None = None
    rotations: np.ndarray | None = None
    K: int | None = None
    edges: np.ndarray | None = None
    world_shapes: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return self.W.shape[0] // 2

    @property
    def n_points(self) -> int:
        return self.W.shape[1]

    @property
    def tracks(self) -> np.ndarray:
        """(F, 2, P) view of ``W``."""
        return self.W.reshape(self.n_frames, 2, self.n_points)

    def __repr__(self) -> str:  # short: the arrays are large
        gt = "shapes" if self.shapes is not None else "no shapes"
        rot = "rotations" if self.rotations is not None else "no rotations"
        F, P = self.n_frames, self.n_points
        return f"Sequence(name={self.name!r}, F={F}, P={P}, K={self.K}, {gt}, {rot})"
