"""How low e3d over all points can go on the dense case (issue 24, acceptance 3): an oracle.

The dense case of ``benchmarks/missing_study.py`` (20,000 points x 100 frames, K = 2, 20 %
of the tracks lost, 10 % late) is a random shape basis: ``X_f = R_f sum_k c_fk S_k``, every
point's basis coefficients ``S_k[:, p]`` drawn independently (N(0, diag(1, .8, .6)^2), x .4
for k >= 2). A track seen in n frames gives 2n equations for its 3K = 6 coefficients, so
one seen in 2 frames is not determined by any data, and one seen in 3 - 5 frames barely.
The oracle knows everything but the basis: the true rotations, the true coefficients, the
generator's prior and the noise-free measurements; it fills each track's unseen frames
with the posterior mean of its coefficients (the least expected squared error there) and
keeps every seen position exact. No method that sees only W does better in expectation.

    python benchmarks/dense_oracle.py [--seeds 0 1 2 3]
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from missing_study import dense_sequence  # noqa: E402

import nrsfm  # noqa: E402


def oracle_fill(shapes_cam, observed, model):
    """(F, 3, P) the camera-frame shapes with each track's unseen frames replaced by the
    posterior mean of its basis coefficients given its seen (x, y)."""
    R, c = model["rotations"], model["coefficients"]
    F, K = c.shape
    Bf = np.einsum("fij,fk->fikj", R, c).reshape(F, 3, 3 * K)       # columns (k, j)
    S0 = np.diag(model["basis_std"].ravel() ** 2)                     # (k, j) as Bf
    est = shapes_cam.copy()
    for p in np.flatnonzero(~observed.all(axis=0)):
        s = observed[:, p]
        A = Bf[s, :2].reshape(-1, 3 * K)
        G = A @ S0 @ A.T + 1e-10 * np.eye(A.shape[0])              # noise-free limit
        est[~s, :, p] = Bf[~s] @ (S0 @ A.T @ np.linalg.solve(G, shapes_cam[s, :2, p].ravel()))
    return est


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3])
    args = ap.parse_args(argv)
    print("| seed | oracle e3d, all points | tracks seen in 2 frames | in 3 - 5 |")
    print("|---|---|---|---|")
    for seed in args.seeds:
        _, observed, gt, model = dense_sequence(20000, 100, 2, 0.005, 0.2, 0.1, seed, True)
        est = oracle_fill(model["camera_shapes"], observed, model)
        n = observed.sum(axis=0)
        e = nrsfm.e3d(est - est.mean(axis=2, keepdims=True), gt)
        print(f"| {seed} | {e:.4f} | {np.sum(n == 2)} | {np.sum((n >= 3) & (n <= 5))} |")


if __name__ == "__main__":
    main()
