"""``nrsfm demo`` and ``nrsfm mocap NAME``: reconstruct a built-in or benchmark sequence and
print its errors against the ground truth."""

from __future__ import annotations

import argparse
import os

from ..pipeline import reconstruct
from ..validation import check_K
from .common import UsageError, add_reconstruction_options, frame_count, positive_int
from .common import print_report
from .common import rrd_path, save_rrd


def _reconstruct(seq, K, args, rotations=None, rrd=None):
    kw = dict(method=args.method, seed=args.seed, shape_solver=args.shape_solver)
    result = reconstruct(seq.W, K, rotations=rotations, progress=not args.quiet, **kw)
    print_report(result, seq)
    if rrd is not None:
        save_rrd(result, rrd, seq)
    return 0


def cmd_demo(args):
    """``nrsfm demo``: the built-in synthetic sequence; ``--video``: the synthetic video."""
    if args.video:
        from .video import cmd_demo_video

        return cmd_demo_video(args)
    given = [f"--{k}" for k in ("frames", "size", "surface") if getattr(args, k) is not None]
    if given:
        raise UsageError(f"{', '.join(given)}: only with --video")
    from data_tools import default_sequence

    rrd = rrd_path(args, "demo.rrd")
    seq = default_sequence()
    print(
        f"built-in input: {seq.name}, F={seq.n_frames} frames, P={seq.n_points} points, "
        f"K={seq.K}, smooth camera, no noise"
    )
    return _reconstruct(seq, seq.K, args, rrd=rrd)


def image_size(text):
    """argparse type: ``HxW`` in pixels, each at least 32 (``--size 240x320``)."""
    try:
        H, W = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected HEIGHTxWIDTH, e.g. 240x320; got {text!r}")
    if H < 32 or W < 32:
        raise argparse.ArgumentTypeError(f"each side must be at least 32 pixels; got {text}")
    return H, W


def add_demo_command(sub):
    p = sub.add_parser(
        "demo",
        help="reconstruct the built-in synthetic sequence (or, with --video, a synthetic "
        "video) and print its errors against ground truth",
        epilog="--video writes out/demo_video/frames/*.png and out/demo_video/ground_truth.npz, "
        "then runs nrsfm video on them with --ground-truth (--seed also seeds the video).",
    )
    add_reconstruction_options(p, "demo.rrd (--video: out/demo_video.rrd)")
    text = "render a synthetic video with ground truth, write it, run nrsfm video on it"
    p.add_argument("--video", action="store_true", help=text)
    p.add_argument("--frames", type=frame_count, metavar="N", help="--video: frames (default 40)")
    text = "--video: image size in pixels (default: 240x320)"
    p.add_argument("--size", type=image_size, metavar="HxW", help=text)
    text = "--video: sheet (a waving flag, default) or face"
    p.add_argument("--surface", choices=("sheet", "face"), help=text)
    p.set_defaults(func=cmd_demo)


def cmd_mocap(args):
    """``nrsfm mocap NAME``: a MoCap benchmark sequence."""
    from data_tools import MOCAP_NAMES, load_mocap

    if args.name not in MOCAP_NAMES:
        names = ", ".join(MOCAP_NAMES)
        raise UsageError(f"unknown MoCap sequence {args.name!r}; expected one of {names}")
    if args.data is None and not os.environ.get("NRSFM_DATA"):
        raise UsageError(
            "no data folder: pass --data DIR or set NRSFM_DATA (the folder that "
            "holds mocap/, or mocap/ itself)"
        )
    rrd = rrd_path(args, f"{args.name}.rrd")
    seq = load_mocap(args.name, args.data)
    K = check_K(seq.K if args.K is None else args.K, seq.n_frames, seq.n_points)
    if args.given_rotations and seq.rotations is None:
        raise UsageError(
            f"--given-rotations: {args.name} has no ground-truth rotations (its "
            "rigid motion is inside the shapes)"
        )
    return _reconstruct(seq, K, args, seq.rotations if args.given_rotations else None, rrd)


def add_mocap_command(sub):
    p = sub.add_parser("mocap", help="reconstruct a MoCap benchmark sequence")
    p.add_argument("name", help="drink, pickup, yoga, stretch, dance, face, walking, shark")
    text = "the folder that holds mocap/, or mocap/ itself (default: $NRSFM_DATA)"
    p.add_argument("--data", metavar="DIR", help=text)
    p.add_argument("--K", type=positive_int, help="override the paper's K")
    text = "use the ground-truth rotations (shape stage only)"
    p.add_argument("--given-rotations", action="store_true", help=text)
    add_reconstruction_options(p, "NAME.rrd")
    p.set_defaults(func=cmd_mocap)
