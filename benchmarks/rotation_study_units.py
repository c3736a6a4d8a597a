"""One answer and rotations that serve the shape (issue 18), per MoCap sequence: the default
pipeline at W x 0.7, 1, 3, 1000 (e3d of each, spread (max - min) / mean), its e_R and the
rotation set it chose for the shape, and e3d with the best single triplet's rotations
(``method="bmm"``'s rotations, default shape solver).

Example::

    OMP_NUM_THREADS=1 python benchmarks/rotation_study_units.py --data DATA drink pickup
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

UNITS = (1.0, 0.7, 3.0, 1000.0)
ROTATION_GT = ("pickup", "yoga", "stretch", "drink")


def run(names, data, units=UNITS, say=print):
    import data_tools
    import nrsfm
    from nrsfm.metrics import e3d, rotation_error

    warnings.simplefilter("ignore")
    say(f"{'sequence':9s} " + " ".join(f"{'x%g' % u:>8s}" for u in units)
        + f" {'spread':>7s} {'e_R':>7s} {'chosen':>15s} {'single e3d':>10s} {'ratio':>6s} "
          f"{'rot s':>6s}")
    rows = []
    for name in names:
        seq = data_tools.load_mocap(name, data)
        errs, first = [], None
        for u in units:
            res = nrsfm.reconstruct(seq.W * u, seq.K)
            errs.append(e3d(res.shapes, seq.shapes))
            first = first or res
        single = nrsfm.reconstruct(seq.W, seq.K, method="bmm")
        single = nrsfm.reconstruct(seq.W, seq.K, rotations=single.rotations)
        e_single = e3d(single.shapes, seq.shapes)
        eR = rotation_error(first.rotations, seq.rotations) if name in ROTATION_GT \
            else float("nan")
        chosen = first.rotation_stage.info.get("shape_selection", {}).get("chosen", "-")
        spread = (max(errs) - min(errs)) / np.mean(errs)
        rows.append(dict(sequence=name, e3d=errs, spread=spread, e_R=eR, chosen=chosen,
                         e3d_single=e_single))
        say(f"{name:9s} " + " ".join(f"{e:8.5f}" for e in errs)
            + f" {100 * spread:6.2f}% {eR:7.4f} {chosen:>15s} {e_single:10.5f} "
              f"{errs[0] / e_single:6.3f} {first.timings['rotations']:6.2f}")
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="*", default=["drink", "pickup", "yoga", "stretch",
                                                     "dance", "face", "walking", "shark"])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    a = ap.parse_args(argv)
    run(a.sequences, a.data)


if __name__ == "__main__":
    main()
