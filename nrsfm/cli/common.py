"""What every ``nrsfm`` subcommand shares: the exit-code convention, one-line errors,
argument validators (``--K``, ``--seed``, counts), the ``--rrd`` option and output-path
checks, progress messages and the result report.

Exit status: 0 success; 1 a failure while running (bad input file, unreadable data, failed
write, an output folder that does not exist or is not writable); 2 a bad command line
(argparse's errors, and :class:`UsageError` for what can only be checked after parsing:
a wrong suffix, conflicting paths, a missing option); 130 interrupted.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..io import atomic_output, check_output_path
from ..stages.shape import SOLVERS

__all__ = ["add_shape_solver_option", "EXIT_OK", "EXIT_ERROR", "EXIT_USAGE", "EXIT_INTERRUPTED", "EXIT_STATUS_HELP",
           "UsageError", "Parser", "one_line", "fail", "positive_int", "seed",
           "add_rrd_option", "rrd_path", "output_path", "say", "write_recording",
           "print_report"]

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
EXIT_STATUS_HELP = ("Exit status: 0 success, 1 error (bad input, failed write), 2 bad command "
                    "line, 130 interrupted. Every error is one line on stderr.")


class UsageError(ValueError):
    """A bad command-line argument detected after parsing (exit status 2)."""


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage block), exit status 2."""

    def error(self, message):
        fail(f"{self.prog}: error: {one_line(message)} (see '{self.prog} --help')",
             EXIT_USAGE)


def one_line(text):
    """``text`` with every run of white space (newlines included) as one space."""
    return " ".join(str(text).split())


def fail(line, code):
    """Print ``line`` on stderr and exit with ``code``."""
    sys.stdout.flush()
    print(line, file=sys.stderr, flush=True)
    raise SystemExit(code)


def _integer(text, what):
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}; got {text!r}")


def positive_int(text):
    """argparse type: an integer >= 1 (``--K``, counts, sizes)."""
    value = _integer(text, "a positive integer")
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1; got {value}")
    return value


def seed(text):
    """argparse type: a non-negative integer (``--seed``)."""
    value = _integer(text, "a non-negative integer")
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be non-negative; got {value}")
    return value


def add_rrd_option(p, default_name):
    """``--rrd [PATH]``: also write a Rerun recording; without PATH, ``default_name``."""
    p.add_argument("--rrd", metavar="PATH", nargs="?", const="",
                   help="also write a Rerun recording (.rrd); without PATH: "
                        f"out/{default_name} under the current folder (or $NRSFM_OUT)")


def output_path(path, what):
    """The output file ``path`` (``~`` expanded), checked writable before the work.

    Raises ValueError / OSError (exit status 1) when it cannot be written."""
    return check_output_path(Path(path).expanduser(), what)


def rrd_path(args, default):
    """The checked ``--rrd`` target: the given path, or ``out/default`` when --rrd has no
    value, or None without --rrd. A name not ending in ``.rrd`` is a :class:`UsageError`."""
    if args.rrd is None:
        return None
    if args.rrd == "":
        from ..paths import output_dir

        return check_output_path(output_dir() / default, "--rrd")
    path = Path(args.rrd).expanduser()
    if path.suffix.lower() != ".rrd":
        raise UsageError(f"--rrd {path}: the recording file name must end in .rrd")
    return output_path(path, "--rrd")


def say(args):
    """A progress printer (stderr), silent with ``--quiet``."""
    if args.quiet:
        return lambda message: None
    return lambda message: print(message, file=sys.stderr, flush=True)


def write_recording(path, write):
    """Write a recording atomically: ``write(tmp)`` writes the ``.rrd`` at a temporary
    path, renamed to ``path`` on success. Returns what ``write`` returns.

    Raises OSError with a one-line message when the recording cannot be written."""
    os.environ.setdefault("RUST_LOG", "off")   # rerun's own multi-line log on write errors
    try:
        with atomic_output(path) as tmp:
            return write(tmp)
    except (OSError, RuntimeError) as exc:
        raise OSError(f"cannot write the recording {path}: {one_line(exc)}") from exc


def _num(x):
    return f"{x:.4f}" if x >= 1e-3 else f"{x:.2e}"


def print_report(result, seq=None):
    """Print the result's summary (with its diagnostics' notes and warnings) and, given a
    sequence with ground truth, the errors; returns the errors (a dict, empty without
    ground truth)."""
    print(result.summary())
    errs = {}
    if seq is not None and seq.shapes is not None:
        errs = result.errors(seq.shapes, seq.rotations)
        parts = [f"e3d {_num(errs['e3d'])}", f"e3d (Akhter) {_num(errs['e3d_akhter'])}"]
        if "e_R" in errs:
            parts.append(f"e_R {_num(errs['e_R'])}")
        print("  errors against ground truth: " + ", ".join(parts))
    return errs


def add_shape_solver_option(p):
    """``--shape-solver`` (every command that reconstructs)."""
    p.add_argument("--shape-solver", choices=list(SOLVERS), default=None,
                   help="shape-stage solver (default: bilinear; admm: the paper's "
                        "continuation ADMM)")
