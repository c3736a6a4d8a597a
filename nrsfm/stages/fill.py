"""Fill of the points not seen in a frame (issue 24): after the shape stage, from the
reconstruction's shapes of the points that were seen.

Where a track is lost, occluded or starts late, the shape stage's own fill of it (the
low-rank model's) is poorly determined: a point seen in a few dozen frames does not pin down
its 3K basis coefficients. Its neighbours, seen in the frames it is not, carry it better.
:func:`fill_unseen` replaces the shape stage's shape of each point in each frame it was not
seen in by the per-coordinate median of four fills:

* ``rigid``: carried rigidly (rotation + translation, Kabsch) from the frame it was seen
  in nearest in time with the 4 points nearest to it there among those seen in both
  frames (the motion-capture user's "rigid body fill");
* ``template``: the same neighbours, the point's position in their frame averaged over
  every frame it was seen with them (generalised Procrustes), carried by their motion;
* ``affine``: an affine combination of its 6 nearest neighbours seen there, the weights
  fitted (ridge) on the frames it was seen with them (exact for a rigid body);
* the shape stage's fill.

"Nearest" (template, affine): mean 3D distance over the frames both are seen. The spread of the three
neighbour fills (RMS over the point's unseen frames, in units of the shapes' RMS radius)
is returned as the fill's reliability: it predicts the fill's error (Spearman 0.4-0.97 over
the lost points of the MoCap sequences). Measurements: ``docs/missing_data_scale.md``,
section "Issue 24".
"""

from __future__ import annotations

import numpy as np

from ..validation import check_shapes

__all__ = ["AFFINE_NEIGHBOURS", "RIDGE", "RIGID_NEIGHBOURS", "fill_unseen"]

#: neighbours of the rigid and template fills, and of the affine fill
RIGID_NEIGHBOURS, AFFINE_NEIGHBOURS = 4, 6
#: ridge of the affine fill's weights, relative to the mean eigenvalue of their normal matrix
RIDGE = 1e-2
_POOL = 16          # candidate neighbours per point (ranked exactly); sampled frames:
_SAMPLE = 20        # frames of the point's that pick the candidates


def _kabsch(A, B):
    """(n, 3, 3) rotations (no reflection) with ``R (A - mean A) ~ B - mean B``; A, B (n, 3, k)."""
    A = A - A.mean(axis=2, keepdims=True)
    B = B - B.mean(axis=2, keepdims=True)
    U, _, Vt = np.linalg.svd(B @ A.transpose(0, 2, 1))
    U = U.copy()
    U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]
    return U @ Vt


def _candidates(X, observed, p):
    """p's candidate neighbours ranked by mean distance over the frames both are seen
    (nearest first; only those seen with p in 3 frames or more)."""
    seen = np.flatnonzero(observed[:, p])
    sample = seen[np.linspace(0, seen.size - 1, min(_SAMPLE, seen.size)).astype(int)]
    d = np.linalg.norm(X[sample] - X[sample][:, :, p:p + 1], axis=1)
    both = observed[sample]
    coarse = np.where(both, d, 0).sum(0) / np.maximum(both.sum(0), 1)
    coarse[(both.sum(0) == 0) | (np.arange(X.shape[2]) == p)] = np.inf
    pool = np.argsort(coarse, kind="stable")[:_POOL]
    pool = pool[np.isfinite(coarse[pool])]
    both = observed[seen][:, pool]
    d = np.linalg.norm(X[seen][:, :, pool] - X[seen][:, :, p:p + 1], axis=1)
    n = both.sum(0)
    mean = np.where(both, d, 0).sum(0) / np.maximum(n, 1)
    keep = n >= 3
    return pool[keep][np.argsort(mean[keep], kind="stable")]


def _neighbour_sets(observed, frames, ranked, n):
    """[(neighbours, frames)]: in each of ``frames``, the first ``n`` of ``ranked`` seen
    there; frames with fewer than 3 are left out."""
    avail = observed[np.ix_(frames, ranked)]
    sel = avail & (np.cumsum(avail, axis=1) <= n)
    ok = sel.sum(axis=1) >= 3
    if not ok.any():
        return []
    patterns, inverse = np.unique(sel[ok], axis=0, return_inverse=True)
    inverse = np.ravel(inverse)
    return [(ranked[pat], frames[ok][inverse == i]) for i, pat in enumerate(patterns)]


def _nearest_seen(seen, frames):
    """(len(frames),) for each frame, the frame of ``seen`` (sorted) nearest in time."""
    if seen.size == 1:
        return np.full(frames.size, seen[0])
    i = np.clip(np.searchsorted(seen, frames), 1, seen.size - 1)
    return np.where(np.abs(seen[i - 1] - frames) <= np.abs(seen[i] - frames),
                    seen[i - 1], seen[i])


