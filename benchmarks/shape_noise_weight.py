"""The bilinear shape solver's noise term (issue 22): e3d against its factor ``mu_noise``.

``mu = max(mu_factor noise (sqrt(F) + sqrt(3P)), mu_noise noise^2 (F + 2P) / sigma_1)``
(:mod:`nrsfm.stages.shape.bilinear`). Rows, ground-truth rotations (the shape stage
alone): pickup and stretch at sigma .05 and .10 with the shape table's two noise seeds
(:func:`nrsfm.experiments.shape.shape_rows`), drink and yoga at sigma .05 and .10 (seed 0),
and with ``--external-data`` the external real sets re-projected by three camera paths at
noise 0, .02 and .05 (:func:`data_tools.reproject`, seed 0). Columns: ``mu_noise`` values
(``shape_options=dict(mu_noise=c)``), e3d, and each as a multiple of the default's.

    OPENBLAS_NUM_THREADS=1 python benchmarks/shape_noise_weight.py --data DATA \\
        [--external-data DATA/external] [--factors 3 4 5 6]
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

import numpy as np

import data_tools as dt
import nrsfm
from nrsfm.experiments.shape import _row_sequence, row_label, shape_rows
from nrsfm.stages.shape.bilinear import BilinearSettings

EXTERNAL = ("kinect_paper", "hulk", "tshirt", "back")
PATHS = ("random", "smooth62", "original")


def rows(data, external):
    """[(label, Sequence)] of the study (noise seeds of one label share it)."""
    out = [(row_label(r), _row_sequence(r, data)[0])
           for r in shape_rows() if r["kind"] == "noise"]
    for name in ("drink", "yoga"):
        seq = dt.load_mocap(name, data)
        out += [(f"{name} sigma {s:.2f}", dataclasses.replace(seq, W=dt.add_noise(seq.W, s)))
                for s in (0.05, 0.10)]
    for name in EXTERNAL if external else ():
        seq = dt.load_external(name, external)
        out += [(f"{name} {p} {s:g}", dt.reproject(seq, p, s, seed=0))
                for p in PATHS for s in (0.0, 0.02, 0.05)]
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", help="the folder that holds mocap/ (default: $NRSFM_DATA)")
    ap.add_argument("--external-data", help="the folder of the external sets (optional)")
    ap.add_argument("--factors", nargs="+", type=float, default=[3.0, 4.0, 5.0, 6.0])
    args = ap.parse_args(argv)
    default = BilinearSettings().mu_noise
    table = {}
    for label, seq in rows(args.data, args.external_data):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            e = [nrsfm.e3d(nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations,
                                             shape_options=dict(mu_noise=c)).shapes,
                           seq.shapes) for c in [default] + args.factors]
        table.setdefault(label, []).append(e)
    print(f"| data | default (mu_noise {default:g}) | "
          + " | ".join(f"mu_noise {c:g}" for c in args.factors) + " |")
    print("|---" * (len(args.factors) + 2) + "|")
    for label, e in table.items():
        m = np.mean(e, axis=0)
        print(f"| {label} | {m[0]:.4f} | "
              + " | ".join(f"{x:.4f} ({x / m[0]:.3f})" for x in m[1:]) + " |")


if __name__ == "__main__":
    main()
