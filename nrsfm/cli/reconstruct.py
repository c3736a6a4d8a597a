"""``nrsfm demo`` and ``nrsfm mocap NAME``: reconstruct a built-in or benchmark sequence and
print its errors against the ground truth; the options every reconstruction command has."""

from __future__ import annotations

import argparse
import os

from ..validation import check_K
from ..pipeline import METHODS, reconstruct
from .common import (UsageError, add_rrd_option, add_shape_solver_option, positive_int,
                     print_report, rrd_path, seed, write_recording)

__all__ = ["add_common_options", "save_rrd", "add_demo_command",
           "add_mocap_command"]


def add_common_options(p, rrd_name="NAME.rrd"):
    """``--method``, ``--shape-solver``, ``--seed``, ``--rrd [PATH]``, ``--quiet``."""
    p.add_argument("--method", choices=sorted(METHODS), default="organic",
                   help="pipeline to run (default: organic)")
    add_shape_solver_option(p)
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
    """``nrsfm demo``: the built-in synthetic sequence; ``--video``: the synthetic video."""
    if args.video:
        from .video import cmd_demo_video

        return cmd_demo_video(args)
    given = [f for f, v in (("--frames", args.frames), ("--size", args.size),
                            ("--surface", args.surface)) if v is not None]
    if given:
        raise UsageError(f"{', '.join(given)}: only with --video")
    from data_tools import default_sequence

    rrd = rrd_path(args, "demo.rrd")
    seq = default_sequence()
    print(f"built-in input: {seq.name}, F={seq.n_frames} frames, P={seq.n_points} points, "
          f"K={seq.K}, smooth camera, no noise")
    result = _reconstruct(seq, seq.K, args)
    if rrd is not None:
        save_rrd(result, rrd, seq)
    return 0


def image_size(text):
    """argparse type: ``HxW`` in pixels, each at least 32 (``--size 240x320``)."""
    parts = text.lower().split("x")
    try:
        H, W = (int(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected HEIGHTxWIDTH, e.g. 240x320; got {text!r}")
    if H < 32 or W < 32:
        raise argparse.ArgumentTypeError(f"each side must be at least 32 pixels; got {text}")
    return H, W


def add_demo_command(sub):
    p = sub.add_parser("demo", help="reconstruct the built-in synthetic sequence (or, with "
                                    "--video, a synthetic video) and print its errors "
                                    "against ground truth",
                       epilog="--rrd without PATH writes out/demo.rrd (--video: "
                              "out/demo_video.rrd) under the current folder (or "
                              "$NRSFM_OUT). --video writes out/demo_video/frames/*.png and "
                              "out/demo_video/ground_truth.npz, then runs nrsfm video on "
                              "them with --ground-truth (--seed also seeds the video).")
    add_common_options(p, "demo.rrd")
    p.add_argument("--video", action="store_true",
                   help="render the synthetic video with ground truth "
                        "(data_tools.make_video), write it, run nrsfm video on it and "
                        "print e3d")
    p.add_argument("--frames", type=positive_int, default=None, metavar="N",
                   help="--video: number of frames (default: 40)")
    p.add_argument("--size", type=image_size, default=None, metavar="HxW",
                   help="--video: image size in pixels (default: 240x320)")
    p.add_argument("--surface", choices=("sheet", "face"), default=None,
                   help="--video: sheet (a waving flag, default) or face")
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
