"""Shape-stage study: the paper's continuation ADMM against the bilinear solver.

Usage::

    NRSFM_DATA=/path/to/data python benchmarks/shape_study.py \
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

The ADMM's own study (not run by default; ground-truth rotations, drink pickup yoga
stretch): ``priors`` (organic / weighted / nuclear / pseudo-inverse beside the published
figures), ``N`` (paper Fig. 3d), ``admm_scale`` (its scale invariance through
``reconstruct`` and its sensitivity to the normalised scale), ``perturb`` (ground-truth
cameras perturbed by random or smooth rotations of 0.5 - 8 degrees).

Published figures come from ``nrsfm.published``.
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import numpy as np
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

import data_tools as dt
import nrsfm
from nrsfm.metrics import e3d, rotation_error
from nrsfm.published import published_value
from nrsfm.stages.shape.admm import normalization_scale
from nrsfm.stages.shape import solve_shapes
from nrsfm.stages.shape.admm import AdmmSettings, admm_iterations
from nrsfm.stages.shape.closed_form import closed_form_shapes

AKHTER4 = ("drink", "pickup", "yoga", "stretch")
SOLVERS = ("admm", "bilinear")
PRIOR_METHOD = {"organic": "organic", "weighted": "wnn", "nuclear": "bmm",
                "pseudo-inv": "pseudo_inverse"}
PAPER_COLUMN = {"organic": "ours", "weighted": "R-BMM", "nuclear": "BMM"}


def _f(x, nd=4):
    return "   -  " if x is None else f"{x:.{nd}f}"




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
        Wn = seq.W / normalization_scale(seq.W)
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


# ---- the ADMM's own study (priors, N, its scale rule, perturbed cameras) ----

def section_priors(seqs):
    print("\n== ADMM priors, ground-truth rotations (nrsfm.reconstruct(W, K, rotations=R_gt, "
          "method=...)) ==")
    head = f"{'seq':8s} {'K':>3s} " + " ".join(f"{p:>10s}" for p in PRIOR_METHOD)
    head += "   | paper (estimated rotations): " + " ".join(
            f"{PAPER_COLUMN[p]:>7s}" for p in ("organic", "weighted", "nuclear"))
    print(head)
    for name, seq in seqs.items():
        vals = []
        for prior, method in PRIOR_METHOD.items():
            rec = nrsfm.reconstruct(seq.W, seq.K, method=method, rotations=seq.rotations)
            vals.append(e3d(rec.shapes, seq.shapes))
        line = f"{name:8s} {seq.K:3d} " + " ".join(f"{v:10.4f}" for v in vals)
        line += "   |                              " + " ".join(
                f"{_f(published_value('mocap_e3d', PAPER_COLUMN[p], name)):>7s}"
                for p in ("organic", "weighted", "nuclear"))
        print(line, flush=True)


def section_N(seqs):
    print("\n== N ablation (paper Fig. 3d): organic weights, first N singular values free ==")
    Ns = range(6)
    print(f"{'seq':8s} " + " ".join(f"{'N=' + str(n):>8s}" for n in Ns))
    for name in AKHTER4:
        seq = seqs[name]
        vals = [e3d(nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations,
                                      shape_options=dict(N=n)).shapes, seq.shapes)
                for n in Ns]
        print(f"{name:8s} " + " ".join(f"{v:8.4f}" for v in vals), flush=True)


def section_admm_scale(seqs):
    print("\n== scale invariance: nrsfm.reconstruct(c * W, K, rotations=R_gt) ==")
    cs = (1e-3, 1.0, 1e3)
    print(f"{'seq':8s} " + " ".join(f"{'c=' + format(c, 'g'):>9s}" for c in cs)
          + "   max diff")
    for name in AKHTER4:
        seq = seqs[name]
        vals = [e3d(nrsfm.reconstruct(seq.W * c, seq.K, rotations=seq.rotations).shapes,
                    seq.shapes) for c in cs]
        print(f"{name:8s} " + " ".join(f"{v:9.6f}" for v in vals)
              + f"   {max(vals) - min(vals):.1e}", flush=True)
    print("\n== sensitivity: W / (m * normalization_scale(W)), organic prior ==")
    ms = (0.5, 0.7, 0.85, 1.0, 1.2, 1.4, 2.0)
    print(f"{'seq':8s} " + " ".join(f"{'m=' + format(m, 'g'):>8s}" for m in ms))
    for name in AKHTER4:
        seq = seqs[name]
        s = normalization_scale(seq.W)
        vals = [e3d(admm_iterations(seq.W / (m * s), seq.rotations, seq.K, "organic", AdmmSettings()).shapes, seq.shapes)
                for m in ms]
        print(f"{name:8s} " + " ".join(f"{v:8.4f}" for v in vals), flush=True)


def perturbed(R, deg, seed):
    rng = np.random.default_rng(seed)
    axis = rng.standard_normal((R.shape[0], 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return R @ Rotation.from_rotvec(axis * np.deg2rad(deg)).as_matrix()


def smoothly_perturbed(R, deg, seed):
    """R_f E_f with E_f = exp(v_f), v_f three sinusoids (period F/3, random phases)."""
    rng = np.random.default_rng(seed)
    F = R.shape[0]
    t = np.arange(F)
    v = np.stack([np.sin(2 * np.pi * t / (F / 3) + p) for p in rng.uniform(0, 2 * np.pi, 3)],
                 axis=1)
    return R @ Rotation.from_rotvec(v * np.deg2rad(deg)).as_matrix()


def section_perturb(seqs, seeds=2):
    degs = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0)
    for kind, fn in (("independent random", perturbed), ("smooth (sinusoidal)",
                                                           smoothly_perturbed)):
        _perturb_table(seqs, degs, kind, fn, seeds)


def _perturb_table(seqs, degs, kind, fn, seeds):
    print(f"\n== ground-truth rotations perturbed per frame by {kind} rotations of the given "
          f"size (mean of {seeds} seeds); organic prior ==")
    print(f"{'seq':8s} " + " ".join(f"{format(g, 'g') + ' deg':>9s}" for g in degs))
    for name in AKHTER4:
        seq = seqs[name]
        s = normalization_scale(seq.W)
        e_vals, r_vals = [], []
        for g in degs:
            runs = [0] if g == 0 else range(seeds)
            e, er = [], []
            for seed in runs:
                R = fn(seq.rotations, g, seed)
                e.append(e3d(admm_iterations(seq.W / s, R, seq.K, "organic", AdmmSettings()).shapes, seq.shapes))
                er.append(rotation_error(R, seq.rotations))
            e_vals.append(np.mean(e))
            r_vals.append(np.mean(er))
        print(f"{name:8s} " + " ".join(f"{v:9.4f}" for v in e_vals), flush=True)
        print(f"{'  e_R':8s} " + " ".join(f"{v:9.4f}" for v in r_vals), flush=True)



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
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    ap.add_argument("--sections", nargs="+",
                    default=["synthetic", "gt", "noise", "time", "dense"],
                    choices=["synthetic", "gt", "noise", "time", "stability", "dense",
                             "priors", "N", "admm_scale", "perturb"])
    ap.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=list(SOLVERS))
    ap.add_argument("--sequences", nargs="+", default=list(dt.MOCAP_NAMES),
                    help="sequences for the stability section")
    args = ap.parse_args(argv)
    needs_data = set(args.sections) & {"gt", "noise", "time", "stability", "priors", "N",
                                       "admm_scale", "perturb"}
    if needs_data and not args.data:
        ap.error("no data folder: pass --data or set NRSFM_DATA")
    mocap = args.data
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
            elif sec == "priors":
                section_priors(seqs)
            elif sec == "N":
                section_N(seqs)
            elif sec == "admm_scale":
                section_admm_scale(seqs)
            elif sec == "perturb":
                section_perturb(seqs)


if __name__ == "__main__":
    main()
