"""Issue 24: fills of the unseen points of lost tracks, compared by measurement.

On the reconstructions cached by ``benchmarks/lost_fill_cache.py`` (the organic pipeline at
the paper's K on W with ``data_tools.drop_tracks(W, 0.3, seed, pattern)``), every candidate
replaces the pipeline's shapes of the points in the frames they were not seen in (the seen
points keep the pipeline's shapes) and is scored as the lost-tracks table scores the
pipeline: mean fill error of the lost points (``nrsfm.experiments.fill``; RMS shape radius
= 1), overall e3d / complete-data e3d, e3d on the seen points / complete. Candidates:

* ``pipeline``: the pipeline's own fill; ``baseline``: ``rigid_neighbour_fill`` (4 nearest
  neighbours, the last frame seen);
* ``rigid-last``: the ``n`` most rigid neighbours (smallest spread of their distance to the
  point over the frames both are seen, on the reconstruction), the last frame seen;
* ``rigid-tmpl``: the same neighbours, a template of the point in its neighbours' frame
  averaged over every frame all of them are seen (generalised Procrustes), carried by the
  neighbours' rigid motion;
* ``rigid-win``: the template from the last ``window`` frames seen only;
* ``mix``: the mean of ``rigid-tmpl`` and the pipeline's fill.

Reliability (acceptance 2): the template's residual on the frames it was built from, and
the frames since the point was last seen; their Spearman correlation with the fill error.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/lost_fill_study.py --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lost_fill_cache import cache_path, study_arguments  # noqa: E402
from lost_fill_methods import fill_point  # noqa: E402



def frames_unseen(observed):
    """(P,) mean over a point's unseen frames of the frames to its nearest seen frame."""
    F = observed.shape[0]
    t = np.arange(F)[:, None]
    before = np.maximum.accumulate(np.where(observed, t, -F), axis=0)
    after = np.minimum.accumulate(np.where(observed, t, 2 * F)[::-1], axis=0)[::-1]
    gap = np.minimum(t - before, after - t)
    return np.where(~observed, gap, 0).sum(0) / np.maximum((~observed).sum(0), 1)


def spearman(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3:
        return float("nan")
    ra = np.argsort(np.argsort(a[ok])).astype(float)
    rb = np.argsort(np.argsort(b[ok])).astype(float)
    return float(np.corrcoef(ra, rb)[0, 1])


def score(fill, truth, observed, e3d_complete):
    """(mean fill error of the lost points, their per-point errors, overall e3d ratio)."""
    from nrsfm.experiments.fill import lost_point_means, point_errors
    from nrsfm.metrics import e3d

    lost = np.flatnonzero(~observed.all(axis=0))
    per = lost_point_means(point_errors(fill, truth), observed)[lost]
    return float(np.mean(per)), per, e3d(fill, truth) / e3d_complete


KINDS = (("last", 4), ("tmpl", 4), ("affine", 6))     # the three of the combination


def candidates(X, obs, undetermined):
    """name -> (filled shapes, per-point reliability or None), and the (P,) spread."""
    lost = np.flatnonzero(~obs.all(axis=0) & obs.any(axis=0))
    fills = {k: X.copy() for k in KINDS + (("rtmpl", 4),)}
    for p in lost:
        for (kind, n), Y in fills.items():
            Y[:, :, p] = fill_point(X, obs, p, kind, n=n)
    S = np.stack([fills[k] for k in KINDS])
    mean = S.mean(axis=0)
    r = np.sqrt(np.mean(np.sum((X - X.mean(axis=2, keepdims=True)) ** 2, axis=1)))
    spread = np.sqrt(np.sum(S.var(axis=0), axis=1)) / r          # (F, P)
    spread_p = np.where(~obs, spread, 0).sum(0) / np.maximum((~obs).sum(0), 1)
    out = {"pipeline": (X, None), "baseline": (fills[("last", 4)], None),
           "rigid-tmpl n4": (fills[("tmpl", 4)], None),
           "rigidity-tmpl n4": (fills[("rtmpl", 4)], None),
           "affine n6": (fills[("affine", 6)], None),
           "mean3": (mean, spread_p), "median3": (np.median(S, axis=0), spread_p),
           "mean3+pipeline": ((3 * mean + X) / 4, spread_p),
           "median3+pipeline": (np.median(np.concatenate([S, X[None]]), axis=0), spread_p),
           "gated": (np.where(undetermined, np.median(S, axis=0), X), spread_p)}
    from nrsfm.stages.fill import fill_unseen
    out["fill_unseen"] = fill_unseen(X, obs)
    out["fill_unseen gated"] = (np.where(undetermined, out["fill_unseen"][0], X),
                                out["fill_unseen"][1])
    return out


def main(argv=None):
    from nrsfm.experiments.fill import e3d_seen
    from nrsfm.experiments.tasks import load_sequence
    from nrsfm.metrics import e3d

    args = study_arguments(__doc__.splitlines()[0], argv)
    print("| sequence | pattern | seed | candidate | fill lost | max | ratio | seen ratio "
          "| rho(resid) | rho(gap) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.sequences:
        seq = load_sequence(name, args.data)
        comp = np.load(cache_path(args.cache, name))
        e3c = e3d(comp["shapes"], seq.shapes)
        for pattern in args.patterns:
            for seed in args.seeds:
                run = np.load(cache_path(args.cache, name, pattern, seed))
                X, obs = run["shapes"], run["observed"]
                seen = e3d_seen(X, seq.shapes, obs) / e3d_seen(comp["shapes"], seq.shapes, obs)
                lost = np.flatnonzero(~obs.all(axis=0))
                mean_gap = frames_unseen(obs)[lost]
                for cname, (fill, rel) in candidates(X, obs, run["undetermined"]).items():
                    m, per, ratio = score(fill, seq.shapes, obs, e3c)
                    rr = spearman(rel[lost], per) if rel is not None else float("nan")
                    print(f"| {name} | {pattern} | {seed} | {cname} | {m:.4f} | "
                          f"{per.max():.3f} | {ratio:.2f} | {seen:.3f} | {rr:.2f} | "
                          f"{spearman(mean_gap, per):.2f} |", flush=True)


if __name__ == "__main__":
    main()
