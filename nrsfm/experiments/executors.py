"""Run tasks on an executor with a resumable on-disk cache.

Every finished task is written to ``cache_dir/<task.key>.json`` atomically
(:func:`nrsfm.io.write_text`), so an interrupted sweep, run again with the
same cache folder, skips the tasks already done. Tasks run in local processes
(``concurrent.futures.ProcessPoolExecutor``, ``workers`` of them; ``workers=1`` runs them
in this process) or on a Dask distributed cluster (``scheduler`` address, or a
``dask.distributed.Client``). Results do not depend on which of them runs a task.
"""

from __future__ import annotations

import json
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from ..io import write_text
from .tasks import run_task

__all__ = ["run_tasks", "load_cached"]


def load_cached(task, cache_dir):
    """The cached rows of ``task``, or None when it has not finished."""
    if cache_dir is None:
        return None
    path = Path(cache_dir) / f"{task.key}.json"
    if not path.is_file():
        return None
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError):
        return None                       # unreadable: run it again
    if rec.get("experiment") != task.experiment or rec.get("params") != task.params_json:
        return None
    return rec["rows"]


def _store(task, rows, cache_dir):
    if cache_dir is None:
        return
    rec = dict(experiment=task.experiment, params=task.params_json, rows=rows)
    write_text(Path(cache_dir) / f"{task.key}.json", json.dumps(rec, sort_keys=True))


def _worker_init():
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"


def run_tasks(tasks, cache_dir=None, workers=1, scheduler=None, progress=None):
    """Run tasks (skipping cached ones) and return their rows in task order.

    Parameters
    ----------
    tasks : sequence of Task
    cache_dir : path, optional
        Folder for the per-task result files (created if needed); None: no cache.
    workers : int
        Local worker processes (``1``: run in this process). Ignored with ``scheduler``.
    scheduler : str or dask.distributed.Client, optional
        Address of a Dask scheduler (``"tcp://host:8786"``) or a connected client.
    progress : callable(task, rows, cached) or None
        Called once per task as it finishes (cached tasks first).

    Returns
    -------
    rows : list of dict
        The rows of every task, in the order of ``tasks``.

    Raises
    ------
    ValueError
        ``workers`` < 1, or duplicate tasks.
    """
    tasks = list(tasks)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be a positive integer; got {workers!r}")
    if len({t.key for t in tasks}) != len(tasks):
        raise ValueError("duplicate tasks in the list")
    if cache_dir is not None:
        Path(cache_dir).mkdir(parents=True, exist_ok=True)
    tick = progress or (lambda task, rows, cached: None)
    results = {}
    todo = []
    for t in tasks:
        rows = load_cached(t, cache_dir)
        if rows is None:
            todo.append(t)
        else:
            results[t.key] = rows
            tick(t, rows, True)

    def done(t, rows):
        _store(t, rows, cache_dir)
        results[t.key] = rows
        tick(t, rows, False)

    if todo and scheduler is not None:
        _run_dask(todo, scheduler, done)
    elif todo and workers > 1:
        with ProcessPoolExecutor(max_workers=workers, initializer=_worker_init) as ex:
            futures = {ex.submit(run_task, t): t for t in todo}
            for fut in as_completed(futures):
                done(futures[fut], fut.result())
    else:
        for t in todo:
            done(t, run_task(t))
    return [r for t in tasks for r in results[t.key]]


def _run_dask(todo, scheduler, done):
    try:
        from dask.distributed import Client, as_completed as dask_completed
    except ImportError as exc:
        raise ValueError("running on a Dask scheduler needs dask.distributed: "
                         "pip install 'nrsfm[distributed]'") from exc

    own = not hasattr(scheduler, "submit")
    client = Client(scheduler) if own else scheduler
    try:
        futures = {}
        for t in todo:
            fut = client.submit(run_task, t, key=f"nrsfm-{t.key}", pure=False)
            futures[fut.key] = (fut, t)
        for fut in dask_completed([f for f, _ in futures.values()]):
            done(futures[fut.key][1], fut.result())
    finally:
        if own:
            client.close()

