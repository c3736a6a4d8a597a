"""Command line: ``nrsfm demo``, ``nrsfm run INPUT.npz``, ``nrsfm mocap NAME``.

Every failure ends in one line on stderr, ``nrsfm: error: <what>``, and a non-zero exit
status (2: bad command line; 1: anything else: bad input file, failed write, ...); inputs
and output paths are checked before the computation; outputs are written exactly where
asked, atomically (:mod:`nrsfm.io`).

Adding a subcommand: write ``add_NAME_command(subparsers)`` in your module; it calls
``subparsers.add_parser(...)`` and ``set_defaults(func=...)`` with ``func(args) -> int``
that raises ``ValueError`` / ``OSError`` on bad input, and append it to :data:`COMMANDS`
below. :func:`main` turns those exceptions into the one-line message.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
import zipfile
import zlib
from pathlib import Path

import numpy as np

from . import __version__
from .validation import check_K, check_measurements, check_rotations, check_shapes
from .io import atomic_output, check_output_path, save_npz
from .pipeline import METHODS, reconstruct
from .stages.shape import SHAPE_SOLVERS
from .video_cli import add_video_commands

EXIT_ERROR = 1
EXIT_USAGE = 2


class UsageError(ValueError):
    """A bad command-line argument detected after parsing (exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block), exit status 2."""

    def error(self, message):
        _fail(f"{self.prog}: error: {_one_line(message)} (see '{self.prog} --help')",
              EXIT_USAGE)


def _one_line(text):
    return " ".join(str(text).split())


def _fail(line, code):
    sys.stdout.flush()
    print(line, file=sys.stderr, flush=True)
    raise SystemExit(code)


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer; got {text!r}")
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1; got {value}")
    return value


def _seed(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer; got {text!r}")
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be non-negative; got {value}")
    return value


def _add_common(p):
    p.add_argument("--method", choices=sorted(METHODS), default="organic",
                   help="pipeline to run (default: organic)")
    p.add_argument("--shape-solver", choices=SHAPE_SOLVERS, default="bilinear",
                   help="shape-stage solver (default: bilinear; admm: the paper's "
                        "continuation ADMM; closed_form: exact rank-K, no prior)")
    p.add_argument("--seed", type=_seed, default=0, help="random seed (default: 0)")
    p.add_argument("--rrd", metavar="PATH", nargs="?", const="",
                   help="also write a Rerun recording (.rrd); without PATH: see below")
    p.add_argument("--quiet", action="store_true", help="no progress messages")


def _num(x):
    return f"{x:.4f}" if x >= 1e-3 else f"{x:.2e}"


def _report(result, seq=None):
    print(result.summary())
    errs = {}
    for flag in getattr(getattr(result, "diagnostics", None), "flags", []):
        print(f"  WARNING: {flag}")       # the NRSfMWarning, printed once (see main)
    if seq is not None and seq.shapes is not None:
        errs = result.errors(seq.shapes, seq.rotations)
        parts = [f"e3d {_num(errs['e3d'])}", f"e3d (Akhter) {_num(errs['e3d_akhter'])}"]
        if "e_R" in errs:
            parts.append(f"e_R {_num(errs['e_R'])}")
        print("  errors against ground truth: " + ", ".join(parts))
    return errs


def _rrd_path(args, default):
    """The checked --rrd target: the given path, or ``default`` when --rrd has no value."""
    if args.rrd is None:
        return None
    if args.rrd == "":
        from .paths import output_dir

        return check_output_path(output_dir() / default, "--rrd")
    path = Path(args.rrd).expanduser()
    if path.suffix.lower() != ".rrd":
        raise UsageError(f"--rrd {path}: the recording file name must end in .rrd")
    return check_output_path(path, "--rrd")


def _save_rrd(result, path, seq=None):
    os.environ.setdefault("RUST_LOG", "off")   # rerun's own multi-line log on write errors
    from .recording import save_recording

    try:
        with atomic_output(path) as tmp:
            save_recording(result, tmp, sequence=seq)
    except (OSError, RuntimeError) as exc:
        raise OSError(f"cannot write the recording {path}: {_one_line(exc)}") from exc
    print(f"  wrote Rerun recording {path} (open it with: rerun {path})")


# --------------------------------------------------------------------------- demo

def cmd_demo(args):
    from data_tools import default_sequence

    rrd = _rrd_path(args, "demo.rrd")
    seq = default_sequence()
    print(f"built-in input: {seq.name}, F={seq.n_frames} frames, P={seq.n_points} points, "
          f"K={seq.K}, smooth camera, no noise")
    result = reconstruct(seq.W, seq.K, method=args.method, seed=args.seed,
                         shape_solver=args.shape_solver,
                         progress=not args.quiet)
    _report(result, seq)
    if rrd:
        _save_rrd(result, rrd, seq)
    return 0


def add_demo_command(sub):
    p = sub.add_parser("demo", help="reconstruct the built-in synthetic sequence and print "
                                    "its errors against ground truth",
                       epilog="--rrd without PATH writes out/demo.rrd under the current "
                              "folder (or $NRSFM_OUT/demo.rrd).")
    _add_common(p)
    p.set_defaults(func=cmd_demo)


# --------------------------------------------------------------------------- run

#: Arrays ``nrsfm run`` reads from its input ``.npz``.
INPUT_KEYS = ("W", "K", "shapes", "rotations", "edges")


def _load_npz(path):
    """The arrays of an ``.npz`` as a dict, with one-line errors for every bad file."""
    path = Path(path).expanduser()
    if path.is_dir():
        raise ValueError(f"input {path} is a folder; give an .npz file")
    if not path.is_file():
        raise FileNotFoundError(f"input file {path} not found")
    if path.stat().st_size == 0:
        raise ValueError(f"input {path} is empty")
    try:
        loaded = np.load(path, allow_pickle=False)
    except ValueError as exc:
        raise ValueError(f"cannot read {path}: not an .npz file ({_one_line(exc)})") from exc
    except (EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"cannot read {path}: corrupt .npz file ({_one_line(exc)})") from exc
    if isinstance(loaded, np.ndarray):
        raise ValueError(f"{path} is a .npy file (one array); nrsfm run reads an .npz with "
                         "an array named W, e.g. numpy.savez('input.npz', W=W, K=3)")
    data = {}
    with loaded as z:
        for key in z.files:
            try:
                data[key] = z[key]
            except ValueError as exc:
                if "allow_pickle" in str(exc) or "Object arrays" in str(exc):
                    raise ValueError(f"{path}: array {key!r} is an object array; save "
                                     "numeric arrays only") from exc
                raise ValueError(f"cannot read array {key!r} of {path}: "
                                 f"{_one_line(exc)}") from exc
            except (EOFError, OSError, zipfile.BadZipFile, zlib.error, KeyError) as exc:
                raise ValueError(f"cannot read array {key!r} of {path}: corrupt .npz file "
                                 f"({_one_line(exc)})") from exc
    if "W" not in data:
        raise ValueError(f"{path} has no array 'W' (found: {sorted(data) or 'no arrays'})")
    return data


def _numeric(name, A):
    A = np.asarray(A)
    if A.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be a numeric (integer or float) array; got dtype "
                         f"{A.dtype}")
    return A


def _file_K(value):
    """K stored in a file: one integer (an integral float is accepted)."""
    A = np.asarray(value)
    if A.size != 1 or A.ndim > 1:
        raise ValueError(f"K in the input must be one integer; got an array of shape "
                         f"{A.shape}")
    item = A.reshape(()).item()
    if A.dtype.kind in "iu":
        return int(item)
    if A.dtype.kind == "f" and np.isfinite(item) and float(item).is_integer():
        return int(item)
    raise ValueError(f"K in the input must be an integer; got {item!r}")


def _edges(value, P):
    E = np.asarray(value)
    if E.dtype.kind not in "iu" or E.ndim != 2 or E.shape[1] != 2:
        raise ValueError(f"edges must be an integer (E, 2) array; got dtype {E.dtype}, "
                         f"shape {E.shape}")
    if E.size and (E.min() < 0 or E.max() >= P):
        raise ValueError(f"edges must index points 0..{P - 1}; got {E.min()}..{E.max()}")
    return E.astype(int)


def _output_arrays(result, K, errs):
    """The arrays ``nrsfm run`` writes (documented in the README)."""
    arrays = dict(rotations=result.rotations, shapes=result.shapes, X_init=result.X_init,
                  W=result.W, row_means=result.row_means, scale=np.float64(result.scale),
                  K=np.int64(K), method=np.array(result.method),
                  version=np.array(__version__))
    if result.shape_stage is not None:
        for key, val in result.shape_stage.history.items():
            arrays[f"shape_{key}"] = np.asarray(val)
    if result.rotation_stage is not None:
        rs = result.rotation_stage
        arrays.update(G=rs.G, per_triplet_rotations=rs.per_triplet, kept=rs.kept)
    for key, val in errs.items():
        arrays[key] = np.float64(val)
    return arrays


def cmd_run(args):
    from data_tools import Sequence

    inp = Path(args.input).expanduser()
    data = _load_npz(inp)
    W = check_measurements(_numeric("W", data["W"]), allow_missing=True)
    if np.isnan(W).any():                 # NaN = not observed: enough observations?
        from .stages.completion import observed_mask

        observed_mask(W)
    F, P = W.shape[0] // 2, W.shape[1]
    if args.K is not None:
        K = args.K
    elif "K" in data:
        K = _file_K(data["K"])
    else:
        raise UsageError("give --K (the input has no array 'K')")
    K = check_K(K, F, P)
    shapes = rotations = edges = None
    if "shapes" in data:
        shapes = check_shapes(_numeric("shapes", data["shapes"]), "shapes (ground truth)",
                              n_frames=F, n_points=P)
    if "rotations" in data:
        rotations = check_rotations(_numeric("rotations", data["rotations"]),
                                    "rotations (ground truth)", n_frames=F)
    if "edges" in data:
        edges = _edges(data["edges"], P)
    if args.given_rotations and rotations is None:
        raise UsageError(f"--given-rotations: {inp} has no array 'rotations'")
    ignored = sorted(set(data) - set(INPUT_KEYS))
    if ignored:
        warnings.warn(f"{inp}: ignoring arrays {ignored}", stacklevel=1)

    if args.output is not None:
        out = Path(args.output).expanduser()
    else:
        out = inp.with_name(inp.stem + "_nrsfm.npz")
    out = check_output_path(out, "output")
    if out.resolve() == inp.resolve():
        raise UsageError(f"output {out} would overwrite the input")
    rrd = _rrd_path(args, out.stem + ".rrd")
    if rrd is not None and rrd.resolve() in (out.resolve(), inp.resolve()):
        raise UsageError(f"--rrd {rrd} would overwrite the input or the output")

    result = reconstruct(W, K, method=args.method, seed=args.seed,
                         shape_solver=args.shape_solver,
                         rotations=rotations if args.given_rotations else None,
                         progress=not args.quiet)
    seq = None
    if shapes is not None:
        seq = Sequence(name=inp.stem, W=result.W, shapes=shapes, rotations=rotations, K=K,
                       edges=edges)
    errs = _report(result, seq)
    try:
        save_npz(out, **_output_arrays(result, K, errs))
    except OSError as exc:
        raise OSError(f"cannot write the output {out}: {_one_line(exc)}") from exc
    print(f"  wrote {out}")
    if rrd is not None:
        _save_rrd(result, rrd, seq)
    return 0


def add_run_command(sub):
    p = sub.add_parser(
        "run", help="reconstruct W from an .npz file and write the result",
        epilog="The output .npz holds rotations (F, 3, 3), shapes (F, 3, P), X_init, W, "
               "row_means, scale, K, method, version, shape_* (shape-stage history), G, "
               "per_triplet_rotations, kept (rotation stage) and e3d, e3d_akhter, e_R "
               "when the input has ground truth; see the README. --rrd without PATH "
               "writes out/OUTPUT_NAME.rrd under the current folder (or $NRSFM_OUT).")
    p.add_argument("input", help=".npz with array W (2F, P) or (F, 2, P); optional K, "
                                 "shapes (F, 3, P) and rotations (F, 3, 3) ground truth, edges")
    p.add_argument("--K", type=_positive_int,
                   help="number of shape bases (default: the file's K)")
    p.add_argument("-o", "--output", metavar="PATH",
                   help="output file, written exactly there (default: INPUT_nrsfm.npz)")
    p.add_argument("--given-rotations", action="store_true",
                   help="use the file's rotations instead of estimating them")
    _add_common(p)
    p.set_defaults(func=cmd_run)


# --------------------------------------------------------------------------- mocap

def cmd_mocap(args):
    from data_tools import MOCAP_NAMES, load_mocap

    if args.name not in MOCAP_NAMES:
        raise UsageError(f"unknown MoCap sequence {args.name!r}; expected one of "
                         f"{', '.join(MOCAP_NAMES)}")
    if args.data is None and not os.environ.get("NRSFM_DATA"):
        raise UsageError("no data folder: pass --data DIR (the folder with the .mat files) "
                         "or set NRSFM_DATA to the folder that holds mocap/")
    rrd = _rrd_path(args, f"{args.name}.rrd")
    seq = load_mocap(args.name, args.data)
    K = args.K if args.K is not None else seq.K
    K = check_K(K, seq.n_frames, seq.n_points)
    if args.given_rotations and seq.rotations is None:
        raise UsageError(f"--given-rotations: {args.name} has no ground-truth rotations "
                         "(its rigid motion is inside the shapes)")
    result = reconstruct(seq.W, K, method=args.method, seed=args.seed,
                         shape_solver=args.shape_solver,
                         rotations=seq.rotations if args.given_rotations else None,
                         progress=not args.quiet)
    _report(result, seq)
    if rrd is not None:
        _save_rrd(result, rrd, seq)
    return 0


def add_mocap_command(sub):
    p = sub.add_parser("mocap", help="reconstruct a MoCap benchmark sequence",
                       epilog="--rrd without PATH writes out/NAME.rrd under the current "
                              "folder (or $NRSFM_OUT/NAME.rrd).")
    p.add_argument("name", help="drink, pickup, yoga, stretch, dance, face, walking, shark")
    p.add_argument("--data", help="folder with the .mat files (default: $NRSFM_DATA/mocap)")
    p.add_argument("--K", type=_positive_int, help="override the paper's K")
    p.add_argument("--given-rotations", action="store_true",
                   help="use ground-truth rotations (shape stage only)")
    _add_common(p)
    p.set_defaults(func=cmd_mocap)


# --------------------------------------------------------------------------- parser, main

def _add_benchmark_command(sub):
    from .experiments.cli import add_benchmark_command   # matplotlib etc. load lazily

    add_benchmark_command(sub)


#: Subcommand registrations, in the order ``nrsfm --help`` lists them. Other modules add
#: theirs with one line here: ``COMMANDS.append(add_NAME_command)``.
COMMANDS = [add_demo_command, add_run_command, add_mocap_command, add_video_commands,
            _add_benchmark_command]


def build_parser():
    parser = _Parser(
        prog="nrsfm",
        description="Non-rigid structure from motion with organic priors "
                    "(Kumar & Van Gool, ECCV 2022).",
        epilog="Exit status: 0 success, 1 error (bad input, failed write), 2 bad command "
               "line. Every error is one line on stderr.")
    parser.add_argument("--version", action="version", version=f"nrsfm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for register in COMMANDS:
        register(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"nrsfm: warning: {_one_line(message)}", file=sys.stderr, flush=True)


#: Exceptions that mean bad input or a failed write, reported as one line.
EXPECTED_ERRORS = (ValueError, OSError, KeyError, IndexError, EOFError, RuntimeError,
                   zipfile.BadZipFile, zlib.error, np.linalg.LinAlgError, MemoryError)


def _describe(exc):
    text = _one_line(exc)
    if isinstance(exc, KeyError):
        return f"missing key {text}"
    if isinstance(exc, MemoryError):
        return "out of memory" + (f" ({text})" if text else "")
    if isinstance(exc, OSError) and not text.strip():
        return type(exc).__name__
    return text or type(exc).__name__


def main(argv=None):
    """Run the command line; returns the exit status (errors: one line on stderr)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from .diagnostics import NRSfMWarning

    saved = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        with warnings.catch_warnings():
            # the report prints the diagnostics' flags; other warnings are one line each
            warnings.filterwarnings("ignore", category=NRSfMWarning)
            return args.func(args)
    except UsageError as exc:
        _fail(f"nrsfm {args.command}: error: {_one_line(exc)}", EXIT_USAGE)
    except KeyboardInterrupt:
        _fail("nrsfm: interrupted", 130)
    except BrokenPipeError:  # e.g. `nrsfm demo | head -1`: stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        raise SystemExit(EXIT_ERROR)
    except EXPECTED_ERRORS as exc:
        if os.environ.get("NRSFM_DEBUG"):
            raise
        _fail(f"nrsfm {args.command}: error: {_describe(exc)}", EXIT_ERROR)
    except Exception as exc:  # a bug: still one line, the traceback on request
        if os.environ.get("NRSFM_DEBUG"):
            raise
        _fail(f"nrsfm {args.command}: internal error: {type(exc).__name__}: "
              f"{_describe(exc)} (run with NRSFM_DEBUG=1 for the traceback)", EXIT_ERROR)
    finally:
        warnings.showwarning = saved


if __name__ == "__main__":
    sys.exit(main())
