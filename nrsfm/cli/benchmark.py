"""``nrsfm benchmark``: the paper's experiments in one command (:mod:`nrsfm.experiments`)."""

from __future__ import annotations

from pathlib import Path

from .common import positive_int, seed

__all__ = ["add_benchmark_command", "cmd_benchmark"]

_DESCRIPTION = ("Run the paper's experiments (MoCap table, Table 1, Table 3, noise, missing "
                "data, N ablation, K sweep, automatic K) as independent tasks and write "
                "Markdown and CSV tables and PNG plots into --out. Finished tasks are cached "
                "in OUT/cache: running the same command again resumes.")


def _output_folder(path, what):
    """A folder to write into (created when absent): ValueError if a file is in the way."""
    path = Path(path).expanduser()
    if path.exists() and not path.is_dir():
        raise ValueError(f"{what} {path} exists and is not a folder")
    return path


def cmd_benchmark(args):
    """Run the plan, print where the tables went."""
    from ..experiments.runner import run_benchmark

    out = _output_folder(args.out, "--out")
    res = run_benchmark(out, data=args.data, only=args.only, sequences=args.sequences,
                        quick=args.quick, workers=args.workers, scheduler=args.scheduler,
                        seed=args.seed, progress=not args.quiet,
                        external=args.external_data)
    print(f"nrsfm benchmark: {res['n_tasks']} tasks ({res['n_cached']} cached) in "
          f"{res['seconds']:.1f} s; wrote {len(res['files'])} files to {res['out']} "
          f"(index: {res['out'] / 'README.md'})")
    return 0


def add_benchmark_command(subparsers):
    """Register ``benchmark`` on the ``nrsfm`` argument parser's subparsers."""
    from ..experiments.plan import EXPERIMENTS

    listed = "; ".join(f"{k}: {v}" for k, v in EXPERIMENTS.items())
    p = subparsers.add_parser(
        "benchmark", help="regenerate the paper's experiments (tables, plots) into a folder",
        description=f"{_DESCRIPTION} Experiments: {listed}")
    p.add_argument("--data", metavar="DIR",
                   help="the folder that holds mocap/ with the MoCap .mat files, or mocap/ "
                        "itself (default: $NRSFM_DATA, either form too)")
    p.add_argument("--external-data", metavar="DIR",
                   help="folder of the external sequences (the shape table's back row; "
                        "default: $NRSFM_EXTERNAL_DATA, or external/ beside mocap/)")
    p.add_argument("--out", required=True, help="output folder (tables, plots, cache/)")
    p.add_argument("--only", nargs="+", choices=list(EXPERIMENTS), metavar="EXPERIMENT",
                   help="run only these experiments: " + ", ".join(EXPERIMENTS))
    p.add_argument("--sequences", nargs="+", metavar="NAME",
                   help="sequences (default: the 8 MoCap sequences; synthetic-SEED for a "
                        "small synthetic one)")
    p.add_argument("--quick", action="store_true",
                   help="the quick set (fewer methods, noise levels, runs; ablations and "
                        "sweeps on pickup only): for CI")
    p.add_argument("--workers", type=positive_int, default=1,
                   help="local worker processes (default 1)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the tasks on a Dask distributed scheduler, e.g. "
                        "tcp://host:8786 (needs the 'distributed' extra)")
    p.add_argument("--seed", type=seed, default=0, help="base seed (default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_benchmark)
    return p
