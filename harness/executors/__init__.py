"""Who measures the pending cells, and where: the interface (base), here in rounds (rounds) or
as Slurm tasks (slurm). A new executor is a class with `name` and `run` (base.Executor),
registered in EXECUTORS."""

from collections.abc import Callable

from harness.errors import HarnessError
from harness.executors.base import Executor
from harness.executors.rounds import LocalExecutor
from harness.executors.slurm.executor import SlurmExecutor

EXECUTORS: dict[str, Callable[[], Executor]] = {"local": LocalExecutor, "slurm": SlurmExecutor}


def make_executor(name: str) -> Executor:
    factory = EXECUTORS.get(name)
    if factory is None:
        raise HarnessError(f"unknown executor '{name}'; expected one of: "
                           f"{', '.join(sorted(EXECUTORS))}")
    return factory()
