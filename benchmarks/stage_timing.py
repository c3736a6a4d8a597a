"""Time per stage of the organic pipeline (median of several runs, one BLAS thread).

    OPENBLAS_NUM_THREADS=1 NRSFM_DATA=/path/to/data python benchmarks/stage_timing.py \
        [--sequences pickup drink] [--repeats 5] [--shape-solver admm] [--given-rotations]

Prints the pipeline's own stage timers (``Reconstruction.timings`` and the rotation stage's
``timings``) as medians, also in units of one thin SVD of a 357 x 123 matrix (the size of
pickup's X#) timed in the same process (the issues' unit: a ratio moves much less than
seconds on a shared machine): the first bracket over the unit timed once at the start,
as the issues measure it; the second over the unit timed again just before each run (the
median of 15 SVDs), the median over the runs of each run's ratio. The two differ: timed
beside the runs the unit reads 15 - 25 % less than at the start of the process (3.3 - 3.9
ms against 4.0 - 4.8 ms in three calls), so the second ratios are that much higher. Then
the paper's reported pickup timings (from
``nrsfm/data/published.json`` through :mod:`nrsfm.published`).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import data_tools as dt
import nrsfm
from nrsfm.published import published_value


def svd_unit(repeats=40):
    """Median seconds of one thin SVD of a seeded 357 x 123 Gaussian matrix."""
    A = np.random.default_rng(0).standard_normal((357, 123))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.linalg.svd(A, full_matrices=False)
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data",
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    ap.add_argument("--sequences", nargs="+", default=["pickup", "drink"])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--shape-solver", default="bilinear", help="shape solver (default bilinear)")
    ap.add_argument("--given-rotations", action="store_true",
                    help="the ground-truth rotations: the shape stage alone")
    args = ap.parse_args(argv)
    mocap = args.data
    unit = svd_unit()
    print(f"one thin SVD of 357 x 123: {1e3 * unit:.2f} ms (the unit of the first brackets; "
          f"the second: each run's stage time over the unit timed just before it, median)")
    for name in args.sequences:
        seq = dt.load_mocap(name, mocap)
        stages, totals, units = {}, [], []
        for _ in range(args.repeats):
            units.append(svd_unit(repeats=15))
            t0 = time.perf_counter()
            res = nrsfm.reconstruct(seq.W, seq.K, shape_solver=args.shape_solver,
                                    rotations=seq.rotations if args.given_rotations else None)
            totals.append(time.perf_counter() - t0)
            for k, v in res.timings.items():
                stages.setdefault(k, []).append(v)
            for k, v in (res.rotation_stage.timings if res.rotation_stage else {}).items():
                stages.setdefault("rotations/" + k, []).append(v)
        print(f"{name} (F={seq.n_frames}, K={seq.K}), median of {args.repeats} runs, seconds")
        for k, v in stages.items():
            beside = np.median(np.divide(v, units))
            print(f"  {k:28s} {np.median(v):8.4f} [{np.median(v) / unit:6.0f}] [{beside:6.0f}]"
                  f"  (min {np.min(v):.4f}, max {np.max(v):.4f})")
        print(f"  {'the unit beside the runs':28s} {np.median(units):8.4f}  (min "
              f"{np.min(units):.4f}, max {np.max(units):.4f})")
        print(f"  {'total reconstruct()':28s} {np.median(totals):8.4f}  (min {np.min(totals):.4f}, "
              f"max {np.max(totals):.4f})")
        print(f"  shape-stage iterations {res.shape_stage.n_iter}")
    t = {k: published_value("timing_reported", k) for k in (
        "pickup_registration_s", "pickup_filtering_s", "pickup_rotation_averaging_s")}
    print("paper (C++/MATLAB, pickup): registration {pickup_registration_s} s, filtering "
          "{pickup_filtering_s} s, averaging {pickup_rotation_averaging_s} s".format(**t))


if __name__ == "__main__":
    main()
