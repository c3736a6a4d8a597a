"""Synthetic deforming sequences with known ground truth (low-rank shape, orthographic camera)."""

from __future__ import annotations

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


def make_synthetic(
    F=120, P=40, K=3, motion="smooth", noise=0.0, deformation=0.4, seed=0, name=None
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

    Returns
    -------
    Sequence
        ``W`` (2F, P) centred; ``shapes`` (F, 3, P) in the camera frame; ``rotations``;
        ``world_shapes``; ``extra`` holds ``basis`` (K, 3, P), ``coefficients`` (F, K) and
        ``W_clean``.
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
    W_clean = cam[:, :2].reshape(2 * F, P)
    W = W_clean.copy()
    if noise:
        W = W + noise * np.mean(np.std(W_clean, axis=1)) * rng.standard_normal(W.shape)
        W -= W.mean(axis=1, keepdims=True)
    return Sequence(
        name=name or f"synthetic-{motion}",
        W=W,
        shapes=cam,
        rotations=R,
        K=K,
        world_shapes=world,
        extra=dict(
            basis=basis, coefficients=coeff, W_clean=W_clean, motion=motion, noise=noise, seed=seed
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
