"""Does a change of the rotation stage keep its answers? ``nrsfm.reconstruct`` on the 8 MoCap
sequences at the paper's K: e3d, e_R (where ground-truth cameras move) and the rotation
stage's rotations, saved to an ``.npz``; against a saved run, the relative changes of e3d
and e_R and the largest entry difference of the rotations, as they are and after one
global alignment (``nrsfm.metrics.camera_alignment``: Dai's cost is invariant under
G -> G O, so the rotations are defined up to one global rotation).

    OPENBLAS_NUM_THREADS=1 python benchmarks/rotation_answers.py --data $NRSFM_DATA \\
        --save before.npz                      # on the code before
    OPENBLAS_NUM_THREADS=1 python benchmarks/rotation_answers.py --data $NRSFM_DATA \\
        --save after.npz --against before.npz  # on the code after

``--turns N --angle A``: instead, e3d of the pipeline when the rotation stage's answer is
turned by N seeded global rotations of angle A (rad): how much e3d moves through the
shape stage when the rotations change by a global rotation alone (e_R does not move).
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import data_tools as dt  # noqa: E402
import nrsfm  # noqa: E402
from nrsfm.metrics import camera_alignment  # noqa: E402
from nrsfm.settings import RotationSettings  # noqa: E402

MOVING_CAMERAS = ("drink", "pickup", "yoga", "stretch")


def run(seq):
    """e3d, e_R (or nan) and the rotation stage's rotations of one sequence."""
    res = nrsfm.reconstruct(seq.W, seq.K)
    err = res.errors(seq.shapes, seq.rotations if seq.name in MOVING_CAMERAS else None)
    return err["e3d"], err.get("e_R") or np.nan, res.rotation_stage.rotations


def aligned_difference(R, R0):
    """Largest entry of ``R0 - R Q`` (first two rows), Q the global alignment of R onto R0."""
    Q = camera_alignment(R, R0)
    return float(np.abs(R0[:, :2] - R[:, :2] @ Q).max())


def compare(names, now, before):
    print("| sequence | e3d before | e3d now | change | e_R before | e_R now | change | "
          "rotations, largest entry difference | after one global alignment |")
    print("|" + "---|" * 9)
    for name in names:
        e0, r0, R0 = (before[f"{name}_{k}"] for k in ("e3d", "e_R", "R"))
        e1, r1, R1 = now[name]
        rel = (lambda a, b: f"{100 * (b - a) / a:+.2f}%" if np.isfinite(a) else "-")
        fmt = (lambda x: f"{x:.5f}" if np.isfinite(x) else "-")
        print(f"| {name} | {e0:.5f} | {e1:.5f} | {rel(e0, e1)} | {fmt(r0)} | {fmt(r1)} | "
              f"{rel(r0, r1)} | {np.abs(R1 - R0).max():.1e} | {aligned_difference(R1, R0):.1e} |",
              flush=True)


def turned(names, data, n, angle):
    """e3d with the rotation stage's answer turned by n seeded global rotations."""
    estimate = RotationSettings.estimate
    turn = [np.eye(3)]

    def turned_estimate(self, *args, **kwargs):
        res = estimate(self, *args, **kwargs)
        res.rotations = res.rotations @ turn[0].T
        res.per_triplet = res.per_triplet @ turn[0].T
        return res

    RotationSettings.estimate = turned_estimate
    try:
        print(f"| sequence | e3d, the answer turned by {angle:g} rad about {n} seeded axes | "
              "spread |")
        print("|---|---|---|")
        for name in names:
            seq = dt.load_mocap(name, data)
            e = []
            for s in range(n):
                axis = Rotation.random(random_state=s).as_rotvec()
                turn[0] = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix()
                e.append(run(seq)[0])
            print(f"| {name} | {min(e):.5f} - {max(e):.5f} | "
                  f"{100 * (max(e) - min(e)) / np.mean(e):.2f}% |", flush=True)
    finally:
        RotationSettings.estimate = estimate


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequences", nargs="*", default=list(dt.MOCAP_NAMES))
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself")
    ap.add_argument("--save", help="write e3d, e_R and the rotations to this .npz")
    ap.add_argument("--against", help="compare with an .npz written by --save")
    ap.add_argument("--turns", type=int, default=0)
    ap.add_argument("--angle", type=float, default=1e-5)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    if args.turns:
        return turned(args.sequences, args.data, args.turns, args.angle)
    now = {name: run(dt.load_mocap(name, args.data)) for name in args.sequences}
    if args.save:
        np.savez(args.save, **{f"{name}_{k}": v for name, out in now.items()
                               for k, v in zip(("e3d", "e_R", "R"), out)})
    if args.against:
        compare(args.sequences, now, np.load(args.against))
    else:
        for name, (e, r, _) in now.items():
            print(f"{name}: e3d {e:.5f}, e_R {r:.5f}")


if __name__ == "__main__":
    main()
