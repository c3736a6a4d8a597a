"""Run the tasks in local processes with a resumable cache, and the benchmark as a whole.

Every finished task is written to ``cache_dir/<task.key>.json`` atomically, so a sweep run
again with the same cache folder skips the tasks already done.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from ..io import write_text
from ..paths import mocap_dir
from .plan import build_plan, unique_tasks
from .report import write_report
from .tasks import run_task


def resolve_data_dir(data=None):
    """The folder with the MoCap ``.mat`` files (:func:`nrsfm.paths.mocap_dir`): ``data``
    or ``$NRSFM_DATA``, the folder that holds ``mocap/`` or ``mocap/`` itself.

    Raises FileNotFoundError when no folder is given or it does not exist."""
    folder = mocap_dir(data)
    if not folder.is_dir():
        raise FileNotFoundError(
            f"benchmark data folder {folder} does not exist; pass the folder that holds "
            "mocap/ (or mocap/ itself)"
        )
    return folder


def load_cached(task, cache_dir):
    """The cached rows of ``task``, or None when it has not finished."""
    path = Path(cache_dir) / f"{task.key}.json"
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError):  # absent or unreadable: run it again
        return None
    if rec.get("experiment") != task.experiment or rec.get("params") != task.params_json:
        return None
    return rec["rows"]


def run_tasks(tasks, cache_dir=None, workers=1, progress=None):
    """Run tasks (in ``workers`` local processes; 1: in this one) and return their rows in
    task order. ``cache_dir``: folder of the per-task result files (None: no cache), whose
    tasks are not run again; ``progress(task, rows, cached)`` is called as each task
    finishes (cached ones first). ValueError for ``workers`` < 1 or duplicate tasks."""
    tasks = list(tasks)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive integer; got {workers!r}")
    if len({t.key for t in tasks}) != len(tasks):
        raise ValueError("duplicate tasks in the list")
    if cache_dir is not None:
        Path(cache_dir).mkdir(parents=True, exist_ok=True)
    tick = progress or (lambda task, rows, cached: None)
    results = {}

    def done(t, rows, cached=False):
        if cache_dir is not None and not cached:
            rec = dict(experiment=t.experiment, params=t.params_json, rows=rows)
            write_text(Path(cache_dir) / f"{t.key}.json", json.dumps(rec, sort_keys=True))
        results[t.key] = rows
        tick(t, rows, cached)

    todo = []
    for t in tasks:
        rows = None if cache_dir is None else load_cached(t, cache_dir)
        if rows is None:
            todo.append(t)
        else:
            done(t, rows, cached=True)
    if workers > 1 and todo:
        with ProcessPoolExecutor(max_workers=workers) as ex:
            futures = {ex.submit(run_task, t): t for t in todo}
            for fut in as_completed(futures):
                done(futures[fut], fut.result())
    else:
        for t in todo:
            done(t, run_task(t))
    return [r for t in tasks for r in results[t.key]]


def sequences_of(tasks):
    """The sequences the tasks name, in first-seen order (tasks that name none left out)."""
    seqs = (t.params.get("sequence") for t in tasks)
    return list(dict.fromkeys(s for s in seqs if s is not None))


def run_benchmark(out, data=None, workers=1, progress=True, **options):
    """Run the experiments and write their tables and plots into the folder ``out``, the
    finished tasks cached in ``out/cache`` (the same call again resumes).

    ``data``: the MoCap folder (:func:`resolve_data_dir`; not needed when every sequence is
    ``synthetic-SEED``); ``workers`` local processes; ``progress``: a progress bar on stderr
    (with tqdm installed); ``options``: ``only``, ``sequences``, ``quick``, ``seed``,
    ``overrides``, ``external`` of :func:`nrsfm.experiments.plan.build_plan`. Returns a dict:
    ``files`` written, ``tables``, ``rows`` (of all tasks), ``n_tasks``, ``n_cached``,
    ``seconds``, ``out``.
    """
    sequences, quick, seed = (options.get(k) for k in ("sequences", "quick", "seed"))
    synthetic = sequences and all(s.startswith("synthetic-") for s in sequences)
    plan = build_plan(data=None if synthetic else resolve_data_dir(data), **options)
    tasks = unique_tasks(plan)
    out, cache = Path(out), Path(out) / "cache"
    bar, n_cached = None, []
    if progress:
        try:
            from tqdm import tqdm

            bar = tqdm(total=len(tasks), desc="nrsfm benchmark", unit="task", file=sys.stderr)
        except ImportError:
            pass

    def tick(task, rows, cached):
        n_cached.append(cached)
        if bar is not None:
            bar.set_postfix_str(str(task)[:60], refresh=False)
            bar.update(1)

    t0 = time.perf_counter()
    try:
        rows = run_tasks(tasks, cache_dir=cache, workers=workers, progress=tick)
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - t0
    results = {t.key: load_cached(t, cache) for t in tasks}
    n = dict(n_tasks=len(tasks), n_cached=sum(n_cached), seconds=seconds)
    header = (
        f"# nrsfm benchmark{' (quick set)' if quick else ''}\n\n{len(tasks)} tasks "
        f"({n['n_cached']} from the cache), {seconds:.0f} s wall, {workers} local "
        f"worker(s), {os.cpu_count()} CPUs, Python {platform.python_version()}, seed "
        f"{seed or 0}, one BLAS thread per task.\n"
    )
    seqs = list(sequences or sequences_of(tasks))
    files, tables = write_report(out, plan, results, seqs, header=header)
    return dict(files=files, tables=tables, rows=rows, out=out, **n)
