"""The paper's experiments (Sec. 4) as independent tasks, which ``nrsfm benchmark`` runs;
from Python: ``run_benchmark("out/bench", data="data/mocap", quick=True)``."""

from .plan import EXPERIMENTS, build_plan, unique_tasks
from .runner import run_benchmark, run_tasks
from .tasks import Task, load_sequence, run_task
