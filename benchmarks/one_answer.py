"""Does the pipeline give one answer? ``nrsfm.reconstruct`` on MoCap sequences with W in
other units (x 0.7, x 3, x 1000) and with four relative perturbations of 1e-7 (seeded), e3d
of each run and the spreads ``(max - min) / mean`` (issue 22, acceptance 3: at most 0.5 %).
``--missing PATTERN``: the same with 30 % of the tracks dropped first
(``data_tools.drop_tracks(W, 0.3, seed=31, pattern=PATTERN)``; NaN stays NaN), the path of
the completion and the neighbour fill (issue 24).

    OPENBLAS_NUM_THREADS=1 python benchmarks/one_answer.py --data $NRSFM_DATA [SEQ ...] \\
        [--shape-solver NAME] [--fixed-rotations] [--missing lost|late|block|uniform]
"""

import argparse
import os
import sys
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import data_tools as dt  # noqa: E402
import nrsfm  # noqa: E402

UNITS = (1.0, 0.7, 3.0, 1000.0)
PERTURBATION = 1e-7


def runs(seq, W, solver, rotations):
    """e3d for each unit and each perturbation of W (NaN: missing)."""
    def e3d(W):
        res = nrsfm.reconstruct(W, seq.K, rotations=rotations, shape_solver=solver)
        return nrsfm.e3d(res.shapes, seq.shapes)

    units = [e3d(c * W) for c in UNITS]
    rng = np.random.default_rng(0)
    scale = PERTURBATION * np.nanmax(np.abs(W))
    perturbed = [e3d(W + scale * rng.standard_normal(W.shape)) for _ in range(4)]
    return units, perturbed


def spread(values):
    return (max(values) - min(values)) / np.mean(values)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequences", nargs="*", default=list(dt.MOCAP_NAMES))
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself")
    ap.add_argument("--shape-solver", default="bilinear")
    ap.add_argument("--fixed-rotations", action="store_true",
                    help="hold the rotations of the unperturbed run fixed (shape stage only)")
    ap.add_argument("--missing", choices=("lost", "late", "block", "uniform"),
                    help="drop 30 %% of the tracks in this pattern first (seed 31)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    print("| sequence | x1 | x0.7 | x3 | x1000 | units spread | four 1e-7 perturbations | "
          "their spread |")
    print("|" + "---|" * 8)
    for name in args.sequences:
        seq = dt.load_mocap(name, args.data)
        W = (seq.W if args.missing is None else
             dt.drop_tracks(seq.W, 0.3, seed=31, pattern=args.missing)[0])
        R = (nrsfm.reconstruct(W, seq.K, shape_solver=args.shape_solver).rotations
             if args.fixed_rotations else None)
        units, pert = runs(seq, W, args.shape_solver, R)
        print(f"| {name} | " + " | ".join(f"{e:.4f}" for e in units)
              + f" | {100 * spread(units):.2f}% | " + " ".join(f"{e:.4f}" for e in pert)
              + f" | {100 * spread(units[:1] + pert):.2f}% |", flush=True)


if __name__ == "__main__":
    main()
