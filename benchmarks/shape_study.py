"""Shape-stage study: the paper's continuation ADMM against the bilinear solver.

Usage::

    NRSFM_DATA=../shared/data python benchmarks/shape_study.py \
        [--sections synthetic gt noise time stability pipeline dense] [--solvers admm bilinear]

Sections (one BLAS thread; the figures are printed, nothing is asserted):

``synthetic``  e3d with ground-truth rotations on noise-free exactly rank-K sequences of
               ``data_tools.make_synthetic`` (K = 1..8; smooth, fast, random motion;
               global scales 1e-3, 1, 1e3; F = 60, P = max(3K + 2, 20)), per solver, and
               the closed-form rank-K solution; the worst case over motions and scales.
``gt``         e3d with ground-truth rotations on drink, pickup, yoga, stretch.
``noise``      pickup, ground-truth rotations, Gaussian noise on W of std sigma x mean row
               std of W (``data_tools.add_noise``), sigma = 0.01 .. 0.25.
``time``       wall time of the shape stage on pickup and drink (median of 3).
``stability``  full pipeline on the 8 MoCap sequences: W, and W plus four seeded draws of
               a 1e-7 relative perturbation (std 1e-7 x the RMS of W); e3d per solver (the
               rotation stage is run once per input and shared by both solvers), spread =
               (max - min) / min over the four draws, ratio to the paper for the
               unperturbed run, and the geometric mean of the ratios.
``dense``      a K = 1 sequence of 30,000 points and 100 frames: time and peak memory of
               the bilinear solver (the dense regime).

Published figures come from ``nrsfm.published``.
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import numpy as np
from threadpoolctl import threadpool_limits

import data_tools as dt
import nrsfm
import nrsfm.scale
from nrsfm.metrics import e3d
from nrsfm.published import published_value
from nrsfm.shape import solve_shapes
from nrsfm.shape_bilinear import closed_form_shapes

AKHTER4 = ("drink", "pickup", "yoga", "stretch")
SOLVERS = ("admm", "bilinear")


def _gt_e3d(seq, solver, W=None):
    W = seq.W if W is None else W
    rec = nrsfm.reconstruct(W, seq.K, rotations=seq.rotations, shape_solver=solver)
    return e3d(rec.shapes, seq.shapes), rec


def section_synthetic(solvers):
    print("\n== synthetic, noise-free, exactly rank K, ground-truth rotations: max e3d over "
          "motions (smooth, fast, random) and scales (1e-3, 1, 1e3) ==")
    print(f"{'K':>3s} {'F':>4s} {'P':>4s} " + " ".join(f"{s:>11s}" for s in solvers)
          + f" {'closed_form':>11s}")
    for K in range(1, 9):
        F, P = 60, max(3 * K + 2, 20)
        worst = {s: 0.0 for s in list(solvers) + ["closed_form"]}
        for motion in ("smooth", "fast", "random"):
            seq = dt.make_synthetic(F=F, P=P, K=K, motion=motion, seed=10 + K)
            for c in (1e-3, 1.0, 1e3):
                for s in solvers:
                    rec = nrsfm.reconstruct(c * seq.W, K, rotations=seq.rotations,
                                            shape_solver=s)
                    worst[s] = max(worst[s], e3d(rec.shapes, seq.shapes))
                worst["closed_form"] = max(worst["closed_form"], e3d(
                    closed_form_shapes(c * seq.W, seq.rotations, K), seq.shapes))
        print(f"{K:3d} {F:4d} {P:4d} " + " ".join(f"{worst[s]:11.1e}" for s in worst),
              flush=True)


def section_gt(seqs, solvers):
    print("\n== MoCap, ground-truth rotations (nrsfm.reconstruct(W, K, rotations=R_gt)) ==")
    print(f"{'seq':8s} {'K':>3s} " + " ".join(f"{s:>9s}" for s in solvers)
          + "  bilinear: iterations, rel. gradient")
    for name in AKHTER4:
        seq = seqs[name]
        vals, info = [], ""
        for s in solvers:
            e, rec = _gt_e3d(seq, s)
            vals.append(e)
            if s == "bilinear":
                st = rec.shape_stage
                info = f"  {st.n_iter}, {st.grad_norm:.1e}"
        print(f"{name:8s} {seq.K:3d} " + " ".join(f"{v:9.4f}" for v in vals) + info,
              flush=True)


def section_noise(seqs, solvers):
    seq = seqs["pickup"]
    sig = (0.0, 0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.25)
    print("\n== pickup, ground-truth rotations, Gaussian noise sigma x mean row std of W "
          "(seed 0) ==")
    print(f"{'solver':9s} " + " ".join(f"{format(s, 'g'):>7s}" for s in sig))
    for s in solvers:
        vals = [_gt_e3d(seq, s, dt.add_noise(seq.W, g, seed=0) if g else seq.W)[0]
                for g in sig]
        print(f"{s:9s} " + " ".join(f"{v:7.4f}" for v in vals), flush=True)


def section_time(seqs, solvers, repeats=3):
    print(f"\n== shape stage time (s), ground-truth rotations, median of {repeats}; "
          "machine shared with other jobs ==")
    for name in ("pickup", "drink"):
        seq = seqs[name]
        Wn = seq.W / nrsfm.scale.normalization_scale(seq.W)
        line = f"{name:8s} F={seq.n_frames:5d} P={seq.n_points:3d} K={seq.K:2d}"
        for s in solvers:
            ts = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                st = solve_shapes(Wn, seq.rotations, seq.K, solver=s)
                ts.append(time.perf_counter() - t0)
            line += f"   {s} {np.median(ts):.2f} ({st.n_iter} it)"
        print(line, flush=True)


def section_stability(mocap, solvers, names, draws=4):
    print("\n== full pipeline nrsfm.reconstruct(W, K): e3d unperturbed | 4 draws of a 1e-7 "
          "relative perturbation, spread (max-min)/min; ratio to the paper ==")
    ratios = {s: [] for s in solvers}
    for name in names:
        seq = dt.load_mocap(name, mocap)
        paper = published_value("mocap_e3d", "ours", name)
        rms = float(np.sqrt(np.mean(seq.W ** 2)))
        rows = {s: [] for s in solvers}
        t0 = time.perf_counter()
        for d in range(draws + 1):
            W = seq.W
            if d:
                W = W + 1e-7 * rms * np.random.default_rng(d).standard_normal(W.shape)
            rec = nrsfm.reconstruct(W, seq.K, shape_solver=solvers[0])
            rows[solvers[0]].append(e3d(rec.shapes, seq.shapes))
            for s in solvers[1:]:
                r2 = nrsfm.reconstruct(W, seq.K, rotations=rec.rotations, shape_solver=s)
                rows[s].append(e3d(r2.shapes, seq.shapes))
        for s in solvers:
            v = np.asarray(rows[s])
            spread = (v[1:].max() - v[1:].min()) / v[1:].min()
            ratios[s].append(v[0] / paper)
            print(f"{name:8s} {s:9s} e3d {v[0]:.4f} | " + " ".join(f"{x:.4f}" for x in v[1:])
                  + f"  spread {100 * spread:5.2f}%  paper {paper:.4f} ratio {v[0] / paper:.3f}",
                  flush=True)
        print(f"{'':8s} ({time.perf_counter() - t0:.0f} s)", flush=True)
    for s in solvers:
        r = np.asarray(ratios[s])
        print(f"{s:9s} geometric mean of e3d / paper {np.exp(np.mean(np.log(r))):.3f}; "
              f"<= 1.10 x paper on {int(np.sum(r <= 1.10))} of {r.size}")


def section_dense():
    print("\n== dense: K = 1, F = 100, P = 30,000, ground-truth rotations, bilinear ==")
    seq = dt.make_synthetic(F=100, P=30000, K=1, motion="smooth", noise=0.01, seed=0)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    t0 = time.perf_counter()
    st = solve_shapes(seq.W, seq.rotations, 1, solver="bilinear")
    secs = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    print(f"time {secs:.2f} s, {st.n_iter} iterations, rel. gradient {st.grad_norm:.1e}, "
          f"e3d {e3d(st.shapes, seq.shapes):.4f}; peak RSS {peak:.2f} GB "
          f"(before the solve {before:.2f} GB)", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="folder holding mocap/ (default: $NRSFM_DATA)")
    ap.add_argument("--sections", nargs="+",
                    default=["synthetic", "gt", "noise", "time", "dense"],
                    choices=["synthetic", "gt", "noise", "time", "stability", "dense"])
    ap.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=list(SOLVERS))
    ap.add_argument("--sequences", nargs="+", default=list(dt.MOCAP_NAMES),
                    help="sequences for the stability section")
    args = ap.parse_args(argv)
    needs_data = set(args.sections) & {"gt", "noise", "time", "stability"}
    if needs_data and not args.data:
        ap.error("no data folder: pass --data or set NRSFM_DATA")
    mocap = os.path.join(args.data, "mocap") if args.data else None
    with threadpool_limits(limits=1):
        seqs = {n: dt.load_mocap(n, mocap) for n in AKHTER4} if needs_data else {}
        for sec in args.sections:
            if sec == "synthetic":
                section_synthetic(args.solvers)
            elif sec == "gt":
                section_gt(seqs, args.solvers)
            elif sec == "noise":
                section_noise(seqs, args.solvers)
            elif sec == "time":
                section_time(seqs, args.solvers)
            elif sec == "stability":
                section_stability(mocap, args.solvers, args.sequences)
            elif sec == "dense":
                section_dense()


if __name__ == "__main__":
    main()
