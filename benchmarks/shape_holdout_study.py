"""Study for issue 22: choose the ADMM's weight mu by held-out entries of W (no constant
fitted to any sequence): hide 10 % of the (frame, point) entries at random, solve the shape
stage with the masked data term (``solve_shape(..., observed=)``) for each mu of a grid, and
keep the mu whose shapes predict the hidden entries best (RMS of ``R_f X_fp - W_fp``). Printed
beside the mu that gives the lowest e3d on the complete W (the oracle) and both e3d.

    OPENBLAS_NUM_THREADS=1 python benchmarks/shape_holdout_study.py --data $NRSFM_DATA \
        --external-data $NRSFM_DATA/external
"""

import argparse
import os
import sys
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import data_tools as dt  # noqa: E402
import nrsfm  # noqa: E402
from nrsfm.stages.measurement import measure  # noqa: E402
from nrsfm.stages.shape import ShapeSettings, solve_shape  # noqa: E402
from nrsfm.stages.shape.admm import AdmmSettings  # noqa: E402

MUS = (1, 3, 10, 30, 100, 300, 1000)
HELD_OUT = 0.1


def rows(data, external):
    """(name, sequence, noise sigma) of the study."""
    p = dt.load_mocap("pickup", data)
    yield "pickup", p, 0.0
    yield "pickup", p, 0.05
    yield "pickup", p, 0.10
    yield "drink", dt.load_mocap("drink", data), 0.05
    back = dt.load_external("back", external)
    yield "back, random camera", dt.reproject(back, "random", 0.0, seed=0), 0.05
    yield "synthetic rank 3", dt.make_synthetic(F=150, P=60, K=3, motion="random", seed=5), 0.05


def held_out_error(Wn, R, K, mu, held):
    """RMS error of the masked solve's prediction of the held-out entries."""
    F, P = Wn.shape[0] // 2, Wn.shape[1]
    res = solve_shape(Wn, R, K, ShapeSettings(solver=AdmmSettings(mu=float(mu))),
                      observed=~held)
    d = (R[:, :2] @ res.shapes - Wn.reshape(F, 2, P))[np.repeat(held[:, None], 2, axis=1)]
    return float(np.sqrt(np.mean(d ** 2)))


def study(name, seq, sigma):
    W = dt.add_noise(seq.W, sigma, seed=0) if sigma else seq.W
    Wn = measure(W, seq.K).Wn
    held = np.random.default_rng(1).random((Wn.shape[0] // 2, Wn.shape[1])) < HELD_OUT
    cv = [held_out_error(Wn, seq.rotations, seq.K, mu, held) for mu in MUS]
    e3 = [nrsfm.e3d(solve_shape(Wn, seq.rotations, seq.K, ShapeSettings(
        solver=AdmmSettings(mu=float(mu)))).shapes, seq.shapes) for mu in MUS]
    i, j = int(np.argmin(cv)), int(np.argmin(e3))
    return (f"| {name} | {sigma:.2f} | {MUS[i]} | {MUS[j]} | {e3[i]:.4f} | {e3[j]:.4f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself")
    ap.add_argument("--external-data", default=os.environ.get("NRSFM_EXTERNAL_DATA"),
                    help="folder of the external sequences (back)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    print("| data | sigma | mu by held-out entries | mu by e3d (oracle) | e3d at the held-out "
          "mu | e3d at the oracle mu |")
    print("|" + "---|" * 6)
    for name, seq, sigma in rows(args.data, args.external_data):
        print(study(name, seq, sigma), flush=True)


if __name__ == "__main__":
    main()
