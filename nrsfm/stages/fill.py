"""Fill of the points not seen in a frame, after the shape stage, from their neighbours.

Where a track is lost or starts late, the shape stage's (low-rank) fill of it is poorly
determined, while its neighbours, seen in the frames it is not, carry it. :func:`fill_unseen`
takes the per-coordinate median of the shape stage's fill and three from the neighbours:
``rigid``, carried rigidly (Kabsch) from the frame seen nearest in time with the 4 points
nearest to it there; ``template``, the point in its 4 nearest neighbours' frame averaged
over the frames it was seen with them (generalised Procrustes), carried by their motion;
``affine``, an affine combination of its 6 nearest neighbours, the weights fitted on the
frames it was seen with them. "Nearest" (template, affine): mean 3D distance over the
frames both are seen. How far the four stray from their median predicts the fill's error.
Why these choices: ``docs/studies/missing_data.md``.
"""

from __future__ import annotations

import numpy as np

from ..geometry import project_to_so3_batch

#: neighbours of the rigid and template fills, and of the affine fill
RIGID_NEIGHBOURS, AFFINE_NEIGHBOURS = 4, 6
#: ridge of the affine fill's weights, relative to the mean eigenvalue of their normal matrix
RIDGE = 1e-2
#: a filled point is unreliable (``Reconstruction.unreliable``) when its fills stray from
#: their median by more than this fraction of the shapes' RMS radius
SPREAD_MAX = 0.05
_POOL = 16  # candidate neighbours per point (ranked exactly)
_SAMPLE = 20  # frames of the point's that pick the candidates
_CHUNK = 1 << 20  # (pair, frame) distances computed at once


def _centroid(A):
    """(..., 3) the mean of the (..., 3, k) points A (``A.mean(axis=2)`` bit for bit)."""
    c = A[..., 0] + A[..., 1]
    for j in range(2, A.shape[-1]):
        c += A[..., j]
    return c / A.shape[-1]


def _kabsch(A, B):
    """(n, 3, 3) rotations with ``R (A - mean A) ~ B - mean B``; A, B (n, 3, k)."""
    A = A - _centroid(A)[..., None]  # B's centring is implied: A's rows sum to 0
    return project_to_so3_batch(B @ A.transpose(0, 2, 1))


def _dist(a, b):
    """Distances of the (..., 3) points a and b, summed in the order x, y, z."""
    d = a - b
    return np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])


