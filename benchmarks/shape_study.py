"""Shape-stage study (issue 3): the ADMM of Eq. (10)-(13) on the MoCap benchmark.

Usage::

    NRSFM_DATA=../shared/data python benchmarks/shape_study.py \
        [--data DIR] [--tables ../shared/paper/tables.json] [--sections gt N scale time]
        [--repeats 5]

Sections (all with ground-truth rotations, one BLAS thread):

``gt``       e3d per sequence for the three priors (organic PSVT N = 1, weighted N = 0,
             nuclear) and the pseudo-inverse start, through ``nrsfm.reconstruct(W, K,
             rotations=R_gt, method=...)`` (so the scale rule of :mod:`nrsfm.scale` is
             applied). Dance's ground-truth camera is fixed: depth is unobservable from it,
             so every prior stays at the pseudo-inverse there.
``N``        e3d against N = 0..5 (paper Fig. 3d) on drink, pickup, yoga, stretch.
``scale``    the same sequence at W * 1e-3, W, W * 1e3 (e3d must agree to 1e-6), and the
             e3d when the normalised scale is multiplied by 0.5 .. 2 (sensitivity).
``perturb``  ground-truth rotations perturbed by seeded random rotations of 0.5-8 degrees:
             does e3d grow with the rotation error?
``time``     median wall time of ``optimize_shapes`` on drink (1102 frames).
``pipeline`` full ``nrsfm.reconstruct(W, K)`` (estimated rotations) on the 8 sequences
             (slow: the rotation stage dominates; not run unless asked).

With ``--tables`` the published figures are printed beside ours (read from that file;
nothing published is typed into this script).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

import data_tools as dt
import nrsfm
from nrsfm.metrics import e3d, rotation_error
from nrsfm.scale import normalization_scale
from nrsfm.shape import optimize_shapes

AKHTER4 = ("drink", "pickup", "yoga", "stretch")
PRIOR_METHOD = {"organic": "organic", "weighted": "wnn", "nuclear": "bmm",
                "pseudo-inv": "pseudo_inverse"}
PAPER_COLUMN = {"organic": "ours", "weighted": "R-BMM", "nuclear": "BMM"}


def _f(x, nd=4):
    return "   -  " if x is None else f"{x:.{nd}f}"


def _paper(tables, column, name):
    if tables is None:
        return None
    return tables.get("mocap_e3d", {}).get(column, {}).get(name)


def section_gt(seqs, tables):
    print("\n== e3d with ground-truth rotations (nrsfm.reconstruct(W, K, rotations=R_gt)) ==")
    head = f"{'seq':8s} {'K':>3s} " + " ".join(f"{p:>10s}" for p in PRIOR_METHOD)
    if tables is not None:
        head += "   | paper (estimated rotations): " + " ".join(
            f"{PAPER_COLUMN[p]:>7s}" for p in ("organic", "weighted", "nuclear"))
    print(head)
    for name, seq in seqs.items():
        vals = []
        for prior, method in PRIOR_METHOD.items():
            rec = nrsfm.reconstruct(seq.W, seq.K, method=method, rotations=seq.rotations)
            vals.append(e3d(rec.shapes, seq.shapes))
        line = f"{name:8s} {seq.K:3d} " + " ".join(f"{v:10.4f}" for v in vals)
        if tables is not None:
            line += "   |                              " + " ".join(
                f"{_f(_paper(tables, PAPER_COLUMN[p], name)):>7s}"
                for p in ("organic", "weighted", "nuclear"))
        print(line, flush=True)


def section_N(seqs):
    print("\n== N ablation (paper Fig. 3d): organic weights, first N singular values free ==")
    Ns = range(6)
    print(f"{'seq':8s} " + " ".join(f"{'N=' + str(n):>8s}" for n in Ns))
    for name in AKHTER4:
        if name not in seqs:
            continue
        seq = seqs[name]
        vals = [e3d(nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations,
                                      shape_options=dict(N=n)).shapes, seq.shapes)
                for n in Ns]
        print(f"{name:8s} " + " ".join(f"{v:8.4f}" for v in vals), flush=True)


def section_scale(seqs):
    print("\n== scale invariance: nrsfm.reconstruct(c * W, K, rotations=R_gt) ==")
    cs = (1e-3, 1.0, 1e3)
    print(f"{'seq':8s} " + " ".join(f"{'c=' + format(c, 'g'):>9s}" for c in cs)
          + "   max diff")
    for name in AKHTER4:
        if name not in seqs:
            continue
        seq = seqs[name]
        vals = [e3d(nrsfm.reconstruct(seq.W * c, seq.K, rotations=seq.rotations).shapes,
                    seq.shapes) for c in cs]
        print(f"{name:8s} " + " ".join(f"{v:9.6f}" for v in vals)
              + f"   {max(vals) - min(vals):.1e}", flush=True)
    print("\n== sensitivity: W / (m * normalization_scale(W)), organic prior ==")
    ms = (0.5, 0.7, 0.85, 1.0, 1.2, 1.4, 2.0)
    print(f"{'seq':8s} " + " ".join(f"{'m=' + format(m, 'g'):>8s}" for m in ms))
    for name in AKHTER4:
        if name not in seqs:
            continue
        seq = seqs[name]
        s = normalization_scale(seq.W)
        vals = [e3d(optimize_shapes(seq.W / (m * s), seq.rotations, seq.K).shapes, seq.shapes)
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
        if name not in seqs:
            continue
        seq = seqs[name]
        s = normalization_scale(seq.W)
        e_vals, r_vals = [], []
        for g in degs:
            runs = [0] if g == 0 else range(seeds)
            e, er = [], []
            for seed in runs:
                R = fn(seq.rotations, g, seed)
                e.append(e3d(optimize_shapes(seq.W / s, R, seq.K).shapes, seq.shapes))
                er.append(rotation_error(R, seq.rotations))
            e_vals.append(np.mean(e))
            r_vals.append(np.mean(er))
        print(f"{name:8s} " + " ".join(f"{v:9.4f}" for v in e_vals), flush=True)
        print(f"{'  e_R':8s} " + " ".join(f"{v:9.4f}" for v in r_vals), flush=True)


def section_time(seqs, repeats):
    if "drink" not in seqs:
        return
    seq = seqs["drink"]
    W = seq.W / normalization_scale(seq.W)
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = optimize_shapes(W, seq.rotations, seq.K)
        times.append(time.perf_counter() - t0)
    print(f"\n== time of optimize_shapes on drink (F={W.shape[0] // 2}, P={W.shape[1]}), "
          f"one BLAS thread, {repeats} runs ==")
    print(f"median {np.median(times):.3f} s (min {min(times):.3f}, max {max(times):.3f}); "
          f"{res.n_iter} iterations, converged={res.converged}")


def section_pipeline(names, mocap, tables):
    print("\n== full pipeline nrsfm.reconstruct(W, K) (estimated rotations) ==")
    for name in names:
        seq = dt.load_mocap(name, mocap)
        t0 = time.perf_counter()
        rec = nrsfm.reconstruct(seq.W, seq.K)
        secs = time.perf_counter() - t0
        err = e3d(rec.shapes, seq.shapes)
        extra = ""
        if seq.rotations is not None and name != "dance":
            extra = f" e_R {rotation_error(rec.rotations, seq.rotations):.4f}"
        paper = _paper(tables, "ours", name)
        extra += "" if paper is None else f"   paper {paper:.4f}"
        print(f"{name:8s} e3d {err:.4f}{extra}  ({secs:.1f} s)", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="folder holding mocap/ (default: $NRSFM_DATA)")
    ap.add_argument("--tables", help="tables.json with the published figures (optional)")
    ap.add_argument("--sections", nargs="+",
                    default=["gt", "N", "scale", "perturb", "time"],
                    choices=["gt", "N", "scale", "perturb", "time", "pipeline"])
    ap.add_argument("--sequences", nargs="+", default=list(AKHTER4) + ["dance"],
                    help="sequences with ground-truth rotations to use")
    ap.add_argument("--repeats", type=int, default=5, help="timing repeats")
    args = ap.parse_args(argv)
    if not args.data:
        ap.error("no data folder: pass --data or set NRSFM_DATA")
    mocap = os.path.join(args.data, "mocap")
    tables = json.load(open(args.tables)) if args.tables else None
    with threadpool_limits(limits=1):
        seqs = {n: dt.load_mocap(n, mocap) for n in args.sequences}
        seqs = {n: s for n, s in seqs.items() if s.rotations is not None}
        for sec in args.sections:
            if sec == "gt":
                section_gt(seqs, tables)
            elif sec == "N":
                section_N(seqs)
            elif sec == "scale":
                section_scale(seqs)
            elif sec == "perturb":
                section_perturb(seqs)
            elif sec == "time":
                section_time(seqs, args.repeats)
            elif sec == "pipeline":
                section_pipeline(dt.MOCAP_NAMES, mocap, tables)


if __name__ == "__main__":
    main()
