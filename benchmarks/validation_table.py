"""Validation table beyond the MoCap benchmark: e3d (and e_R) per method on re-projected data.

Rows are (sequence, camera path, noise): the ground-truth shapes of a MoCap sequence (or
of an external real sequence, see ``docs/validation_data.md``) re-projected by a camera
path of :mod:`data_tools.reprojection` with Gaussian noise of std ``noise`` x the mean row
std of W. Columns are methods, each a callable ``method(seq) -> (shapes, rotations)``:

``gt:<solver>``    ``nrsfm.reconstruct(W, K, rotations=R_gt, shape_solver=<solver>)``
                   (the shape stage alone; ``--solvers``)
``full:<solver>``  ``nrsfm.reconstruct(W, K, shape_solver=<solver>)`` (``--full``); e_R is
                   printed beside e3d.
``select:<solver>`` the same with the shape solved in full for both rotation candidates
                   and the lower objective kept (``ShapeSettings.select_rotations=True``;
                   ``--select``).
``full:bmm``       the BMM baseline through the whole pipeline
                   (``nrsfm.reconstruct(W, K, method="bmm")``; ``--bmm``).

New methods: add a callable to :data:`METHODS` (or call :func:`register`). A ``*`` after a
figure marks a run that raised an ``nrsfm.NRSfMWarning``. K is the paper's K for MoCap
sequences and the documented suggestion for external ones; nothing else is set per row.

Example::

    OPENBLAS_NUM_THREADS=1 python benchmarks/validation_table.py --data $NRSFM_DATA \\
        --sequences pickup stretch drink --paths original smooth62 smooth145 smooth180 \\
        fast random --noise 0 0.02 --solvers bilinear admm
    python benchmarks/validation_table.py --external-data /path/to/extdata \\
        --sequences back hulk --solvers bilinear admm --full
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
import warnings

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import data_tools as dt  # noqa: E402
import nrsfm  # noqa: E402

DEFAULT_PATHS = ["original", "smooth62", "smooth145", "smooth180", "fast", "random"]

#: method name -> callable(seq) -> (shapes (F, 3, P), rotations (F, 3, 3) or None)
METHODS = {}


def register(name, method):
    """Add a method column: ``method(seq) -> (shapes, rotations or None)``."""
    METHODS[name] = method
    return method


def shape_stage(solver):
    """Method: ground-truth rotations, shape solver ``solver`` of ``nrsfm.reconstruct``."""
    def run(seq):
        rec = nrsfm.reconstruct(seq.W, seq.K, rotations=seq.rotations, shape_solver=solver)
        return rec.shapes, None
    return run


def full_pipeline(solver, select=False):
    """Method: the whole pipeline (rotations estimated) with shape solver ``solver``;
    ``select=True``: the shape solved in full for both rotation candidates, the lower
    objective kept (``ShapeSettings.select_rotations=True``; the default solves once)."""
    settings = nrsfm.settings.method_settings("organic", shape_solver=solver)
    if select:
        settings = dataclasses.replace(
            settings, shape=dataclasses.replace(settings.shape, select_rotations=True))

    def run(seq):
        rec = nrsfm.reconstruct(seq.W, seq.K, settings=settings)
        return rec.shapes, rec.rotations
    return run


def bmm_pipeline(seq):
    """Method: the BMM baseline (its rotations and its nuclear-norm shape stage)."""
    rec = nrsfm.reconstruct(seq.W, seq.K, method="bmm")
    return rec.shapes, rec.rotations


def evaluate(method, seq):
    """(e3d, e_R or None, warned, seconds) of one method on one sequence."""
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", nrsfm.NRSfMWarning)
        shapes, R = method(seq)
    seconds = time.perf_counter() - t0
    warned = any(issubclass(w.category, nrsfm.NRSfMWarning) for w in caught)
    e_R = nrsfm.rotation_error(R, seq.rotations) if R is not None else None
    return nrsfm.e3d(shapes, seq.shapes), e_R, warned, seconds


def loader(data, external):
    """``name -> Sequence`` over the MoCap folder and the external-data folder."""
    def load(name):
        if name in dt.EXTERNAL:
            return dt.load_external(name, external)
        return dt.load_mocap(name, data)
    return load


def cell(result):
    e, e_R, warned, _ = result
    mark = "*" if warned else ""
    return f"{e:.4f}{mark}" if e_R is None else f"{e:.4f} / {e_R:.3f}{mark}"


def print_table(rows, names, results, times):
    """Markdown table: one line per row, one column per method."""
    head = ["sequence", "path", "turn", "noise"] + [
        n + (" e3d / e_R" if n.startswith(("full:", "select:")) else " e3d") for n in names]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for seq, res in zip(rows, results):
        x = seq.extra
        print(f"| {x['source']} | {x['path']} | {x['turn']:.0f} | {x['noise']:g} | "
              + " | ".join(cell(res[n]) for n in names) + " |")
    print("\nTotal seconds per method (one BLAS thread; shared machine, indicative): "
          + ", ".join(f"{n} {times[n]:.1f}" for n in names))


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("NRSFM_DATA"),
                    help="the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)")
    ap.add_argument("--external-data", default=os.environ.get("NRSFM_EXTERNAL_DATA"),
                    help="folder of the external sequences (default $NRSFM_EXTERNAL_DATA)")
    ap.add_argument("--sequences", nargs="+", default=["pickup", "stretch", "drink"],
                    help=f"MoCap names or external names {sorted(dt.EXTERNAL)}")
    ap.add_argument("--paths", nargs="+", default=DEFAULT_PATHS,
                    help="camera paths: original, smooth<deg>, fast[<deg>], random")
    ap.add_argument("--noise", nargs="+", type=float, default=[0.0, 0.02])
    ap.add_argument("--solvers", nargs="+", default=["bilinear", "admm"],
                    help="shape solvers run with ground-truth rotations (gt:<solver>)")
    ap.add_argument("--full", action="store_true",
                    help="also run the whole pipeline per solver (full:<solver>)")
    ap.add_argument("--select", action="store_true",
                    help="also run the pipeline choosing between rotation candidates by the "
                         "shape objective (select:<solver>)")
    ap.add_argument("--bmm", action="store_true",
                    help="also run the BMM baseline through the pipeline (full:bmm)")
    ap.add_argument("--seed", type=int, default=0)
    return ap.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    for s in args.solvers:
        register(f"gt:{s}", shape_stage(s))
        if args.full:
            register(f"full:{s}", full_pipeline(s))
        if args.select:
            register(f"select:{s}", full_pipeline(s, select=True))
    if args.bmm:
        register("full:bmm", bmm_pipeline)
    names = list(METHODS)
    spec = [(q, p, z) for q in args.sequences for p in args.paths for z in args.noise]
    rows = dt.validation_set(spec, loader(args.data, args.external_data), seed=args.seed)
    results, times = [], dict.fromkeys(names, 0.0)
    for seq in rows:
        res = {n: evaluate(METHODS[n], seq) for n in names}
        for n in names:
            times[n] += res[n][3]
        results.append(res)
        print(f"{seq.name}: " + ", ".join(f"{n} {cell(res[n])}" for n in names),
              file=sys.stderr, flush=True)
    print_table(rows, names, results, times)


if __name__ == "__main__":
    main()
