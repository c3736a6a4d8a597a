"""Rotation and shape error under track noise on pickup (the paper's Fig. 3a-b).

    NRSFM_DATA=/path/to/data python benchmarks/noise_study.py [--sequence pickup]
        [--sigmas 0.01 0.05 0.10 0.15 0.20 0.25] [--seeds 10] [--methods organic bmm]
        [--plot docs/figures/noise_study.png]

Noise model: Gaussian on W with standard deviation sigma x (mean row standard deviation
of W), ``data_tools.add_noise(W, sigma, seed)``; the reconstruction uses the same seed.
Prints one row per sigma and method (mean and standard deviation of e_R and e3d over the
seeds, the worst e_R, the runs flagged by ``Reconstruction.diagnostics``, mean seconds) and
writes a plot of both curves with one-standard-deviation bands.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import data_tools as dt
import nrsfm


def run(seq, sigmas, seeds, methods):
    """{(method, sigma): dict of arrays e_R, e3d, seconds, flagged}."""
    out = {}
    for sigma in sigmas:
        for seed in range(seeds):
            W = dt.add_noise(seq.W, sigma, seed=seed)
            for m in methods:
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", nrsfm.NRSfMWarning)
                    res = nrsfm.reconstruct(W, seq.K, method=m, seed=seed)
                dt_s = time.perf_counter() - t0
                e = res.errors(seq.shapes, seq.rotations)
                d = out.setdefault((m, sigma), dict(e_R=[], e3d=[], seconds=[], flagged=[]))
                d["e_R"].append(e["e_R"])
                d["e3d"].append(e["e3d"])
                d["seconds"].append(dt_s)
                d["flagged"].append(res.diagnostics.flagged)
    return {k: {kk: np.array(vv) for kk, vv in v.items()} for k, v in out.items()}


def table(results, sigmas, methods):
    lines = ["| sigma | method | e_R mean | e_R std | e_R max | e3d mean | e3d std | flagged | s/run |",
             "|---|---|---|---|---|---|---|---|---|"]
    for sigma in sigmas:
        for m in methods:
            d = results[(m, sigma)]
            lines.append(f"| {sigma:.2f} | {m} | {d['e_R'].mean():.4f} | {d['e_R'].std():.4f} | "
                         f"{d['e_R'].max():.4f} | {d['e3d'].mean():.4f} | {d['e3d'].std():.4f} | "
                         f"{int(d['flagged'].sum())}/{len(d['flagged'])} | "
                         f"{d['seconds'].mean():.2f} |")
    return "\n".join(lines)


def plot(results, sigmas, methods, path, name):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for ax, key, label in zip(axes, ("e_R", "e3d"), ("$e_R$", "$e_{3d}$")):
        for m in methods:
            mu = np.array([results[(m, s)][key].mean() for s in sigmas])
            sd = np.array([results[(m, s)][key].std() for s in sigmas])
            ax.plot(sigmas, mu, marker="o", label=m)
            ax.fill_between(sigmas, mu - sd, mu + sd, alpha=0.25)
        ax.set_xlabel("noise sigma (x mean row std of W)")
        ax.set_ylabel(label)
        ax.set_title(f"{name}: {label} w.r.t. noise")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data",
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    ap.add_argument("--sequence", default="pickup")
    ap.add_argument("--sigmas", type=float, nargs="+",
                    default=[0.01, 0.05, 0.10, 0.15, 0.20, 0.25])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--methods", nargs="+", default=["organic", "bmm"])
    ap.add_argument("--plot", default="docs/figures/noise_study.png")
    args = ap.parse_args(argv)
    seq = dt.load_mocap(args.sequence, args.data)
    results = run(seq, args.sigmas, args.seeds, args.methods)
    print(f"{args.sequence} (F={seq.n_frames}, K={seq.K}), {args.seeds} seeds per sigma")
    print(table(results, args.sigmas, args.methods))
    worst = max(results[k]["e_R"].max() for k in results)
    print(f"largest e_R of any run: {worst:.4f}")
    if args.plot:
        plot(results, args.sigmas, args.methods, args.plot, args.sequence)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