def _mean_distance(Xt, O, todo, slot, q, frames, valid):
    """(mean, count) for each pair (todo[slot[i]], q[i]): the mean distance over the frames
    ``frames[slot[i]][valid[slot[i]]]`` in which q[i] is seen, and their number."""
    mean, count = np.empty(q.size), np.empty(q.size, int)
    F = Xt.shape[1]
    flat, seen = Xt.reshape(-1, 3), O.T.ravel()
    own = Xt[todo[:, None], frames]  # (n, S, 3), once per point
    step = max(1, _CHUNK // max(frames.shape[1], 1))
    for s in range(0, q.size, step):
        i = slice(s, s + step)
        f = frames[slot[i]].T  # (frames, pairs)
        iq = q[i] * F + f
        both = valid[slot[i]].T & seen.take(iq)
        d = _dist(flat.take(iq, axis=0), own[slot[i]].transpose(1, 0, 2))
        count[i] = both.sum(axis=0)
        mean[i] = np.where(both, d, 0).sum(axis=0) / np.maximum(count[i], 1)
    return mean, count


def _samples(O, todo):
    """(n, S) frames and validity: ``_SAMPLE`` of each point's seen frames, and all."""
    seen = O[:, todo].T
    n = seen.sum(axis=1)
    allf = np.zeros((todo.size, max(n.max(), 1)), int)
    allv = np.arange(allf.shape[1]) < n[:, None]
    allf[allv] = np.nonzero(seen)[1]
    m = np.minimum(_SAMPLE, n)
    j = np.zeros((todo.size, _SAMPLE), int)
    sv = np.arange(_SAMPLE) < m[:, None]
    for k in np.unique(n):  # np.linspace, as the per-point definition
        j[n == k, : min(_SAMPLE, k)] = np.linspace(0, k - 1, min(_SAMPLE, k)).astype(int)
    return np.take_along_axis(allf, j, axis=1), sv, allf, allv


def _near_pairs(X, O, todo, sf):
    """Sorted distinct (point slot, candidate) pairs: in each of the point's sampled frames
    ``sf`` (n, S), the ``_POOL + 1`` points seen there nearest to it; X (F, 3, P)."""
    from scipy.spatial import cKDTree

    slot, cand = [], []
    for f in np.unique(sf):
        rows, ids = np.flatnonzero((sf == f).any(axis=1)), np.flatnonzero(O[f])
        k = min(_POOL + 1, ids.size)
        tree = cKDTree(X[f][:, ids].T, leafsize=32, balanced_tree=False, compact_nodes=False)
        slot.append(np.repeat(rows, k))
        cand.append(ids[tree.query(X[f][:, todo[rows]].T, k=k)[1].reshape(-1)])
    P = X.shape[2]
    key = np.unique(np.concatenate(slot) * P + np.concatenate(cand))
    return key // P, key % P


def _candidates(X, Xt, O, todo):
    """(n, _POOL) each point's candidate neighbours (-1: none), nearest first by mean distance
    over the frames both are seen (3 or more), among the nearest over its sampled frames."""
    sf, sv, allf, allv = _samples(O, todo)
    slot, q = _near_pairs(X, O, todo, np.where(sv, sf, sf[:, :1]))  # pad: a repeat
    coarse, count = _mean_distance(Xt, O, todo, slot, q, sf, sv)
    ok = (count > 0) & (q != todo[slot])
    slot, q, coarse = slot[ok], q[ok], coarse[ok]
    order = np.lexsort((q, coarse, slot))
    pick = order[_rank(slot[order], todo.size) < _POOL]
    slot, q, coarse = slot[pick], q[pick], coarse[pick]
    mean, n = _mean_distance(Xt, O, todo, slot, q, allf, allv)
    keep = n >= 3
    slot, q, mean, coarse = slot[keep], q[keep], mean[keep], coarse[keep]
    order = np.lexsort((q, coarse, mean, slot))
    out = np.full((todo.size, _POOL), -1)
    out[slot[order], _rank(slot[order], todo.size)] = q[order]
    return out


def _rank(slot, n):
    """Each entry's place among those of its slot (entries sorted by slot, n slots)."""
    return np.arange(slot.size) - np.searchsorted(slot, np.arange(n))[slot]


def _by_size(avail, n):
    """[(k, rows, columns)]: the first ``n`` available of each row of ``avail`` (m, S) bool,
    grouped by their number k >= 3: the rows with k, and their (rows, k) columns."""
    sel, count = np.empty_like(avail), np.zeros(avail.shape[0], np.int64)
    for j in range(avail.shape[1]):  # a running count per column (S is small)
        count += avail[:, j]
        sel[:, j] = avail[:, j] & (count <= n)
    k = np.minimum(count, n)
    out = []
    for size in np.unique(k[k >= 3]):
        rows = np.flatnonzero(k == size)
        out.append((size, rows, np.nonzero(sel[rows])[1].reshape(rows.size, size)))
    return out


def _gather(Xt, nb, f):
    """(m, 3, k) the shapes of the (m, k) points ``nb`` in the frames ``f`` (m,)."""
    return np.ascontiguousarray(Xt[nb, f[:, None]].transpose(0, 2, 1))


def _nearest_seen(seen, unseen_f, slot):
    """For each (slot, frame) pair, the slot's seen frame nearest in time (earlier on a tie)."""
    F = seen.shape[1]
    frame = np.arange(F)
    prev = np.maximum.accumulate(np.where(seen, frame, -1), axis=1)[slot, unseen_f]
    nxt = np.minimum.accumulate(np.where(seen, frame, 2 * F)[:, ::-1], axis=1)[:, ::-1]
    nxt = nxt[slot, unseen_f]
    use_prev = (prev >= 0) & ((nxt >= F) | (unseen_f - prev <= nxt - unseen_f))
    return np.where(use_prev, prev, nxt)


def _rigid(Xt, O, todo, ranked, slot, f, seen_f):
    """(m, 3) the rigid fill of each (point slot, unseen frame f) pair (NaN where not made):
    from the frame r seen nearest in time, the ``RIGID_NEIGHBOURS`` candidates nearest to
    the point in r among those seen in r and f (``seen_f`` (m, _POOL): in f)."""
    out = np.full((slot.size, 3), np.nan)
    F = Xt.shape[1]
    r = _nearest_seen(O[:, todo].T, f, slot)
    p = todo[slot]
    key, pair = np.unique(slot * F + r, return_inverse=True)  # distinct (slot, r)
    us, ur = key // F, key % F
    cand = ranked[us]
    valid = cand >= 0
    cand = np.where(valid, cand, 0)
    d = _dist(Xt[cand, ur[:, None]], Xt[todo[us], ur][:, None])
    seen_r = valid & O[ur[:, None], cand]
    order = np.argsort(np.where(seen_r, d, np.inf), axis=1, kind="stable")
    order = order[pair]
    cand = np.take_along_axis(cand[pair], order, axis=1)
    avail = np.take_along_axis(seen_r[pair] & seen_f, order, axis=1)
    for _, rows, cols in _by_size(avail, RIGID_NEIGHBOURS):
        nb = np.take_along_axis(cand[rows], cols, axis=1)
        A, B = _gather(Xt, nb, r[rows]), _gather(Xt, nb, f[rows])
        R = _kabsch(A, B)
        out[rows] = np.einsum("nij,nj->ni", R, Xt[p[rows], r[rows]] - _centroid(A)) + _centroid(B)
    return out


def _patterns(O, todo, ranked, slot, seen_f, n):
    """[(k, item, nb, islot, bi, bf)] for the fills from the first ``n`` candidates seen in
    the frame: each pair's item (-1: none; one item per point and neighbour set seen
    together in at least 2 frames: rows ``bi``, ``bf``, sorted), the items' (items, k)
    neighbours and point slots."""
    out = []
    for k, rows, cols in _by_size(seen_f, n):
        code = slot[rows] * (1 << _POOL) + (1 << cols).sum(axis=1)
        codes, inverse = np.unique(code, return_inverse=True)
        islot, icols = codes >> _POOL, (codes[:, None] >> np.arange(_POOL)) & 1
        nb = np.take_along_axis(ranked[islot], np.nonzero(icols)[1].reshape(-1, k), axis=1)
        both = O[:, todo[islot]].T & O.T[nb].all(axis=1)  # (items, F)
        good = both.sum(axis=1) >= 2
        item = np.full(slot.size, -1)
        renum = np.cumsum(good) - 1
        item[rows] = np.where(good[inverse], renum[inverse], -1)
        if good.any():
            bi, bf = np.nonzero(both[good])
            out.append((k, item, nb[good], islot[good], bi, bf))
    return out


def _segment_mean(V, seg, n):
    """(n, ...) the mean of the rows of V in each of n segments (rows sorted by seg)."""
    start = np.searchsorted(seg, np.arange(n))
    count = np.diff(np.append(start, seg.size)).reshape((n,) + (1,) * (V.ndim - 1))
    return np.add.reduceat(V, start, axis=0) / count


def _template(Xt, ip, nb, bi, bf, iters=3):
    """(items, 3, k), (items, 3): each item's neighbours' template and the point in it,
    averaged (GPA) over the frames the point was seen with them."""
    n = nb.shape[0]
    A = _gather(Xt, nb[bi], bf)
    c = _centroid(A)
    a = Xt[ip[bi], bf] - c
    A = A - c[..., None]
    Z = A[np.searchsorted(bi, np.arange(n), side="right") - 1]
    for _ in range(iters):
        R = _kabsch(A, Z[bi])
        Z = _segment_mean(R @ A, bi, n)
    return Z, _segment_mean(np.einsum("nij,nj->ni", R, a), bi, n)


def _affine(Xt, ip, nb, bi, bf):
    """(items, k) each item's affine weights (``mean_N + sum_j b_j (x_j - mean_N)``),
    fitted (ridge) on the frames the point was seen with its neighbours."""
    n, k = nb.shape
    A = _gather(Xt, nb[bi], bf)
    c = _centroid(A)[..., None]
    D = A - c
    y = Xt[ip[bi], bf] - c[:, :, 0]
    start = np.searchsorted(bi, np.arange(n))
    G = np.add.reduceat(np.einsum("rik,ril->rkl", D, D), start, axis=0)
    h = np.add.reduceat(np.einsum("rik,ri->rk", D, y), start, axis=0)
    reg = RIDGE * np.trace(G, axis1=1, axis2=2) / k
    return np.linalg.solve(G + reg[:, None, None] * np.eye(k), h[:, :, None])[:, :, 0]


def _fills(Xt, O, todo, ranked, slot, f):
    """(3, m, 3) the rigid, template and affine fills of each pair (NaN where not made)."""
    out = np.full((3, slot.size, 3), np.nan)
    seen_f = (O[:, np.maximum(ranked, 0)] & (ranked >= 0))[f, slot]  # (m, _POOL)
    out[0] = _rigid(Xt, O, todo, ranked, slot, f, seen_f)
    for n, j in ((RIGID_NEIGHBOURS, 1), (AFFINE_NEIGHBOURS, 2)):
        for k, item, nb, islot, bi, bf in _patterns(O, todo, ranked, slot, seen_f, n):
            rows = np.flatnonzero(item >= 0)
            it = item[rows]
            B = _gather(Xt, nb[it], f[rows])
            c = _centroid(B)
            if j == 1:
                Z, z = _template(Xt, todo[islot], nb, bi, bf)
                out[j, rows] = np.einsum("nij,nj->ni", _kabsch(Z[it], B), z[it]) + c
            else:
                b = _affine(Xt, todo[islot], nb, bi, bf)
                out[j, rows] = c + np.einsum("nik,nk->ni", B - c[:, :, None], b[it])
    return out


def _median4(a, b, c, d):
    """Element-wise median of four arrays (the mean of the middle two, as ``np.median``)."""
    lo = np.maximum(np.minimum(a, b), np.minimum(c, d))
    return 0.5 * (lo + np.minimum(np.maximum(a, b), np.maximum(c, d)))


def fill_unseen(shapes, observed, points=None):
    """The shapes with every point's unseen frames filled from its neighbours.

    Parameters
    ----------
    shapes : (F, 3, P) ndarray
        A reconstruction's shapes (any units); those of the points seen in a frame are
        kept, and give the fills.
    observed : (F, P) bool array_like
        True where a point was seen.
    points : (P,) bool array_like, optional
        The points to fill (default: every point not seen in some frame);
        :func:`nrsfm.reconstruct` passes those the data leave undetermined.

    Returns
    -------
    filled : (F, 3, P) ndarray
        ``shapes`` with each point's shape in each frame it was not seen in replaced by the
        per-coordinate median of its rigid, template and affine fills and its shape there;
        kept where no neighbour fill can be made (fewer than 3 neighbours seen).
    spread : (P,) ndarray
        Reliability of each point's fill: in each of its unseen frames the median of the
        distances of its four fills to their median, RMS over those frames, in units of the
        shapes' RMS radius; NaN for a point not filled.
    """
    X = np.asarray(shapes, float)  # from reconstruct: checked
    if X.ndim != 3 or X.shape[1] != 3:
        raise ValueError(f"shapes must have shape (F, 3, P); got {X.shape}")
    observed = np.asarray(observed, bool)
    if observed.shape != (X.shape[0], X.shape[2]):
        raise ValueError(f"observed must have shape {X.shape[::2]}; got {observed.shape}")
    filled = X.copy()
    spread = np.full(X.shape[2], np.nan)
    centred = X - X.mean(axis=2, keepdims=True)
    radius = np.sqrt(np.einsum("fip,fip->", centred, centred) / (X.shape[0] * X.shape[2]))
    del centred
    todo = ~observed.all(axis=0) & observed.any(axis=0)
    if points is not None:
        todo &= np.asarray(points, bool)
    todo = np.flatnonzero(todo)
    if todo.size == 0:
        return filled, spread
    Xt = np.ascontiguousarray(X.transpose(2, 0, 1))  # (P, F, 3)
    ranked = _candidates(X, Xt, observed, todo)
    slot, f = np.nonzero(~observed[:, todo].T)  # (point, unseen frame)
    S = _fills(Xt, observed, todo, ranked, slot, f)
    made = np.isfinite(S).all(axis=(0, 2))
    S, slot, f = S[:, made], slot[made], f[made]
    p = todo[slot]
    four = (S[0], S[1], S[2], Xt[p, f])
    median = _median4(*four)
    filled[f, :, p] = median
    stray = _median4(*(_dist(x, median) for x in four))  # robust to one stray fill
    n = np.bincount(slot, minlength=todo.size)
    mean = np.bincount(slot, stray * stray, minlength=todo.size) / np.maximum(n, 1)
    spread[todo[n > 0]] = np.sqrt(mean[n > 0]) / radius if radius > 0 else 0.0
    return filled, spread
