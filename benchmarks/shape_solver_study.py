"""How fast the default shape solver reaches its answer (ground-truth rotations).

    OPENBLAS_NUM_THREADS=1 NRSFM_DATA=/path/to/data python benchmarks/shape_solver_study.py \
        [--sequences pickup drink yoga stretch] [--gtol 1e-6 1e-7 1e-8 1e-9] [--repeats 3]

For each sequence the bilinear solver (the default settings but ``gtol``) runs with the
ground-truth rotations; a reference solve to a relative gradient of 1e-11 gives "the
answer". Printed per ``gtol``: L-BFGS iterations, the rank of the answer, time as a
multiple of one thin SVD of a 357 x 123 matrix timed in the same process (median of
``--repeats``), e3d, and the relative distance ``||X - X_ref|| / ||X_ref||`` to the
reference. Uses only the public API, so the same script measures older code.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import data_tools as dt
from nrsfm.metrics import e3d
from nrsfm.stages.shape.bilinear import BilinearSettings, solve_bilinear
from stage_timing import svd_unit                     # benchmarks/ (the script's folder)


def _timed(W, R, K, settings, repeats):
    """(result, median seconds, median SVD units) of ``repeats`` solves."""
    secs, units = [], []
    for _ in range(repeats):
        unit = svd_unit(10)
        t0 = time.perf_counter()
        res = solve_bilinear(W, R, K, "organic", settings)
        secs.append(time.perf_counter() - t0)
        units.append(secs[-1] / unit)
    return res, float(np.median(secs)), float(np.median(units))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", help="folder holding mocap/ (default: $NRSFM_DATA)")
    ap.add_argument("--sequences", nargs="+", default=["pickup", "drink", "yoga", "stretch"])
    ap.add_argument("--gtol", nargs="+", type=float, default=[1e-6, 1e-7, 1e-8, 1e-9])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    print("| sequence | gtol | iterations | rank | time (SVD units) | e3d | distance to the answer |")
    print("|---|---|---|---|---|---|---|")
    for name in args.sequences:
        seq = dt.load_mocap(name, args.data)
        W = seq.W - seq.W.mean(axis=1, keepdims=True)
        ref = solve_bilinear(W, seq.rotations, seq.K, "organic",
                             BilinearSettings(gtol=1e-11, max_iter=20000))
        norm = float(np.linalg.norm(ref.shapes))
        for gtol in args.gtol:
            res, _, units = _timed(W, seq.rotations, seq.K, BilinearSettings(gtol=gtol),
                                   args.repeats)
            dist = float(np.linalg.norm(res.shapes - ref.shapes)) / norm
            rank = res.params.get("live_rank", res.params.get("rank"))
            print(f"| {name} | {gtol:.0e} | {res.n_iter} | {rank} | {units:.0f} | "
                  f"{e3d(res.shapes, seq.shapes):.5f} | {dist:.1e} |")
        print(f"| {name} | reference (1e-11) | {ref.n_iter} | "
              f"{ref.params.get('live_rank', ref.params.get('rank'))} | - | "
              f"{e3d(ref.shapes, seq.shapes):.5f} | 0 |")


if __name__ == "__main__":
    main()
