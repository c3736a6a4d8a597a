"""Missing data at scale: the rank-r factorisation of the observed entries against complete
tracks (and the soft-impute completion). Prints two tables.

1. Dense synthetic tracks (issue 16, acceptance 1): P points x F frames from a random
   rank-3K shape basis (K bases of 3 x P, smooth coefficients) under a smooth orthographic
   camera, noise as a fraction of W's mean row std; ``--lost`` of the tracks are lost from
   a frame drawn in [2, F) to the end, ``--late`` start at a frame drawn in [0, F - 2)
   (NaN before). Same data reconstructed with complete tracks and with the missing
   entries, in one run: time, e3d over all points, and e3d over the tracks the completion
   determines (fill gain <= ``MAX_GAIN``, ``nrsfm.stages.completion_fast.fill_gain``)
   beside the complete-track e3d on the same points.
2. MoCap (issue 16, acceptance 2; needs NRSFM_DATA): 30 % missing in the tracking pattern
   and uniformly at random (``data_tools.drop_tracks``, seed 0), organic at the paper's K:
   e3d of complete data, of the current soft-impute completion (``nrsfm.completion``), and
   of the factorisation of W (lags 0) and of the lagged matrix (lags -1, 0, 1).
3. Synthetic videos (``data_tools.synthetic_video``, sheet and face), sparse and dense
   tracks with new tracks every ``--detect-every`` frames: the complete tracks alone
   against every track seen in 2+ frames (factorisation, then the pipeline), K = 1.

    Run from the repository root, one BLAS thread:
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/missing_study.py
    python benchmarks/missing_study.py --skip-mocap --points 2000
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import nrsfm  # noqa: E402
from data_tools.synthetic import camera_rotations  # noqa: E402
from nrsfm.metrics import e3d  # noqa: E402
from nrsfm.stages.completion_fast import MAX_GAIN, complete_low_rank  # noqa: E402


def dense_sequence(P, F, K, noise, lost, late, seed):
    """Synthetic dense tracks with lost and late tracks.

    Returns
    -------
    W : (2F, P) ndarray
        Complete noisy measurements (per-frame translation included).
    observed : (F, P) bool ndarray
    shapes : (F, 3, P) ndarray
        Ground truth in the camera frame, centred per frame.
    """
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((K, 3, P)) * np.array([1.0, 0.8, 0.6])[:, None]
    basis[1:] *= 0.4
    t = np.arange(F)[:, None]
    coeff = np.sin(2 * np.pi * rng.uniform(1, 4, (1, K)) * t / F
                   + rng.uniform(0, 2 * np.pi, (1, K)))
    coeff[:, 0] = 1.0 + 0.1 * coeff[:, 0]
    cam = camera_rotations(F, "smooth", rng) @ np.einsum("fk,kip->fip", coeff, basis)
    W = cam[:, :2].reshape(2 * F, P) + 3.0 * rng.standard_normal((2 * F, 1))
    W = W + noise * np.mean(np.std(W, axis=1)) * rng.standard_normal(W.shape)
    observed = np.ones((F, P), bool)
    order = rng.permutation(P)
    n_lost, n_late = int(round(lost * P)), int(round(late * P))
    frames = np.arange(F)[:, None]
    lost_p, late_p = order[:n_lost], order[n_lost:n_lost + n_late]
    observed[:, lost_p] = frames < rng.integers(2, F, n_lost)[None, :]
    observed[:, late_p] = frames >= rng.integers(0, F - 2, n_late)[None, :]
    return W, observed, cam - cam.mean(axis=2, keepdims=True)


def with_nan(W, observed):
    """Copy of W with NaN where a point is not observed."""
    return np.where(np.repeat(observed, 2, axis=0), W, np.nan)


def dense_table(args):
    P, F, K = args.points, args.frames, args.K
    W, observed, gt = dense_sequence(P, F, K, args.noise, args.lost, args.late, args.seed)
    Wm = with_nan(W, observed)
    t0 = time.perf_counter()
    full = nrsfm.reconstruct(W, K)
    t_full = time.perf_counter() - t0
    t0 = time.perf_counter()
    comp = complete_low_rank(Wm, 3 * K)
    t_comp = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = nrsfm.reconstruct(comp.W, K)
    t_miss = t_comp + time.perf_counter() - t0
    det = comp.determined()
    e_full, e_all = e3d(full.shapes, gt), e3d(res.shapes, gt)
    e_full_det = e3d(full.shapes[:, :, det], gt[:, :, det])
    e_det = e3d(res.shapes[:, :, det], gt[:, :, det])
    print(f"\nTable 1: dense synthetic tracks, P = {P}, F = {F}, K = {K}, noise "
          f"{100 * args.noise:g} %, {100 * args.lost:g} % lost, {100 * args.late:g} % late, "
          f"seed {args.seed}; {100 * comp.missing_fraction:.1f} % of the observations "
          f"missing\n")
    print("| run | seconds | ratio to complete | e3d all points | e3d determined tracks "
          "| complete-track e3d, same tracks | bound 1.2 x + .002 |")
    print("|---|---|---|---|---|---|---|")
    print(f"| complete tracks | {t_full:.1f} | 1 | {e_full:.4f} | - | - | - |")
    print(f"| missing: factorisation ({comp.n_iter} iterations, {t_comp:.1f} s) + pipeline "
          f"| {t_miss:.1f} | {t_miss / t_full:.2f} | {e_all:.4f} | {e_det:.4f} "
          f"({det.sum()} of {P}) | {e_full_det:.4f} | {1.2 * e_full_det + 0.002:.4f} |")
    nobs = observed.sum(axis=0)
    print(f"\nundetermined tracks (fill gain > {MAX_GAIN:g}): {P - det.sum()}, observed in "
          f"{nobs[~det].min() if (~det).any() else '-'} to "
          f"{nobs[~det].max() if (~det).any() else '-'} frames; determined tracks: at least "
          f"{nobs[det].min()} frames")


def mocap_table(args):
    import data_tools as dt
    from nrsfm.completion import complete_measurements

    rows = []
    for name in args.sequences:
        seq = dt.load_mocap(name)
        K = seq.K
        e0 = nrsfm.reconstruct(seq.W, K).errors(seq.shapes)["e3d"]
        for pattern in ("tracking", "uniform"):
            Wm, mask = dt.drop_tracks(seq.W, args.fraction, seed=args.seed, pattern=pattern)
            t0 = time.perf_counter()
            old = complete_measurements(Wm)
            t_old = time.perf_counter() - t0
            e_old = nrsfm.reconstruct(old.W, K).errors(seq.shapes)["e3d"]
            fact = []
            for lags in ((0,), (-1, 0, 1)):
                t0 = time.perf_counter()
                new = complete_low_rank(Wm, rank_rule(Wm, K, args.rank), lags=lags)
                t_new = time.perf_counter() - t0
                e_new = nrsfm.reconstruct(new.W, K).errors(seq.shapes)["e3d"]
                fact += [e_new, t_new, new.n_iter]
            rows.append((name, pattern, K, new.rank, e0, e_old, t_old, *fact))
            print(f"  {name} {pattern} done", file=sys.stderr, flush=True)
    print(f"\nTable 2: MoCap, {100 * args.fraction:g} % missing, seed {args.seed}, organic "
          f"at the paper's K, rank rule {args.rank}\n")
    print("| sequence | pattern | K | rank | complete e3d | soft-impute e3d (x) | s "
          "| factorisation e3d (x) | s (iterations) | factorisation, lags -1..1, e3d (x) "
          "| s (iterations) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, pat, K, r, e0, eo, to, e1, t1, n1, e2, t2, n2 in rows:
        print(f"| {name} | {pat} | {K} | {r} | {e0:.4f} | {eo:.4f} ({eo / e0:.2f}) | "
              f"{to:.1f} | {e1:.4f} ({e1 / e0:.2f}) | {t1:.1f} ({n1}) | {e2:.4f} "
              f"({e2 / e0:.2f}) | {t2:.1f} ({n2}) |")


def video_table(args):
    from data_tools.synthetic_video import make_video
    from data_tools.video import track_dense, track_sparse

    rows = []
    for surface in args.surfaces:
        v = make_video(surface, n_frames=args.video_frames, seed=args.seed)
        for kind in ("sparse", "dense"):
            t0 = time.perf_counter()
            tr = (track_sparse(v.frames, detect_every=args.detect_every) if kind == "sparse"
                  else track_dense(v.frames, step=4, detect_every=args.detect_every))
            t_track = time.perf_counter() - t0
            rows.append((surface, kind, tr, t_track, *video_runs(v, tr)))
            print(f"  {surface} {kind} done", file=sys.stderr, flush=True)
    print(f"\nTable 3: synthetic videos, {args.video_frames} frames, new tracks every "
          f"{args.detect_every} frames, K = 1; e3d over the frame-0 tracks on the surface "
          f"(late tracks have no ground truth here)\n")
    print("| video | tracks | complete | lost | late | track s | complete tracks: s, e3d "
          "| all tracks (2+ frames): factorisation s, total s | e3d on the complete tracks "
          "| e3d on the determined frame-0 tracks (n) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for surface, kind, tr, tt, tc, ec, tf, ta, ea, ed, nd in rows:
        F = tr.n_frames
        print(f"| {surface} {kind} | {tr.n_points} | {int(tr.complete.sum())} | "
              f"{int((tr.lost_at < F).sum())} | {int((tr.start > 0).sum())} | {tt:.1f} | "
              f"{tc:.1f}, {ec:.4f} | {tf:.1f}, {ta:.1f} | {ea:.4f} | {ed:.4f} ({nd}) |")


def video_runs(v, tr):
    """Complete tracks against all tracks seen in 2+ frames, on one tracked video."""
    F = tr.n_frames
    seen = np.isfinite(tr.tracks).all(axis=1).sum(axis=0) >= 2
    first = seen & (tr.start == 0)
    seq = v.sequence(tr.tracks[:, :, first])                   # frame-0 tracks on the surface
    gt, ok = seq.shapes, seq.extra["valid"]
    cols = np.flatnonzero(first)[ok]                           # tracks with ground truth
    comp = np.isfinite(seq.W).all(axis=0)
    t0 = time.perf_counter()
    rc = nrsfm.reconstruct(seq.W[:, comp], 1)
    tc = time.perf_counter() - t0
    ec = e3d(rc.shapes, gt[:, :, comp])
    late = np.flatnonzero(seen & (tr.start > 0))
    W_all = tr.W[:, np.r_[cols, late]]
    t0 = time.perf_counter()
    fc = complete_low_rank(W_all, 3)
    tf = time.perf_counter() - t0
    ra = nrsfm.reconstruct(fc.W, 1)
    ta = time.perf_counter() - t0
    n = len(cols)
    X = ra.shapes[:, :, :n]
    det = fc.determined()[:n]
    ea = e3d(X[:, :, comp], gt[:, :, comp])
    ed = e3d(X[:, :, det], gt[:, :, det])
    return tc, ec, tf, ta, ea, ed, int(det.sum())


def rank_rule(W, K, rule):
    """Rank of the factorisation: ``3K``, or ``auto``: the rank rule of ``choose_K`` on the
    mean-filled W."""
    if rule == "3K":
        return 3 * K
    from nrsfm.experiments.autok import choose_K

    filled = np.where(np.isnan(W), np.nanmean(W, axis=1, keepdims=True), W)
    return choose_K(filled)[1]["rank"]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=20000)
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--K", type=int, default=2)
    p.add_argument("--noise", type=float, default=0.005)
    p.add_argument("--lost", type=float, default=0.2)
    p.add_argument("--late", type=float, default=0.1)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--fraction", type=float, default=0.3, help="MoCap missing fraction")
    p.add_argument("--rank", default="3K", choices=["3K", "auto"])
    p.add_argument("--sequences", nargs="+", default=["drink", "pickup", "yoga", "stretch"])
    p.add_argument("--surfaces", nargs="+", default=["sheet", "face"])
    p.add_argument("--video-frames", type=int, default=100)
    p.add_argument("--detect-every", type=int, default=5)
    p.add_argument("--skip-dense", action="store_true")
    p.add_argument("--skip-video", action="store_true")
    p.add_argument("--skip-mocap", action="store_true")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)
    print(f"threads: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; timings on a "
          f"shared 2-core machine")
    if not args.skip_dense:
        dense_table(args)
    if not args.skip_mocap:
        mocap_table(args)
    if not args.skip_video:
        video_table(args)


if __name__ == "__main__":
    main()
