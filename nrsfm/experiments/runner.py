"""``run_benchmark``: plan, run (resumable), and write the tables and plots."""

from __future__ import annotations

import os
import platform
import sys
import time
from pathlib import Path

from ..paths import mocap_dir
from .executors import run_tasks
from .plan import build_plan, unique_tasks
from .report import write_report

__all__ = ["run_benchmark", "resolve_data_dir"]


def resolve_data_dir(data=None):
    """The folder with the MoCap ``.mat`` files (:func:`nrsfm.paths.mocap_dir`).

    Parameters
    ----------
    data : str or Path, optional
        The folder that holds ``mocap/``, or ``mocap/`` itself; default ``$NRSFM_DATA``
        (either form too).

    Returns
    -------
    folder : Path

    Raises
    ------
    FileNotFoundError
        No folder given, or the folder does not exist (the message names it).
    """
    folder = mocap_dir(data)
    if not folder.is_dir():
        raise FileNotFoundError(f"benchmark data folder {folder} does not exist; pass the "
                                "folder that holds mocap/ (or mocap/ itself)")
    return folder


def run_benchmark(out, data=None, only=None, sequences=None, quick=False, workers=1,
                  scheduler=None, seed=0, progress=True, overrides=None, external=None):
    """Run the selected experiments and write their tables and plots into ``out``.

    Parameters
    ----------
    out : path
        Output folder; finished tasks are cached in ``out/cache`` (a second run with the
        same settings resumes and skips them).
    data : path, optional
        MoCap folder (see :func:`resolve_data_dir`). Not needed when every sequence is
        synthetic (``synthetic-SEED``).
    only, sequences, quick, seed, overrides, external
        See :func:`nrsfm.experiments.plan.build_plan`.
    workers : int
        Local worker processes.
    scheduler : str or dask.distributed.Client, optional
        Run on a Dask distributed cluster instead.
    progress : bool
        Show a progress bar (tqdm, on stderr).

    Returns
    -------
    dict
        ``files`` written, ``tables``, ``rows`` (all task rows), ``n_tasks``,
        ``n_cached``, ``seconds``.
    """
    synthetic = sequences and all(s.startswith("synthetic-") for s in sequences)
    data_dir = None if synthetic else resolve_data_dir(data)
    plan = build_plan(only=only, sequences=sequences, quick=quick, data=data_dir, seed=seed,
                      overrides=overrides, external=external)
    tasks = unique_tasks(plan)
    out = Path(out)
    t0 = time.perf_counter()
    bar = None
    if progress:
        try:
            from tqdm import tqdm
        except ImportError:                     # plain lines without the optional tqdm
            bar = _LineProgress(len(tasks))
        else:
            bar = tqdm(total=len(tasks), desc="nrsfm benchmark", unit="task",
                       file=sys.stderr)
    n_cached = 0

    def tick(task, rows, cached):
        nonlocal n_cached
        n_cached += cached
        if bar is not None:
            bar.set_postfix_str(str(task)[:60], refresh=False)
            bar.update(1)

    try:
        rows = run_tasks(tasks, cache_dir=out / "cache", workers=workers,
                         scheduler=scheduler, progress=tick)
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - t0
    from .executors import load_cached

    results = {t.key: load_cached(t, out / "cache") for t in tasks}
    seqs = sequences or sequences_of(tasks)
    header = (f"# nrsfm benchmark{' (quick set)' if quick else ''}\n\n"
              f"{len(tasks)} tasks ({n_cached} from the cache), {seconds:.0f} s wall, "
              f"{'Dask scheduler' if scheduler else f'{workers} local worker(s)'}, "
              f"{os.cpu_count()} CPUs, Python {platform.python_version()}, seed {seed}, "
              f"one BLAS thread per task.\n")
    files, tables = write_report(out, plan, results, list(seqs), header=header)
    return dict(files=files, tables=tables, rows=rows, n_tasks=len(tasks),
                n_cached=n_cached, seconds=seconds, out=out)


def sequences_of(tasks):
    """The sequences the tasks name, in first-seen order (tasks that name none, such as
    the shape experiment's, are left out)."""
    return list(dict.fromkeys(t.params["sequence"] for t in tasks
                              if t.params.get("sequence") is not None))


class _LineProgress:
    """Minimal stand-in for a tqdm bar: one line per finished task on stderr."""

    def __init__(self, total):
        self.total, self.n, self.text = total, 0, ""

    def set_postfix_str(self, text, refresh=False):
        self.text = text

    def update(self, k):
        self.n += k
        print(f"nrsfm benchmark {self.n}/{self.total} {self.text}", file=sys.stderr,
              flush=True)

    def close(self):
        pass
