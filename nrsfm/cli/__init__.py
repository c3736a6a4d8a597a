"""Command line: ``nrsfm demo``, ``run``, ``mocap``, ``track``, ``video``, ``benchmark``.

A subcommand (``add_..._command(subparsers)`` in :data:`COMMANDS`) raises ``ValueError`` /
``OSError`` on bad input, :class:`~.common.UsageError` on a bad argument found after parsing;
:func:`main` makes every failure one line on stderr and an exit status. Inputs and output
paths are checked before the computation; outputs are written where asked, atomically.
"""

from __future__ import annotations

import os
import sys
import warnings
import zipfile
import zlib

import numpy as np

from .. import __version__
from .benchmark import add_benchmark_command
from .common import EXIT_ERROR, EXIT_INTERRUPTED, EXIT_STATUS_HELP, EXIT_USAGE, Parser
from .common import UsageError, fail, one_line
from .reconstruct import add_demo_command, add_mocap_command
from .run import add_run_command
from .video import add_video_commands

#: Subcommand registrations, in the order ``nrsfm --help`` lists them.
COMMANDS = [
    add_demo_command,
    add_run_command,
    add_mocap_command,
    add_video_commands,
    add_benchmark_command,
]

#: Exceptions that mean bad input or a failed write (exit status 1).
EXPECTED_ERRORS = (ValueError, OSError, KeyError, IndexError, EOFError, RuntimeError, MemoryError)
EXPECTED_ERRORS += (zipfile.BadZipFile, zlib.error, np.linalg.LinAlgError)


def build_parser():
    """The ``nrsfm`` argument parser with every subcommand of :data:`COMMANDS`."""
    parser = Parser(
        prog="nrsfm",
        description="Non-rigid structure from motion with organic priors (Kumar & Van Gool, "
        "ECCV 2022).",
        epilog=EXIT_STATUS_HELP,
    )
    parser.add_argument("--version", action="version", version=f"nrsfm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for register in COMMANDS:
        register(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"nrsfm: warning: {one_line(message)}", file=sys.stderr, flush=True)


def _describe(exc):
    text = one_line(exc)
    if isinstance(exc, KeyError):
        return f"missing key {text}"
    if isinstance(exc, MemoryError):
        return "out of memory" + (f" ({text})" if text else "")
    return text or type(exc).__name__


def main(argv=None):
    """Run the command line; returns the exit status (errors: one line on stderr)."""
    args = build_parser().parse_args(argv)
    from ..diagnostics import NRSfMWarning

    debug = os.environ.get("NRSFM_DEBUG")
    saved, warnings.showwarning = warnings.showwarning, _show_warning
    try:
        with warnings.catch_warnings():
            # the report prints the diagnostics' flags; other warnings are one line each
            warnings.filterwarnings("ignore", category=NRSfMWarning)
            return args.func(args)
    except UsageError as exc:
        fail(f"nrsfm {args.command}: error: {one_line(exc)}", EXIT_USAGE)
    except KeyboardInterrupt:
        fail("nrsfm: interrupted", EXIT_INTERRUPTED)
    except BrokenPipeError:  # e.g. `nrsfm demo | head -1`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        raise SystemExit(EXIT_ERROR) from None
    except EXPECTED_ERRORS as exc:
        if debug:
            raise
        fail(f"nrsfm {args.command}: error: {_describe(exc)}", EXIT_ERROR)
    except Exception as exc:  # a bug: still one line, the traceback on request
        if debug:
            raise
        what = f"internal error: {type(exc).__name__}: {_describe(exc)}"
        fail(f"nrsfm {args.command}: {what} (NRSFM_DEBUG=1 shows the traceback)", EXIT_ERROR)
    finally:
        warnings.showwarning = saved
