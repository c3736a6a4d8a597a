"""Validation data: ground-truth shapes re-projected by new orthographic camera paths.

A sequence with 3D ground truth fixes the shapes; the camera path is a free choice of the
benchmark that recorded it. Re-projecting the world-frame shapes ``S_f`` by other cameras
``R_f`` gives new measurement matrices with known answers:

    W_f = [R_f S_f]_{rows 1, 2}        (orthographic camera, rows centred per frame)

Camera paths are callables ``path(F, seed) -> (F, 3, 3)`` (world to camera):

``smooth(turn)``  rotation vector ``[a t, 0.4 sin 3t, 0.3 cos 2t]``, ``t = linspace(0, 1, F)``,
                  with ``a`` chosen so that the path turns ``turn`` degrees: the largest
                  angle between the first camera and any later one. ``a = 1`` turns 62.1
                  degrees; the Akhter MoCap paths turn 180.
``fast(step)``    a random walk: each camera is the previous one turned by ``step`` degrees
                  (default 40) about a uniformly drawn axis.
``random()``      independent uniformly distributed (Haar) rotations per frame.
``original``      the sequence's own cameras (reproduces its W).

Noise: ``data_tools.add_noise`` (Gaussian, std ``noise`` x the mean row std of the
noise-free W, rows re-centred), the convention of the project's noise study; seeded.
"""

from __future__ import annotations

import zlib

import numpy as np

from .noise import add_noise
from nrsfm.sequence import Sequence


