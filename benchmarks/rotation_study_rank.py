"""W of numerical rank below 3K (issue 18): rigid plus planar deformation, and K above the
true K, on noise-free synthetic data with W in several units. Prints e_R and e3d per run.

Example::

    OMP_NUM_THREADS=1 python benchmarks/rotation_study_rank.py
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

UNITS = (0.7, 1.0, 3.0)


def rigid_plus_planar(F=200, P=60, seed=0):
    """Rigid body plus one planar deformation mode (z = 0): W of rank 5."""
    import data_tools

    seq = data_tools.make_synthetic(F=F, P=P, K=2, seed=seed)
    B = seq.extra["basis"].copy()
    B[1, 2] = 0.0
    world = np.einsum("fk,kip->fip", seq.extra["coefficients"], B)
    cam = seq.rotations @ world
    return data_tools.Sequence(name="rigid+planar", W=cam[:, :2].reshape(2 * F, P),
                               shapes=cam, rotations=seq.rotations, K=2, world_shapes=world)


def cases(F=200, P=60):
    """(label, sequence, K used) for every case of the study."""
    import data_tools

    out = []
    seq = rigid_plus_planar(F, P)
    for K in (2, 3):
        out.append((f"rigid+planar K={K}", seq, K))
    for K_true in (1, 2, 3):
        seq = data_tools.make_synthetic(F=F, P=P, K=K_true, seed=K_true)
        for extra in (1, 2):
            out.append((f"true K={K_true}, K={K_true + extra}", seq, K_true + extra))
    return out


def run(F=200, P=60, units=UNITS, say=print):
    import nrsfm
    from nrsfm.metrics import e3d, rotation_error

    rows = []
    say(f"{'case':26s} {'units':>6s} {'rank':>4s} {'e_R':>9s} {'e3d':>9s} {'warn':>4s} "
        f"{'time':>6s}")
    for label, seq, K in cases(F, P):
        for c in units:
            t0 = time.perf_counter()
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                res = nrsfm.reconstruct(seq.W * c, K)
            dt = time.perf_counter() - t0
            warned = any(issubclass(w.category, nrsfm.NRSfMWarning) for w in caught)
            eR = rotation_error(res.rotations, seq.rotations)
            e = e3d(res.shapes, seq.shapes)
            rank = res.diagnostics.signals["numerical_rank"]
            rows.append(dict(case=label, units=c, rank=rank, e_R=eR, e3d=e, warned=warned))
            say(f"{label:26s} {c:6g} {rank:4d} {eR:9.2e} {e:9.2e} {str(warned):>4s} "
                f"{dt:6.2f}")
    worst_R = max(r["e_R"] for r in rows)
    worst_3d = max(r["e3d"] for r in rows)
    say(f"worst e_R {worst_R:.2e} (target <= 1e-5), worst e3d {worst_3d:.2e} "
        f"(target <= 1e-3)")
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--points", type=int, default=60)
    a = ap.parse_args(argv)
    run(a.frames, a.points)


if __name__ == "__main__":
    main()
