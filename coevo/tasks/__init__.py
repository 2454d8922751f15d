"""The tasks: worlds whose behaviours the GA learns (the interface is :mod:`coevo.tasks.base`).

* ``fuel``: tracking under fuel constraints (report Appendix A): Tracking, Docking, Executive;
* ``door``: door traversal with seven sonars that may fail (report Appendix B): one behaviour, door;
* ``corridor``: a one-cell-wide corridor to walk to its end, small enough for tests to learn
  in a second; it shows that the GA, worker, broker, replay and check name no task.

Importing this package registers every built-in task's behaviours (their rule schemas).
"""

from __future__ import annotations

from coevo.errors import ConfigError
from coevo.tasks.base import Evaluation, Evaluator, Partners, Task
from coevo.tasks.corridor import CorridorTask
from coevo.tasks.door import DoorTask
from coevo.tasks.fuel import FuelTask

__all__ = ["Task", "Evaluator", "Evaluation", "Partners", "TASKS", "get_task", "task_of", "measure_labels", "DEFAULT_TASK"]

TASKS: dict[str, Task] = {t.name: t for t in (FuelTask(), CorridorTask(), DoorTask())}
DEFAULT_TASK = "fuel"


def get_task(name: str) -> Task:
    """The task called ``name``."""
    try:
        return TASKS[name]
    except KeyError:
        raise ConfigError(f"unknown task {name!r} (use {' or '.join(TASKS)})") from None


def measure_labels() -> dict[str, str]:
    """Every task's short names of its status measures."""
    return {k: v for t in TASKS.values() for k, v in t.measure_labels.items()}


def task_of(behaviour: str) -> Task:
    """The task a behaviour belongs to (behaviour names are unique across tasks)."""
    for t in TASKS.values():
        if str(behaviour) in t.behaviours:
            return t
    known = ", ".join(b for t in TASKS.values() for b in t.behaviours)
    raise ConfigError(f"unknown behaviour {str(behaviour)!r} (known: {known})")
