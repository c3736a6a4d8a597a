"""What the ``nrsfm`` subcommands share: exit statuses, one-line errors, argument validators,
the options of every reconstruction, output-path checks and the result report."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..io import atomic_output, check_output_path

EXIT_ERROR = 1  # a failure while running: bad input file, failed write, ...
EXIT_USAGE = 2  # a bad command line (argparse, or UsageError after parsing)
EXIT_INTERRUPTED = 130
EXIT_STATUS_HELP = (
    "Exit status: 0 success, 1 error (bad input, failed write), 2 bad command line, 130 "
    "interrupted. Every error is one line on stderr."
)


class UsageError(ValueError):
    """A bad command-line argument detected after parsing (exit status 2)."""


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block), exit status 2."""

    def error(self, message):
        fail(f"{self.prog}: error: {one_line(message)} (see '{self.prog} --help')", EXIT_USAGE)


def one_line(text):
    """``text`` with every run of white space (newlines included) as one space."""
    return " ".join(str(text).split())


def fail(line, code):
    """Print ``line`` on stderr and exit with ``code``."""
    sys.stdout.flush()
    print(line, file=sys.stderr, flush=True)
    raise SystemExit(code)


def _integer(text, what, minimum):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}; got {text!r}") from None
    if value < minimum:
        need = f"at least {minimum}" if minimum else "non-negative"
        raise argparse.ArgumentTypeError(f"must be {need}; got {value}")
    return value


def frame_count(text):
    """argparse type: a number of frames, at least 2 (a camera motion needs two)."""
    return _integer(text, "an integer of at least 2", 2)


def positive_int(text):
    """argparse type: an integer >= 1 (``--K``, counts, sizes)."""
    return _integer(text, "a positive integer", 1)


def seed(text):
    """argparse type: a non-negative integer (``--seed``)."""
    return _integer(text, "a non-negative integer", 0)


def add_reconstruction_options(p, rrd_name, quiet=True):
    """``--method``, ``--shape-solver``, ``--seed``, ``--rrd [PATH]`` (without PATH:
    ``out/rrd_name``) and, if ``quiet``, ``--quiet``."""
    from ..pipeline import METHODS
    from ..stages.shape import SOLVERS

    text = "the pipeline (default: organic)"
    p.add_argument("--method", choices=sorted(METHODS), default="organic", help=text)
    text = "shape-stage solver (default: bilinear; admm: the paper's continuation ADMM)"
    p.add_argument("--shape-solver", choices=list(SOLVERS), help=text)
    p.add_argument("--seed", type=seed, default=0, help="random seed (default: 0)")
    text = f"also write a Rerun recording; without PATH: out/{rrd_name} (or under $NRSFM_OUT)"
    p.add_argument("--rrd", metavar="PATH", nargs="?", const="", help=text)
    if quiet:
        p.add_argument("--quiet", action="store_true", help="no progress messages")


