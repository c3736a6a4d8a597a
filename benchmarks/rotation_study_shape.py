"""Rotations that serve the shape (issue 18): e_R and e3d (default shape solver) of the
single best triplet (``bmm``), the paper's L1 average (``organic``), the average with the
family combination (``family``, :mod:`nrsfm.research`) and the averaged rotations
projected back onto one triplet of the rank-3K factorisation (``refit``); each with the
rotation stage's own rotations (no shape selection). ``rowsp``: how far the rotations are
from the cameras of one triplet (:func:`nrsfm.research.triplets.row_space_residual`, relative;
0 = consistent with W's row space).

Example::

    OMP_NUM_THREADS=1 python benchmarks/rotation_study_shape.py --data DATA drink pickup
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

VARIANTS = {
    "bmm": ("bmm", {}),
    "organic": ("organic", {}),
    "family": ("family", {}),
    "refit": ("organic", dict(refit=True)),
}


def stage_rotations_only(method="organic", **rotation_options):
    """Typed settings of a method (or of the research strategy ``family``) with the shape
    solved for the rotation stage's own rotations (``ShapeSettings.select_rotations=False``)."""
    import dataclasses

    from nrsfm.research import research_settings
    from nrsfm.settings import RotationSettings, method_settings

    production = {f.name for f in dataclasses.fields(RotationSettings)}
    if method in RotationSettings.STRATEGIES and set(rotation_options) <= production:
        s = method_settings(method, rotation_options=rotation_options)
    else:
        s = research_settings(method, **rotation_options)
    return dataclasses.replace(s, shape=dataclasses.replace(s.shape,
                                                            select_rotations=False))


def run(names, data, variants=tuple(VARIANTS), say=print):
    import data_tools
    import nrsfm
    from nrsfm.metrics import e3d, rotation_error
    from nrsfm.research.triplets import row_space_residual

    warnings.simplefilter("ignore")
    say(f"{'sequence':9s} " + " ".join(f"{v + ' e_R':>13s} {v + ' e3d':>13s} {'rowsp':>8s} {'s':>5s}"
                                        for v in variants))
    rows = []
    for name in names:
        seq = data_tools.load_mocap(name, data)
        cells, G0 = [], None
        for v in variants:
            strategy, opts = VARIANTS[v]
            t0 = time.perf_counter()
            res = nrsfm.reconstruct(seq.W, seq.K, settings=stage_rotations_only(strategy,
                                                                                **opts))
            if G0 is None:
                G0 = res.rotation_stage.G[0]
            if strategy == "bmm":        # the bmm rotations, default shape solver
                res = nrsfm.reconstruct(seq.W, seq.K, rotations=res.rotations)
            dt = time.perf_counter() - t0
            eR = rotation_error(res.rotations, seq.rotations)
            e = e3d(res.shapes, seq.shapes)
            rs = row_space_residual(res.factorization.M_hat, res.rotations, G0)
            rows.append(dict(sequence=name, variant=v, e_R=eR, e3d=e, seconds=dt,
                             row_space=rs))
            cells.append(f"{eR:13.4f} {e:13.5f} {rs:8.4f} {dt:5.1f}")
        say(f"{name:9s} " + " ".join(cells), flush=True) if say is print else say(
            f"{name:9s} " + " ".join(cells))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sequences", nargs="*", default=["drink", "pickup", "yoga", "stretch",
                                                     "dance", "face", "walking", "shark"])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS))
    a = ap.parse_args(argv)
    folder = os.path.join(a.data, "mocap")
    run(a.sequences, folder if os.path.isdir(folder) else a.data, a.variants)


if __name__ == "__main__":
    main()
