"""Per-point fills of the lost-fill study (issue 24): each fills one point's unseen frames
from the reconstruction's shapes of the points seen there (see lost_fill_study.py)."""

from __future__ import annotations

import numpy as np


def kabsch(A, B):
    """Batched rotation R (n, 3, 3), no reflection, with R (A - cA) ~ B - cB for A, B (n, 3, k)."""
    A = A - A.mean(axis=2, keepdims=True)
    B = B - B.mean(axis=2, keepdims=True)
    U, _, Vt = np.linalg.svd(B @ A.transpose(0, 2, 1))
    d = np.sign(np.linalg.det(U @ Vt))
    U = U.copy()
    U[:, :, 2] *= d[:, None]
    return U @ Vt


def rigidity(X, observed, p):
    """(P,) spread (std) over the frames both are seen of the distance from p to each point,
    in units of the shapes' RMS radius; inf for p itself and points never seen with p."""
    radius = np.sqrt(np.mean(np.sum((X - X.mean(axis=2, keepdims=True)) ** 2, axis=1)))
    d = np.linalg.norm(X - X[:, :, p:p + 1], axis=1) / radius         # (F, P)
    both = observed & observed[:, p:p + 1]
    n = both.sum(axis=0)
    mean = np.where(both, d, 0).sum(axis=0) / np.maximum(n, 1)
    var = np.where(both, (d - mean) ** 2, 0).sum(axis=0) / np.maximum(n, 1)
    out = np.where(n >= 3, np.sqrt(var), np.inf)
    out[p] = np.inf
    return out


def template(X, frames, nb, p, iters=3):
    """The point p in its neighbours' frame averaged over ``frames`` (GPA on the
    neighbours): returns (Z (3, k) neighbours, z (3,) point, residual RMS of p)."""
    A = X[frames][:, :, nb]
    a = X[frames][:, :, p] - A.mean(axis=2)
    A = A - A.mean(axis=2, keepdims=True)
    Z = A[-1]
    for _ in range(iters):
        R = kabsch(A, np.broadcast_to(Z, A.shape))
        Z = (R @ A).mean(axis=0)
    pts = np.einsum("nij,nj->ni", R, a)
    z = pts.mean(axis=0)
    resid = float(np.sqrt(np.mean(np.sum((pts - z) ** 2, axis=1))))
    return Z, z, resid


def carry(X, frames, nb, Z, z):
    """p's fill in ``frames``: the template (Z, z) moved onto the neighbours there."""
    B = X[frames][:, :, nb]
    R = kabsch(np.broadcast_to(Z, B.shape), B)
    return np.einsum("nij,j->ni", R, z) + B.mean(axis=2)


def _last_seen(seen):
    F = seen.size
    idx = np.where(seen, np.arange(F), -1)
    last = np.maximum.accumulate(idx)
    nxt = np.where(seen, np.arange(F), F)
    nxt = np.minimum.accumulate(nxt[::-1])[::-1]
    return last, nxt



def radius(X):
    return float(np.sqrt(np.mean(np.sum((X - X.mean(axis=2, keepdims=True)) ** 2, axis=1))))


def mean_distance(X, observed, p):
    d = np.linalg.norm(X - X[:, :, p:p + 1], axis=1)
    both = observed & observed[:, p:p + 1]
    n = both.sum(axis=0)
    out = np.where(n >= 3, np.where(both, d, 0).sum(axis=0) / np.maximum(n, 1), np.inf)
    out[p] = np.inf
    return out


def groups(observed, p, rank, n):
    """{neighbour tuple: unseen frames} with the n best-ranked points seen in each frame."""
    keys = {}
    for f in np.flatnonzero(~observed[:, p]):
        cand = np.where(observed[f], rank, np.inf)
        order = np.argsort(cand, kind="stable")[:n]
        keys.setdefault(tuple(order[np.isfinite(cand[order])]), []).append(f)
    return keys


def affine_fit(X, frames, nb, p, lam):
    """b (k,) with X_p ~ mean_N + sum_j b_j (X_j - mean_N) on ``frames`` (ridge lam)."""
    A = X[frames][:, :, nb]
    c = A.mean(axis=2, keepdims=True)
    D = (A - c).transpose(0, 1, 2).reshape(-1, len(nb))          # (3T, k)
    y = (X[frames][:, :, p] - c[:, :, 0]).reshape(-1)
    G = D.T @ D
    b = np.linalg.solve(G + lam * np.trace(G) / len(nb) * np.eye(len(nb)), D.T @ y)
    return b


def fill_point(X, observed, p, kind, n=4, lam=1e-2):
    """(F, 3) trajectory of p: X where seen, the fill of ``kind`` where not.

    kind: "last" (rigid, nearest in the last frame seen: the baseline), "tmpl" (rigid
    template over every co-seen frame, nearest by mean distance), "rtmpl" (template, most
    rigid neighbours), "affine" (affine combination of the nearest, ridge lam)."""
    out = X[:, :, p].copy()
    seen = observed[:, p]
    if kind == "last":
        last, nxt = _last_seen(seen)
        ref = np.where(last >= 0, last, nxt)
        for f in np.flatnonzero(~seen):
            r = ref[f]
            cand = observed[r] & observed[f]
            cand[p] = False
            d = np.where(cand, np.linalg.norm(X[r] - X[r][:, p:p + 1], axis=0), np.inf)
            nb = np.argsort(d, kind="stable")[:min(n, int(cand.sum()))]
            if len(nb) >= 3:
                Z = X[r][:, nb] - X[r][:, nb].mean(axis=1, keepdims=True)
                z = X[r][:, p] - X[r][:, nb].mean(axis=1)
                out[f] = carry(X, np.array([f]), nb, Z, z)[0]
        return out
    rank = rigidity(X, observed, p) if kind == "rtmpl" else mean_distance(X, observed, p)
    for nb, frames in groups(observed, p, rank, n).items():
        nb, frames = list(nb), np.array(frames)
        both = np.flatnonzero(seen & observed[:, nb].all(axis=1)) if nb else []
        if len(nb) < 3 or len(both) < 2:
            continue
        if kind == "affine":
            b = affine_fit(X, both, nb, p, lam)
            B = X[frames][:, :, nb]
            c = B.mean(axis=2)
            out[frames] = c + np.einsum("fik,k->fi", B - c[:, :, None], b)
        else:
            Z, z, _ = template(X, both, nb, p)
            out[frames] = carry(X, frames, nb, Z, z)
    return out


def held_out(observed, p, q):
    """p's seen frames nearest in time to its unseen frames: the fraction q of them."""
    seen = observed[:, p]
    last, nxt = _last_seen(~seen)          # nearest unseen frame before / after
    F = seen.size
    d = np.minimum(np.where(last >= 0, np.arange(F) - last, F),
                   np.where(nxt < F, nxt - np.arange(F), F))
    idx = np.flatnonzero(seen)
    k = max(1, int(round(q * idx.size)))
    return idx[np.argsort(d[idx], kind="stable")[:k]]


def validation_error(X, observed, p, kind, q=0.3, **kw):
    """Mean error (RMS radius = 1) of the fill of ``kind`` on p's held-out seen frames."""
    hold = held_out(observed, p, q)
    obs = observed.copy()
    obs[hold, p] = False
    pred = fill_point(X, obs, p, kind, **kw)
    return float(np.mean(np.linalg.norm(pred[hold] - X[hold, :, p], axis=1)) / radius(X))