def _positive_float(text):
    """argparse type: a finite number above 0 (``--focal``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number; got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a positive number; got {text}")
    return value


def add_camera_options(p):
    """``--intrinsics FILE`` or ``--focal PIXELS [--principal CX CY]``: a pinhole camera,
    so that a perspective refinement follows the orthographic stages."""
    g = p.add_mutually_exclusive_group()
    text = (
        "the camera matrix of the pixel tracks (a text file of 3 x 3 numbers, rows on lines, "
        "spaces or commas): a perspective refinement follows the orthographic stages"
    )
    g.add_argument("--intrinsics", metavar="FILE", help=text)
    text = "focal length in pixels (square pixels, no skew), instead of --intrinsics"
    g.add_argument("--focal", type=_positive_float, metavar="PIXELS", help=text)
    text = (
        "principal point in pixels with --focal (default: the image centre, when the input "
        "has image_size as nrsfm track writes it)"
    )
    p.add_argument("--principal", nargs=2, type=float, metavar=("CX", "CY"), help=text)


def camera(args, image_size=None):
    """The intrinsics the camera options give (a (3, 3) array), or None (orthographic).

    ``image_size`` (height, width) gives the default principal point, the image centre.
    Raises UsageError for ``--principal`` without ``--focal`` or no principal point, and
    ValueError for an unreadable or invalid ``--intrinsics`` file (named).
    """
    import numpy as np

    from ..stages.perspective import check_intrinsics

    if args.principal is not None and args.focal is None:
        raise UsageError("--principal goes with --focal (--intrinsics holds its own)")
    if args.intrinsics is not None:
        path = Path(args.intrinsics).expanduser()
        try:
            values = path.read_text().replace(",", " ").split()
            A = np.array([float(v) for v in values])
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise ValueError(f"cannot read --intrinsics {path}: {one_line(exc)}") from None
        if A.size != 9:
            raise ValueError(f"--intrinsics {path} must hold 9 numbers (3 x 3); got {A.size}")
        try:
            return check_intrinsics(A.reshape(3, 3))
        except ValueError as exc:
            raise ValueError(f"--intrinsics {path}: {exc}") from None
    if args.focal is None:
        return None
    if args.principal is not None:
        cx, cy = args.principal
    elif image_size is not None:
        cy, cx = (float(n) / 2 for n in image_size)
    else:
        raise UsageError("give --principal CX CY with --focal (the input has no image_size)")
    return check_intrinsics((args.focal, cx, cy))


def output_path(path, what, suffix=".npz"):
    """The output file ``path`` (``~`` expanded), checked writable before the work
    (ValueError / OSError otherwise: exit status 1); a name not ending in ``suffix`` (what is
    written there) is a :class:`UsageError`."""
    path = Path(path).expanduser()
    if path.suffix.lower() != suffix and not path.is_dir():
        raise UsageError(f"{what} {path}: the file written is a {suffix} file; name it so")
    return check_output_path(path, what)


def rrd_path(args, default):
    """The checked ``--rrd`` target: the path given, ``out/default`` for ``--rrd`` alone, None
    without ``--rrd``; a name not ending in ``.rrd`` is a :class:`UsageError`."""
    if args.rrd is None:
        return None
    if args.rrd == "":
        from ..paths import output_dir

        return check_output_path(output_dir() / default, "--rrd")
    path = Path(args.rrd).expanduser()
    if path.suffix.lower() != ".rrd":
        raise UsageError(f"--rrd {path}: the recording file name must end in .rrd")
    return output_path(path, "--rrd", ".rrd")


def write_recording(path, write):
    """``write(tmp)`` writes the ``.rrd`` at a temporary path, renamed to ``path`` on
    success; returns what ``write`` returns. OSError (one line) when it cannot be written."""
    os.environ.setdefault("RUST_LOG", "off")  # rerun's own multi-line log on write errors
    try:
        with atomic_output(path) as tmp:
            return write(tmp)
    except (OSError, RuntimeError) as exc:
        raise OSError(f"cannot write the recording {path}: {one_line(exc)}") from exc


def save_rrd(result, path, seq=None, image_size=None):
    """Write the recording of ``result`` (with ground truth ``seq``; ``image_size`` (H, W)
    of a perspective run's images, where the input has it) to ``path``."""
    from ..views.recording import save_recording

    def write(tmp):
        return save_recording(result, tmp, sequence=seq, image_size=image_size)

    write_recording(path, write)
    print(f"  wrote Rerun recording {path} (open it with: rerun {path})")


def _num(x):
    return f"{x:.4f}" if x >= 1e-3 else f"{x:.2e}"


def print_report(result, seq=None):
    """Print the result's summary and, given a sequence with ground truth, its errors;
    returns the errors (a dict, empty without ground truth)."""
    print(result.summary())
    if seq is None or seq.shapes is None:
        return {}
    errs = result.errors(seq.shapes, seq.rotations)
    parts = [f"e3d {_num(errs['e3d'])}", f"e3d (Akhter) {_num(errs['e3d_akhter'])}"]
    parts += [f"e_R {_num(errs['e_R'])}"] if "e_R" in errs else []
    print("  errors against ground truth: " + ", ".join(parts))
    return errs
