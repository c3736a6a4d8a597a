"""Synthetic deforming sequences with known ground truth (low-rank shape; an orthographic
camera, or a pinhole camera at a given distance)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from nrsfm.sequence import Sequence

MOTIONS = ("smooth", "fast", "static", "random")


def camera_rotations(F, motion="smooth", rng=None):
    """Camera rotation trajectory of F frames.

    Parameters
    ----------
    F : int
    motion : {"smooth", "fast", "static", "random"}
        ``smooth``: about 5 degrees per frame about a slowly wobbling axis (like the Akhter
        sequences); ``fast``: about 25 degrees per frame; ``static``: a fixed view with
        0.2-degree jitter; ``random``: an independent uniformly random rotation per frame.
    rng : numpy.random.Generator

    Returns
    -------
    R : (F, 3, 3) ndarray
    """
    rng = np.random.default_rng(rng)
    if motion not in MOTIONS:
        raise ValueError(f"unknown motion {motion!r}; expected one of {MOTIONS}")
    start = Rotation.random(random_state=rng)
    if motion == "random":
        return Rotation.random(F, random_state=rng).as_matrix()
    if motion == "static":
        jitter = Rotation.from_rotvec(np.deg2rad(0.2) * rng.standard_normal((F, 3)))
        return (jitter * start).as_matrix()
    step = {"smooth": 5.0, "fast": 25.0}[motion]
    t = np.arange(F)
    phase = rng.uniform(0, 2 * np.pi, 2)
    axis = np.stack(
        [
            0.3 * np.sin(2 * np.pi * t / 97 + phase[0]),
            np.ones(F),
            0.3 * np.cos(2 * np.pi * t / 61 + phase[1]),
        ],
        axis=1,
    )
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    steps = Rotation.from_rotvec(np.deg2rad(step) * axis)
    out = [start]
    for f in range(1, F):
        out.append(steps[f] * out[-1])
    return Rotation.concatenate(out).as_matrix()


@dataclass(frozen=True)
class PerspectiveCamera:
    """A pinhole camera for :func:`make_synthetic`.

    Attributes
    ----------
    distance : float
        Distance from the camera centre to the shapes' centroid, in units of the shapes'
        radius (the largest distance of a point from the centroid over all frames), so above
        1 every point is in front of the camera; at 50 the view is close to orthographic, at
        2 to 5 strongly perspective.
    focal : float
        Focal length in pixels.
    principal : (float, float)
        Principal point (x, y) in pixels.

    Raises
    ------
    ValueError
        ``distance`` not above 1, ``focal`` not positive, ``principal`` not two numbers.

    Examples
    --------
    >>> PerspectiveCamera(distance=3.0, focal=800.0).intrinsics[0]
    array([800.,   0., 320.])
    """

    distance: float = 3.0
    focal: float = 800.0
    principal: tuple = (320.0, 240.0)

    def __post_init__(self):
        if not (np.isfinite(self.distance) and self.distance > 1):
            raise ValueError(f"distance must be above 1 (object radii); got {self.distance!r}")
        if not (np.isfinite(self.focal) and self.focal > 0):
            raise ValueError(f"focal must be positive (pixels); got {self.focal!r}")
        if np.shape(self.principal) != (2,) or not np.all(np.isfinite(self.principal)):
            raise ValueError(f"principal must be two numbers (x, y); got {self.principal!r}")

    @property
    def intrinsics(self):
        """(3, 3) ndarray: the camera matrix ``[[f, 0, cx], [0, f, cy], [0, 0, 1]]``."""
        (cx, cy), f = self.principal, float(self.focal)
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    def project(self, X_cam):
        """Pixels (F, 2, P) of camera-frame points (F, 3, P) whose depths are positive."""
        uv = X_cam[:, :2] / X_cam[:, 2:3]
        return self.focal * uv + np.asarray(self.principal, float)[None, :, None]


def make_synthetic(
    F=120,
    P=40,
    K=3,
    motion="smooth",
    noise=0.0,
    deformation=0.4,
    seed=0,
    name=None,
    camera=None,
):
    """A seeded synthetic NRSfM sequence with ground truth.

    Shapes are ``X_f = sum_k c_fk B_k`` (Eq. 1): a rigid mean shape ``B_1`` (coefficient
    near 1) plus K - 1 deformation modes with smooth coefficients, seen by an orthographic
    camera ``R_f``.

    Parameters
    ----------
    F, P, K : int
        Frames, points, shape bases (``3K <= min(2F, P)``).
    motion : {"smooth", "fast", "static", "random"}
        Camera trajectory, see :func:`camera_rotations`.
    noise : float
        Gaussian noise added to W, as a fraction of W's mean row standard deviation.
    deformation : float
        Size of the deformation modes relative to the mean shape.
    seed : int
    camera : PerspectiveCamera or None
        None: an orthographic camera (W centred, in the shapes' units). A
        :class:`PerspectiveCamera`: the shapes seen by a pinhole camera at its distance, W in
        pixels (not centred; the same draws of shapes and rotations as without it).

    Returns
    -------
    Sequence
        ``W`` (2F, P); ``shapes`` (F, 3, P) in the camera frame (centred); ``rotations``;
        ``world_shapes``; ``extra`` holds ``basis`` (K, 3, P), ``coefficients`` (F, K),
        ``W_clean``, and with a camera ``intrinsics`` (3, 3) and ``depth`` (the centroid's
        distance in the shapes' units).

    Raises
    ------
    ValueError
        ``3K > min(2F, P)``.
    """
    if 3 * K > min(2 * F, P):
        raise ValueError(f"K={K} too large for F={F}, P={P}: need 3K <= min(2F, P)")
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((K, 3, P)) * np.array([1.0, 0.8, 0.6])[:, None]
    basis[1:] *= deformation
    basis -= basis.mean(axis=2, keepdims=True)
    t = np.arange(F)[:, None]
    freq = rng.uniform(0.5, 2.5, (1, K)) * 2 * np.pi / max(F, 2)
    phase = rng.uniform(0, 2 * np.pi, (1, K))
    coeff = np.sin(freq * t * 3 + phase)
    coeff[:, 0] = 1.0 + 0.1 * coeff[:, 0]
    world = np.einsum("fk,kip->fip", coeff, basis)
    R = camera_rotations(F, motion, rng)
    cam = R @ world
    extra = {}
    if camera is None:
        W_clean = cam[:, :2].reshape(2 * F, P)
    else:
        depth = camera.distance * float(np.sqrt(np.sum(world**2, axis=1)).max())
        X = cam + np.array([0.0, 0.0, depth])[None, :, None]
        W_clean = camera.project(X).reshape(2 * F, P)
        extra = dict(intrinsics=camera.intrinsics, depth=depth, camera=camera)
    W = W_clean.copy()
    if noise:
        W = W + noise * np.mean(np.std(W_clean, axis=1)) * rng.standard_normal(W.shape)
        if camera is None:
            W -= W.mean(axis=1, keepdims=True)
    return Sequence(
        name=name or f"synthetic-{motion}",
        W=W,
        shapes=cam,
        rotations=R,
        K=K,
        world_shapes=world,
        extra=dict(
            basis=basis,
            coefficients=coeff,
            W_clean=W_clean,
            motion=motion,
            noise=noise,
            seed=seed,
            **extra,
        ),
    )


def make_rank_deficient(F=80, P=30, motion="smooth", seed=0, name=None):
    """A rigid body plus one planar deformation: ``X_f = S_0 + b_f S_1`` with ``S_1`` in the
    plane z = 0 of the world, so that W has rank 3 + 2 = 5, below 3K for K = 2 (the true
    K) and above.

    Parameters
    ----------
    F, P : int
    motion : {"smooth", "fast", "static", "random"}
        Camera trajectory, see :func:`camera_rotations`.
    seed : int

    Returns
    -------
    Sequence
        ``K`` = 2, ``W`` (2F, P) centred, ``shapes`` (camera frame), ``rotations``,
        ``world_shapes``.
    """
    rng = np.random.default_rng(seed)
    S0 = rng.standard_normal((3, P))
    S1 = np.zeros((3, P))
    S1[:2] = 0.5 * rng.standard_normal((2, P))
    S0 -= S0.mean(axis=1, keepdims=True)
    S1 -= S1.mean(axis=1, keepdims=True)
    b = np.sin(np.linspace(0, 3 * np.pi, F) + rng.uniform(0, 2 * np.pi))
    world = S0[None] + b[:, None, None] * S1[None]
    R = camera_rotations(F, motion, rng)
    cam = R @ world
    return Sequence(
        name=name or f"rigid-planar-{motion}",
        W=cam[:, :2].reshape(2 * F, P),
        shapes=cam,
        rotations=R,
        K=2,
        world_shapes=world,
        extra=dict(motion=motion, seed=seed),
    )


def default_sequence():
    """The built-in input of ``nrsfm demo``: 150 frames, 45 points, K = 3, smooth camera."""
    return make_synthetic(
        F=150, P=45, K=3, motion="smooth", noise=0.0, seed=7, name="synthetic-demo"
    )
