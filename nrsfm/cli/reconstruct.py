"""``nrsfm demo`` and ``nrsfm mocap NAME``: reconstruct a built-in or benchmark sequence and
print its errors against the ground truth; the options every reconstruction command has."""

from __future__ import annotations

import os

from ..validation import check_K
from ..pipeline import METHODS, reconstruct
from ..stages.shape import SHAPE_SOLVERS
from .common import (UsageError, add_rrd_option, positive_int, print_report, rrd_path, seed,
                     write_recording)

__all__ = ["add_common_options", "save_rrd", "add_demo_command", "add_mocap_command"]


def add_common_options(p, rrd_name="NAME.rrd"):
    """``--method``, ``--shape-solver``, ``--seed``, ``--rrd [PATH]``, ``--quiet``."""
    p.add_argument("--method", choices=sorted(METHODS), default="organic",
                   help="pipeline to run (default: organic)")
    p.add_argument("--shape-solver", choices=SHAPE_SOLVERS, default="bilinear",
                   help="shape-stage solver (default: bilinear; admm: the paper's "
                        "continuation ADMM; closed_form: exact rank-K, no prior; "
                        "constrained: W fitted to within its noise)")
    p.add_argument("--seed", type=seed, default=0, help="random seed (default: 0)")
    add_rrd_option(p, rrd_name)
    p.add_argument("--quiet", action="store_true", help="no progress messages")


def save_rrd(result, path, seq=None):
    """Write the recording of ``result`` (with ground truth ``seq``) to ``path``."""
    from ..views.recording import save_recording

    write_recording(path, lambda tmp: save_recording(result, tmp, sequence=seq))
    print(f"  wrote Rerun recording {path} (open it with: rerun {path})")


def _reconstruct(seq, K, args, rotations=None):
    result = reconstruct(seq.W, K, method=args.method, seed=args.seed,
                         shape_solver=args.shape_solver, rotations=rotations,
                         progress=not args.quiet)
    print_report(result, seq)
    return result


def cmd_demo(args):
    """``nrsfm demo``: the built-in synthetic sequence."""
    from data_tools import default_sequence

    rrd = rrd_path(args, "demo.rrd")
    seq = default_sequence()
    print(f"built-in input: {seq.name}, F={seq.n_frames} frames, P={seq.n_points} points, "
          f"K={seq.K}, smooth camera, no noise")
    result = _reconstruct(seq, seq.K, args)
    if rrd is not None:
        save_rrd(result, rrd, seq)
    return 0


def add_demo_command(sub):
    p = sub.add_parser("demo", help="reconstruct the built-in synthetic sequence and print "
                                    "its errors against ground truth",
                       epilog="--rrd without PATH writes out/demo.rrd under the current "
                              "folder (or $NRSFM_OUT/demo.rrd).")
    add_common_options(p, "demo.rrd")
    p.set_defaults(func=cmd_demo)


def cmd_mocap(args):
    """``nrsfm mocap NAME``: a MoCap benchmark sequence."""
    from data_tools import MOCAP_NAMES, load_mocap

    if args.name not in MOCAP_NAMES:
        raise UsageError(f"unknown MoCap sequence {args.name!r}; expected one of "
                         f"{', '.join(MOCAP_NAMES)}")
    if args.data is None and not os.environ.get("NRSFM_DATA"):
        raise UsageError("no data folder: pass --data DIR or set NRSFM_DATA (the folder "
                         "that holds mocap/, or mocap/ itself)")
    rrd = rrd_path(args, f"{args.name}.rrd")
    seq = load_mocap(args.name, args.data)
    K = args.K if args.K is not None else seq.K
    K = check_K(K, seq.n_frames, seq.n_points)
    if args.given_rotations and seq.rotations is None:
        raise UsageError(f"--given-rotations: {args.name} has no ground-truth rotations "
                         "(its rigid motion is inside the shapes)")
    result = _reconstruct(seq, K, args, seq.rotations if args.given_rotations else None)
    if rrd is not None:
        save_rrd(result, rrd, seq)
    return 0


def add_mocap_command(sub):
    p = sub.add_parser("mocap", help="reconstruct a MoCap benchmark sequence",
                       epilog="--rrd without PATH writes out/NAME.rrd under the current "
                              "folder (or $NRSFM_OUT/NAME.rrd).")
    p.add_argument("name", help="drink, pickup, yoga, stretch, dance, face, walking, shark")
    p.add_argument("--data", metavar="DIR",
                   help="the folder that holds mocap/ with the .mat files, or mocap/ itself "
                        "(default: $NRSFM_DATA, either form too)")
    p.add_argument("--K", type=positive_int, help="override the paper's K")
    p.add_argument("--given-rotations", action="store_true",
                   help="use ground-truth rotations (shape stage only)")
    add_common_options(p)
    p.set_defaults(func=cmd_mocap)
