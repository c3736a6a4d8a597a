"""Study for issue 22: which weight mu of the paper's ADMM is best as the noise grows,
whether it follows today's noise estimate of W, and whether held-out entries of W find it.

For each sequence and noise level (Gaussian, std sigma x the mean row std of W, seed 0),
with the ground-truth rotations: the noise estimate ``nr`` (the RMS of W beyond rank 3K as
a fraction of W's RMS, :func:`nrsfm.noise.noise_level`), e3d of
``shape_solver="admm", shape_options=dict(mu=m)`` on a grid of m, the best m, the m of the
trial law ``max(1, 42000 nr^2)`` (read off pickup and stretch), and the default's e3d.

    OPENBLAS_NUM_THREADS=1 python benchmarks/shape_weight_study.py --data $NRSFM_DATA \
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
from nrsfm.noise import noise_level  # noqa: E402
from nrsfm.stages.measurement import measure  # noqa: E402
from nrsfm.stages.shape import ShapeSettings, solve_shape  # noqa: E402
from nrsfm.stages.shape.admm import AdmmSettings  # noqa: E402

MUS = (1, 3, 10, 30, 100, 300, 1000)
SIGMAS = (0.0, 0.02, 0.05, 0.10)


def sequences(data, external):
    """drink, yoga, back and pickup re-projected by a random camera, a synthetic rank-3."""
    yield dt.load_mocap("drink", data)
    yield dt.load_mocap("yoga", data)
    yield dt.reproject(dt.load_external("back", external), "random", 0.0, seed=0)
    yield dt.make_synthetic(F=150, P=60, K=3, motion="random", seed=5, name="synthetic-random")
    yield dt.reproject(dt.load_mocap("pickup", data), "random", 0.0, seed=0)


def row(seq, sigma):
    W = dt.add_noise(seq.W, sigma, seed=0) if sigma else seq.W
    nr = noise_level(W, seq.K) / np.sqrt(np.mean(W ** 2))
    es = [nrsfm.e3d(nrsfm.reconstruct(W, seq.K, rotations=seq.rotations, shape_solver="admm",
                                      shape_options=dict(mu=float(m))).shapes, seq.shapes)
          for m in MUS]
    default = nrsfm.e3d(nrsfm.reconstruct(W, seq.K, rotations=seq.rotations).shapes,
                        seq.shapes)
    return (f"| {seq.name} | {sigma:.2f} | {nr:.4f} | {max(1, 42000 * nr * nr):.1f} | "
            f"{MUS[int(np.argmin(es))]} | " + " | ".join(f"{e:.4f}" for e in es)
            + f" | {default:.4f} |")


HELD_OUT = 0.1


def held_out_rows(data, external):
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


def held_out_row(name, seq, sigma):
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
    ap.add_argument("--held-out", action="store_true",
                    help="choose mu by held-out entries of W (see the module docstring)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    if args.held_out:
        print("| data | sigma | mu by held-out entries | mu by e3d (oracle) | e3d at the "
              "held-out mu | e3d at the oracle mu |")
        print("|" + "---|" * 6)
        for name, seq, sigma in held_out_rows(args.data, args.external_data):
            print(held_out_row(name, seq, sigma), flush=True)
        return
    print("| data | sigma | nr | law mu | best mu | " + " | ".join(f"mu {m}" for m in MUS)
          + " | default |")
    print("|" + "---|" * (6 + len(MUS)))
    for seq in sequences(args.data, args.external_data):
        for sigma in SIGMAS:
            print(row(seq, sigma), flush=True)


if __name__ == "__main__":
    main()
