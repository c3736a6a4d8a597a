"""Command line: ``nrsfm demo``, ``run``, ``mocap``, ``track``, ``video``, ``benchmark``.

One parser package: the subcommands live in :mod:`.reconstruct` (demo, mocap), :mod:`.run`,
:mod:`.video` (track, video) and :mod:`.benchmark`; :mod:`.common` holds what they share
(validators, ``--rrd``, output checks, the report).

Every failure ends in one line on stderr, ``nrsfm: error: <what>``, and a non-zero exit
status (:data:`~.common.EXIT_USAGE` 2: bad command line; :data:`~.common.EXIT_ERROR` 1:
anything else: bad input file, failed write, ...); inputs and output paths are checked
before the computation; outputs are written exactly where asked, atomically
(:mod:`nrsfm.io`).

Adding a subcommand: write ``add_NAME_command(subparsers)`` in a module of this package; it
calls ``subparsers.add_parser(...)`` and ``set_defaults(func=...)`` with ``func(args) ->
int`` that raises ``ValueError`` / ``OSError`` on bad input (:class:`~.common.UsageError`
for a bad argument found after parsing), and append it to :data:`COMMANDS` below.
:func:`main` turns those exceptions into the one-line message.
"""

from __future__ import annotations

import os
import sys
import warnings
import zipfile
import zlib

import numpy as np

from .. import __version__
from .common import (EXIT_ERROR, EXIT_INTERRUPTED, EXIT_STATUS_HELP, EXIT_USAGE, Parser,
                     UsageError, fail, one_line)
from .reconstruct import add_demo_command, add_mocap_command
from .run import add_run_command
from .video import add_video_commands

__all__ = ["COMMANDS", "build_parser", "main"]


def _add_benchmark_command(sub):
    from .benchmark import add_benchmark_command   # matplotlib etc. load lazily

    add_benchmark_command(sub)


#: Subcommand registrations, in the order ``nrsfm --help`` lists them.
COMMANDS = [add_demo_command, add_run_command, add_mocap_command, add_video_commands,
            _add_benchmark_command]


def build_parser():
    """The ``nrsfm`` argument parser with every subcommand of :data:`COMMANDS`."""
    parser = Parser(
        prog="nrsfm",
        description="Non-rigid structure from motion with organic priors "
                    "(Kumar & Van Gool, ECCV 2022).",
        epilog=EXIT_STATUS_HELP)
    parser.add_argument("--version", action="version", version=f"nrsfm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for register in COMMANDS:
        register(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"nrsfm: warning: {one_line(message)}", file=sys.stderr, flush=True)


#: Exceptions that mean bad input or a failed write, reported as one line.
EXPECTED_ERRORS = (ValueError, OSError, KeyError, IndexError, EOFError, RuntimeError,
                   zipfile.BadZipFile, zlib.error, np.linalg.LinAlgError, MemoryError)


def _describe(exc):
    text = one_line(exc)
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
    from ..diagnostics import NRSfMWarning

    saved = warnings.showwarning
    warnings.showwarning = _show_warning
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
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        raise SystemExit(EXIT_ERROR)
    except EXPECTED_ERRORS as exc:
        if os.environ.get("NRSFM_DEBUG"):
            raise
        fail(f"nrsfm {args.command}: error: {_describe(exc)}", EXIT_ERROR)
    except Exception as exc:  # a bug: still one line, the traceback on request
        if os.environ.get("NRSFM_DEBUG"):
            raise
        fail(f"nrsfm {args.command}: internal error: {type(exc).__name__}: "
             f"{_describe(exc)} (run with NRSFM_DEBUG=1 for the traceback)", EXIT_ERROR)
    finally:
        warnings.showwarning = saved

