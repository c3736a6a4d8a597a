"""The paper's experiments (Sec. 4) as independent tasks: plan, executors, tables, plots.

``nrsfm benchmark`` (:mod:`nrsfm.cli.benchmark`) runs them; from Python::

    from nrsfm.experiments import run_benchmark
    run_benchmark("out/bench", data="data/mocap", quick=True)
"""

from .autok import choose_K
from .executors import load_cached, run_tasks
from .plan import EXPERIMENTS, build_plan, settings, unique_tasks
from .runner import run_benchmark
from .tasks import Task, load_sequence, run_task

__all__ = ["EXPERIMENTS", "Task", "build_plan", "choose_K", "load_cached", "load_sequence",
           "run_benchmark", "run_task", "run_tasks", "settings", "unique_tasks"]