def _rigid(X, observed, p, ranked, unseen):
    """(F, 3) the rigid fill (NaN where not made): from the frame r seen nearest in time,
    the ``RIGID_NEIGHBOURS`` candidates nearest to p in r among those seen in r and f."""
    out = np.full(X[:, :, p].shape, np.nan)
    refs = _nearest_seen(np.flatnonzero(observed[:, p]), unseen)
    for r in np.unique(refs):
        d = np.linalg.norm(X[r][:, ranked] - X[r][:, p:p + 1], axis=0)
        order = ranked[np.argsort(np.where(observed[r, ranked], d, np.inf), kind="stable")]
        order = order[observed[r, order]]
        for nb, frames in _neighbour_sets(observed, unseen[refs == r], order,
                                          RIGID_NEIGHBOURS):
            A, B = X[r][:, nb], X[frames][:, :, nb]
            R = _kabsch(np.broadcast_to(A, B.shape), B)
            out[frames] = (np.einsum("fij,j->fi", R, X[r][:, p] - A.mean(axis=1))
                           + B.mean(axis=2))
    return out


def _template(X, p, nb, both, frames, iters=3):
    """The point in its neighbours' frame averaged over ``both`` (GPA), carried."""
    A = X[both][:, :, nb]
    a = X[both][:, :, p] - A.mean(axis=2)
    A = A - A.mean(axis=2, keepdims=True)
    Z = A[-1]
    for _ in range(iters):
        R = _kabsch(A, np.broadcast_to(Z, A.shape))
        Z = (R @ A).mean(axis=0)
    z = np.einsum("nij,nj->ni", R, a).mean(axis=0)
    B = X[frames][:, :, nb]
    R = _kabsch(np.broadcast_to(Z, B.shape), B)
    return np.einsum("fij,j->fi", R, z) + B.mean(axis=2)


def _affine(X, p, nb, both, frames):
    """``mean_N + sum_j b_j (x_j - mean_N)``, b fitted (ridge) on ``both``."""
    A = X[both][:, :, nb]
    c = A.mean(axis=2, keepdims=True)
    D = (A - c).reshape(-1, len(nb))
    y = (X[both][:, :, p] - c[:, :, 0]).reshape(-1)
    G = D.T @ D
    b = np.linalg.solve(G + RIDGE * np.trace(G) / len(nb) * np.eye(len(nb)), D.T @ y)
    B = X[frames][:, :, nb]
    c = B.mean(axis=2)
    return c + np.einsum("fik,k->fi", B - c[:, :, None], b)


def _fills(X, observed, p, ranked):
    """(3, F, 3) the rigid, template and affine fills of p (NaN where not made)."""
    unseen = np.flatnonzero(~observed[:, p])
    out = np.full((3,) + X[:, :, p].shape, np.nan)
    out[0] = _rigid(X, observed, p, ranked, unseen)
    for n, k, fill in ((RIGID_NEIGHBOURS, 1, _template), (AFFINE_NEIGHBOURS, 2, _affine)):
        for nb, frames in _neighbour_sets(observed, unseen, ranked, n):
            both = np.flatnonzero(observed[:, p] & observed[:, nb].all(axis=1))
            if both.size >= 2:
                out[k, frames] = fill(X, p, nb, both, frames)
    return out


def fill_unseen(shapes, observed, points=None):
    """The shapes with every point's unseen frames filled from its neighbours.

    Parameters
    ----------
    shapes : (F, 3, P) ndarray
        A reconstruction's shapes (any units, any per-frame frame); those of the points
        seen in a frame are kept, and give the fills.
    observed : (F, P) bool array_like
        True where a point was seen.
    points : (P,) bool array_like, optional
        The points to fill (default: every point not seen in some frame);
        :func:`nrsfm.reconstruct` passes those the data leave undetermined (the others'
        model fill is better: uniform missing data, short gaps).

    Returns
    -------
    filled : (F, 3, P) ndarray
        ``shapes`` with each point's shape in each frame it was not seen in replaced by the
        per-coordinate median of its rigid, template and affine fills and its shape there
        (the model's fill); where no neighbour fill can be made (fewer than 3 neighbours
        seen there and with the point), the model's fill is kept.
    spread : (P,) ndarray
        Reliability of each point's fill: the RMS over its unseen frames of the spread
        (root of the summed per-coordinate variance) of its three neighbour fills, in units
        of the shapes' RMS radius; larger is less reliable. NaN for a point not filled
        (seen in every frame or in none, or not in ``points``).
    """
    X = check_shapes(shapes, "shapes")
    observed = np.asarray(observed, bool)
    if observed.shape != (X.shape[0], X.shape[2]):
        raise ValueError(f"observed must have shape {(X.shape[0], X.shape[2])}; got "
                         f"{observed.shape}")
    filled = X.copy()
    spread = np.full(X.shape[2], np.nan)
    radius = np.sqrt(np.mean(np.sum((X - X.mean(axis=2, keepdims=True)) ** 2, axis=1)))
    todo = ~observed.all(axis=0) & observed.any(axis=0)
    if points is not None:
        todo &= np.asarray(points, bool)
    for p in np.flatnonzero(todo):
        S = _fills(X, observed, p, _candidates(X, observed, p))
        made = np.isfinite(S).all(axis=(0, 2))
        if not made.any():
            continue
        S = S[:, made]
        frames = np.flatnonzero(made)
        filled[frames, :, p] = np.median(np.concatenate([S, X[frames, :, p][None]]), axis=0)
        var = np.sum(S.var(axis=0), axis=1)
        spread[p] = np.sqrt(np.mean(var)) / radius if radius > 0 else 0.0
    return filled, spread