def _skew(v):
    """(..., 3) vectors -> (..., 3, 3) cross-product matrices."""
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack(
        [np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def rotvec_to_matrix(v):
    """Rodrigues' formula: (..., 3) rotation vectors (radians) -> (..., 3, 3) rotations."""
    v = np.asarray(v, float)
    theta = np.linalg.norm(v, axis=-1)[..., None, None]
    Kx = _skew(v)
    small = theta < 1e-8
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta**2 / 24, (1 - np.cos(t)) / t**2)
    return np.eye(3) + a * Kx + b * (Kx @ Kx)


def rotation_angle(R):
    """(..., 3, 3) rotations -> (...) angles in degrees (accurate near 0 and 180)."""
    R = np.asarray(R, float)
    s = 0.5 * np.linalg.norm(
        np.stack(
            [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
            -1,
        ),
        axis=-1,
    )
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    return np.degrees(np.arctan2(s, c))


def path_turn(R):
    """Turn of a camera path (F, 3, 3): the largest angle (degrees) from the first camera."""
    R = np.asarray(R, float)
    return float(rotation_angle(np.einsum("ji,fjk->fik", R[0], R)).max())


def _smooth_rotations(F, a):
    t = np.linspace(0.0, 1.0, F)
    return rotvec_to_matrix(np.stack([a * t, 0.4 * np.sin(3 * t), 0.3 * np.cos(2 * t)], -1))


def smooth(turn=62.0):
    """Smooth path turning ``turn`` degrees (0 < turn <= 180); see the module docstring.

    Returns
    -------
    path : callable ``(F, seed) -> (F, 3, 3)``; deterministic (the seed is not used).
    """
    turn = float(turn)
    if not 0 < turn <= 180:
        raise ValueError(f"turn must be in (0, 180] degrees; got {turn}")

    target = min(turn, 180.0 - 1e-6)  # the angle to the first camera is at most 180

    def path(F, seed=0):
        lo, hi = 0.0, 1.0
        while path_turn(_smooth_rotations(F, hi)) < target and hi < 64:
            lo, hi = hi, 2 * hi
        for _ in range(60):  # bisection on a: the smallest a reaching the turn
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if path_turn(_smooth_rotations(F, mid)) < target else (lo, mid)
        return _smooth_rotations(F, hi)

    path.__name__ = f"smooth{turn:g}"
    return path


def _random_axes(rng, n):
    u = rng.standard_normal((n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def fast(step=40.0):
    """Random walk of ``step`` degrees per frame about uniformly drawn axes.

    Returns
    -------
    path : callable ``(F, seed) -> (F, 3, 3)``.
    """
    step = float(step)
    if not 0 < step <= 180:
        raise ValueError(f"step must be in (0, 180] degrees; got {step}")

    def path(F, seed=0):
        rng = np.random.default_rng(seed)
        turns = rotvec_to_matrix(np.radians(step) * _random_axes(rng, F))
        R = np.empty((F, 3, 3))
        R[0] = rotvec_to_matrix(np.pi * rng.random() * _random_axes(rng, 1))[0]
        for f in range(1, F):
            R[f] = turns[f] @ R[f - 1]
        return R

    path.__name__ = f"fast{step:g}"
    return path


def random():
    """Independent uniform (Haar) rotations, one per frame (unit quaternions from normals).

    Returns
    -------
    path : callable ``(F, seed) -> (F, 3, 3)``.
    """

    def path(F, seed=0):
        q = np.random.default_rng(seed).standard_normal((F, 4))
        w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
        return np.stack(
            [
                np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
            ],
            -2,
        )

    path.__name__ = "random"
    return path


def world_shapes(seq):
    """Ground truth of ``seq`` in its world frame, (F, 3, P), centred per frame.

    ``seq.world_shapes`` when given; else ``R_f' X_f`` from the camera-frame shapes and
    rotations; else (no rotations: face, walking, shark) the camera-frame shapes, the
    camera being the identity.
    """
    if seq.shapes is None and seq.world_shapes is None:
        raise ValueError(f"sequence {seq.name!r} has no 3D ground truth")
    if seq.world_shapes is not None:
        S = np.asarray(seq.world_shapes, float)
    elif seq.rotations is not None:
        S = np.einsum("fji,fjp->fip", np.asarray(seq.rotations, float), seq.shapes)
    else:
        S = np.asarray(seq.shapes, float)
    return S - S.mean(axis=2, keepdims=True)


def project(S, R):
    """Orthographic projection of world shapes S (F, 3, P) by cameras R (F, 3, 3).

    Returns
    -------
    W : (2F, P) ndarray, rows ``x_f, y_f`` interleaved and centred.
    X : (F, 3, P) ndarray, camera-frame shapes ``R_f S_f`` centred per frame.
    """
    S, R = np.asarray(S, float), np.asarray(R, float)
    if S.ndim != 3 or S.shape[1] != 3:
        raise ValueError(f"world shapes must have shape (F, 3, P); got {S.shape}")
    if R.shape != (S.shape[0], 3, 3):
        raise ValueError(
            f"rotations must have shape (F, 3, 3) = {(S.shape[0], 3, 3)}; got {R.shape}"
        )
    X = R @ (S - S.mean(axis=2, keepdims=True))
    return X[:, :2].reshape(2 * S.shape[0], S.shape[2]).copy(), X


def reproject(seq, path="original", noise=0.0, seed=0, name=None, noise_seed=None):
    """``seq``'s ground-truth shapes seen by a new orthographic camera path.

    Parameters
    ----------
    seq : Sequence
        With 3D ground truth (see :func:`world_shapes`).
    path : "original", callable ``(F, seed) -> (F, 3, 3)``, or (F, 3, 3) array_like
        Camera rotations (world to camera). ``"original"``: ``seq.rotations`` (the identity
        where the sequence has none).
    noise : float
        Noise std as a fraction of the mean row std of the noise-free W, ``>= 0``.
    seed : int
        Seeds the path (and the noise, unless ``noise_seed`` is given).
    name : str, optional
        Name of the result; defaults to ``"<seq.name>/<path>/noise<noise>"``.
    noise_seed : int, optional
        Seed of the noise; defaults to ``seed + 1``.

    Returns
    -------
    Sequence
        ``W`` (2F, P), ``rotations`` (F, 3, 3), ``shapes`` (F, 3, P) in the new camera
        frame, ``world_shapes``, ``K`` and ``edges`` of ``seq``; ``extra`` records the
        path, its turn in degrees, the noise and the seed.
    """
    S = world_shapes(seq)
    F = S.shape[0]
    R, label = _path_rotations(seq, path, F, seed)
    W, X = project(S, R)
    if noise:
        W = add_noise(W, noise, seed=seed + 1 if noise_seed is None else noise_seed)
    return Sequence(
        name=name or f"{seq.name}/{label}/noise{noise:g}",
        W=W,
        shapes=X,
        rotations=R,
        K=seq.K,
        edges=seq.edges,
        world_shapes=S,
        extra=dict(
            path=label,
            turn=path_turn(R),
            noise=float(noise),
            seed=seed,
            noise_seed=noise_seed,
            source=seq.name,
        ),
    )


def _path_rotations(seq, path, F, seed):
    """(rotations (F, 3, 3), label) for a path argument of :func:`reproject`."""
    if isinstance(path, str):
        if path != "original":
            return _path_rotations(seq, parse_path(path), F, seed)
        if seq.rotations is None:
            return np.broadcast_to(np.eye(3), (F, 3, 3)).copy(), "original"
        return np.asarray(seq.rotations, float), "original"
    if callable(path):
        R, label = np.asarray(path(F, seed), float), getattr(path, "__name__", "custom")
    else:
        R, label = np.asarray(path, float), "custom"
    if R.shape != (F, 3, 3):
        raise ValueError(f"camera path must give shape (F, 3, 3) = {(F, 3, 3)}; got {R.shape}")
    return R, label


def parse_path(text):
    """Camera path from its name: ``original``, ``smooth<deg>``, ``fast[<deg>]``, ``random``.

    Examples: ``"smooth62"``, ``"smooth145"``, ``"fast"`` (40 degrees per frame),
    ``"fast15"``, ``"random"``.
    """
    if text == "original":
        return "original"
    if text == "random":
        return random()
    for prefix, make, default in (("smooth", smooth, None), ("fast", fast, 40.0)):
        if text.startswith(prefix):
            arg = text[len(prefix) :]
            if not arg and default is None:
                raise ValueError(f"path {text!r} needs a turn in degrees, e.g. 'smooth62'")
            try:
                return make(float(arg) if arg else default)
            except ValueError as exc:
                raise ValueError(f"bad camera path {text!r}: {exc}") from exc
    raise ValueError(
        f"unknown camera path {text!r}; expected 'original', 'smooth<deg>', "
        f"'fast[<deg>]' or 'random'"
    )


def row_seed(seed, *key):
    """Seed from a base seed and a key (e.g. name, path): not from a place in a list."""
    text = "|".join(f"{k:g}" if isinstance(k, float) else str(k) for k in key)
    return (int(seed) * 1_000_003 + zlib.crc32(text.encode())) % 2**31


def validation_set(rows, load, seed=0):
    """Build the validation sequences.

    Parameters
    ----------
    rows : iterable of (name, path, noise)
        ``name`` a sequence name given to ``load``; ``path`` a name accepted by
        :func:`parse_path`; ``noise`` as in :func:`reproject`.
    load : callable ``name -> Sequence``
        E.g. ``lambda n: data_tools.load_mocap(n, folder)``; called once per name.
    seed : int
        Base seed. A row's camera path is drawn from ``row_seed(seed, name, path)`` (the
        same path at every noise level) and its noise from ``row_seed(seed, name, path,
        noise)``: rows do not depend on their order.

    Returns
    -------
    list of Sequence, one per row, in order.
    """
    cache, out = {}, []
    for name, path, noise in rows:
        if name not in cache:
            cache[name] = load(name)
        out.append(
            reproject(
                cache[name],
                path,
                noise,
                seed=row_seed(seed, name, path),
                noise_seed=row_seed(seed, name, path, float(noise)),
            )
        )
    return out
