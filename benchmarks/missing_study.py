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
   e3d of complete data, of the current soft-impute completion, and of the factorisation.

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
            t0 = time.perf_counter()
            new = complete_low_rank(Wm, rank_rule(Wm, K, args.rank))
            t_new = time.perf_counter() - t0
            e_new = nrsfm.reconstruct(new.W, K).errors(seq.shapes)["e3d"]
            rows.append((name, pattern, K, new.rank, e0, e_old, t_old, e_new, t_new))
            print(f"  {name} {pattern} done", file=sys.stderr, flush=True)
    print(f"\nTable 2: MoCap, {100 * args.fraction:g} % missing, seed {args.seed}, organic "
          f"at the paper's K, rank rule {args.rank}\n")
    print("| sequence | pattern | K | rank | complete e3d | soft-impute e3d (x) | s "
          "| factorisation e3d (x) | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, pat, K, r, e0, eo, to, en, tn in rows:
        print(f"| {name} | {pat} | {K} | {r} | {e0:.4f} | {eo:.4f} ({eo / e0:.2f}) | "
              f"{to:.1f} | {en:.4f} ({en / e0:.2f}) | {tn:.1f} |")


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
    p.add_argument("--skip-dense", action="store_true")
    p.add_argument("--skip-mocap", action="store_true")
    args = p.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)
    print(f"threads: OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; timings on a "
          f"shared 2-core machine")
    if not args.skip_dense:
        dense_table(args)
    if not args.skip_mocap:
        mocap_table(args)


if __name__ == "__main__":
    main()
