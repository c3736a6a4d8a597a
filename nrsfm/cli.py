"""Command line: ``nrsfm demo``, ``nrsfm run INPUT.npz``, ``nrsfm mocap NAME``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from .pipeline import METHODS, reconstruct


def _add_common(p):
    p.add_argument("--method", choices=sorted(METHODS), default="organic",
                   help="pipeline to run (default: organic)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--rrd", metavar="PATH", help="also write a Rerun recording (.rrd)")
    p.add_argument("--quiet", action="store_true", help="no progress messages")


def _num(x):
    return f"{x:.4f}" if x >= 1e-3 else f"{x:.2e}"


def _report(result, seq=None):
    print(result.summary())
    if seq is not None and seq.shapes is not None:
        errs = result.errors(seq.shapes, seq.rotations)
        parts = [f"e3d {_num(errs['e3d'])}", f"e3d (Akhter) {_num(errs['e3d_akhter'])}"]
        if "e_R" in errs:
            parts.append(f"e_R {_num(errs['e_R'])}")
        print("  errors against ground truth: " + ", ".join(parts))


def _save_rrd(result, path, seq=None):
    from .recording import save_recording

    out = save_recording(result, path, sequence=seq)
    print(f"  wrote Rerun recording {out} (open it with: rerun {out})")


def cmd_demo(args):
    from data_tools import default_sequence

    seq = default_sequence()
    print(f"built-in input: {seq.name}, F={seq.n_frames} frames, P={seq.n_points} points, "
          f"K={seq.K}, smooth camera, no noise")
    result = reconstruct(seq.W, seq.K, method=args.method, seed=args.seed,
                         progress=not args.quiet)
    _report(result, seq)
    if args.rrd:
        _save_rrd(result, args.rrd, seq)
    return 0


def _load_npz(path):
    path = Path(path)
    if not path.is_file():
        raise SystemExit(f"nrsfm run: input file {path} not found")
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    if "W" not in data:
        raise SystemExit(f"nrsfm run: {path} has no array 'W' (found: {sorted(data)})")
    return data


def cmd_run(args):
    from data_tools import Sequence

    data = _load_npz(args.input)
    K = args.K if args.K is not None else (int(data["K"]) if "K" in data else None)
    if K is None:
        raise SystemExit("nrsfm run: give --K (the input has no 'K' array)")
    gt_rot = data.get("rotations")
    try:
        result = reconstruct(data["W"], K, method=args.method, seed=args.seed,
                             rotations=gt_rot if args.given_rotations else None,
                             progress=not args.quiet)
    except ValueError as exc:
        raise SystemExit(f"nrsfm run: {exc}")
    seq = None
    if "shapes" in data:
        seq = Sequence(name=Path(args.input).stem, W=result.W, shapes=data["shapes"],
                       rotations=gt_rot, K=K,
                       edges=data.get("edges"))
    _report(result, seq)
    out = Path(args.output or Path(args.input).with_suffix("").as_posix() + "_nrsfm.npz")
    arrays = dict(rotations=result.rotations, shapes=result.shapes, X_init=result.X_init,
                  W=result.W, row_means=result.row_means, scale=result.scale, K=K,
                  method=np.array(result.method))
    if result.shape_stage is not None:
        for key, val in result.shape_stage.history.items():
            arrays[f"admm_{key}"] = np.asarray(val)
    if result.rotation_stage is not None:
        rs = result.rotation_stage
        arrays.update(G=rs.G, per_triplet_rotations=rs.per_triplet, kept=rs.kept)
    np.savez_compressed(out, **arrays)
    print(f"  wrote {out}")
    if args.rrd:
        _save_rrd(result, args.rrd, seq)
    return 0


def cmd_mocap(args):
    from data_tools import load_mocap

    try:
        seq = load_mocap(args.name, args.data)
    except (FileNotFoundError, ValueError) as exc:
        raise SystemExit(f"nrsfm mocap: {exc}")
    K = args.K or seq.K
    result = reconstruct(seq.W, K, method=args.method, seed=args.seed,
                         rotations=seq.rotations if args.given_rotations else None,
                         progress=not args.quiet)
    _report(result, seq)
    if args.rrd:
        _save_rrd(result, args.rrd, seq)
    return 0


def build_parser():
    parser = argparse.ArgumentParser(
        prog="nrsfm",
        description="Non-rigid structure from motion with organic priors "
                    "(Kumar & Van Gool, ECCV 2022).")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="reconstruct the built-in synthetic sequence and print "
                                    "its errors against ground truth")
    _add_common(p)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("run", help="reconstruct W from an .npz file and write the result")
    p.add_argument("input", help=".npz with array W (2F, P) or (F, 2, P); optional K, "
                                 "shapes (F, 3, P) and rotations (F, 3, 3) ground truth, edges")
    p.add_argument("--K", type=int, help="number of shape bases (default: the file's K)")
    p.add_argument("-o", "--output", help="output .npz (default: INPUT_nrsfm.npz)")
    p.add_argument("--given-rotations", action="store_true",
                   help="use the file's rotations instead of estimating them")
    _add_common(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("mocap", help="reconstruct a MoCap benchmark sequence")
    p.add_argument("name", help="drink, pickup, yoga, stretch, dance, face, walking, shark")
    p.add_argument("--data", help="folder with the .mat files (default: $NRSFM_DATA/mocap)")
    p.add_argument("--K", type=int, help="override the paper's K")
    p.add_argument("--given-rotations", action="store_true",
                   help="use ground-truth rotations (shape stage only)")
    _add_common(p)
    p.set_defaults(func=cmd_mocap)
    from .experiments.cli import add_benchmark_command; add_benchmark_command(sub)  # noqa: E702
    return parser


def main(argv=None):
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
