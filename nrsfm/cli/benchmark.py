"""``nrsfm benchmark``: the paper's experiments in one command (:mod:`nrsfm.experiments`)."""

from __future__ import annotations

import os
from pathlib import Path

from ..io import check_output_path
from .common import UsageError, positive_int, seed


def cmd_benchmark(args):
    """Run the plan, print where the tables went."""
    from ..experiments.runner import run_benchmark

    out = Path(args.out).expanduser()
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out} exists and is not a folder")
    mocap = not args.sequences or any(not s.startswith("synthetic") for s in args.sequences)
    if mocap and args.data is None and not os.environ.get("NRSFM_DATA"):
        raise UsageError(
            "no data folder: pass --data DIR or set NRSFM_DATA (the folder that "
            "holds mocap/, or mocap/ itself)"
        )
    if mocap and args.data is not None and not Path(args.data).expanduser().is_dir():
        raise UsageError(f"--data {args.data} is not a folder")
    try:  # the output folder, checked before any work
        out.mkdir(parents=True, exist_ok=True)
        check_output_path(out / "README.md", "--out")
    except OSError as exc:
        raise UsageError(f"--out {out}: {exc.strerror or exc}") from exc
    external = args.external_data
    if external is None and args.data is not None:  # external/ beside mocap/, as NRSFM_DATA
        root = Path(args.data).expanduser()
        external = root.parent if root.name == "mocap" else root
    kw = dict(only=args.only, sequences=args.sequences, quick=args.quick, workers=args.workers)
    kw.update(seed=args.seed, progress=not args.quiet, external=external)
    res = run_benchmark(out, args.data, **kw)
    print(
        f"nrsfm benchmark: {res['n_tasks']} tasks ({res['n_cached']} cached) in "
        f"{res['seconds']:.1f} s; wrote {len(res['files'])} files to {out} "
        f"(index: {out / 'README.md'})"
    )
    return 0


def add_benchmark_command(subparsers):
    """Register ``benchmark`` on the ``nrsfm`` argument parser's subparsers."""
    from ..experiments.plan import EXPERIMENTS

    listed = "; ".join(f"{k}: {v}" for k, v in EXPERIMENTS.items())
    p = subparsers.add_parser(
        "benchmark",
        help="regenerate the paper's experiments (tables, plots) into a folder",
        description="Run the paper's experiments as independent tasks in local processes and "
        "write Markdown and CSV tables and PNG plots into --out. Finished tasks are cached in "
        f"OUT/cache: the same command again resumes. Experiments: {listed}",
    )
    env = "default: $NRSFM_DATA"
    p.add_argument("--data", metavar="DIR", help=f"folder of mocap/, or mocap/ itself ({env})")
    env = "default: $NRSFM_EXTERNAL_DATA, or external/ beside mocap/"
    p.add_argument("--external-data", metavar="DIR", help=f"folder of external/ ({env})")
    p.add_argument("--out", required=True, help="output folder (tables, plots, cache/)")
    p.add_argument(
        "--only",
        nargs="+",
        choices=list(EXPERIMENTS),
        metavar="EXPERIMENT",
        help="run only these experiments: " + ", ".join(EXPERIMENTS),
    )
    text = "default: the 8 MoCap sequences; synthetic-SEED for a small synthetic one"
    p.add_argument("--sequences", nargs="+", metavar="NAME", help=text)
    text = "the quick set (fewer methods, levels, runs; ablations on pickup only): for CI"
    p.add_argument("--quick", action="store_true", help=text)
    p.add_argument("--workers", type=positive_int, default=1, help="local processes (default 1)")
    p.add_argument("--seed", type=seed, default=0, help="base seed (default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_benchmark)
