"""The tasks: worlds whose behaviours the GA learns (the interface is :mod:`coevo.tasks.base`).

* ``fuel``: tracking under fuel constraints (report Appendix A): Tracking, Docking, Executive;
* ``door``: door traversal with seven sonars that may fail (report Appendix B): one behaviour, door;
* ``corridor``: a one-cell-wide corridor to walk to its end, small enough for tests to learn
  in a second; it shows that the GA, worker, broker, replay and check name no task.

Importing this package registers every built-in task's behaviours (their rule schemas).

Settings as given and as saved: :func:`split_settings` reads ``--ga`` values that name a setting
of the task's world (and none of the GA's) as world settings; :func:`saved_settings` reads a
saved run's settings as the run learned with them (both for the fuel task's Docking settings,
GA settings in the runs saved before November 2026, world settings since).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from coevo.config import GAConfig, Settings, saved_ga
from coevo.errors import ConfigError
from coevo.tasks.base import Evaluation, Evaluator, Partners, Task
from coevo.tasks.corridor import CorridorTask
from coevo.tasks.door import DoorTask
from coevo.tasks.fuel import FuelTask

__all__ = ["Task", "Evaluator", "Evaluation", "Partners", "TASKS", "get_task", "task_of", "measure_labels", "DEFAULT_TASK",
           "split_settings", "saved_settings"]

TASKS: dict[str, Task[Any]] = {t.name: t for t in (FuelTask(), CorridorTask(), DoorTask())}
DEFAULT_TASK = "fuel"


def get_task(name: str) -> Task[Any]:
    """The task called ``name``."""
    try:
        return TASKS[name]
    except KeyError:
        raise ConfigError(f"unknown task {name!r} (use {' or '.join(TASKS)})") from None


def measure_labels() -> dict[str, str]:
    """Every task's short names of its status measures."""
    return {k: v for t in TASKS.values() for k, v in t.measure_labels.items()}


def task_of(behaviour: str) -> Task[Any]:
    """The task a behaviour belongs to (behaviour names are unique across tasks)."""
    for t in TASKS.values():
        if str(behaviour) in t.behaviours:
            return t
    known = ", ".join(b for t in TASKS.values() for b in t.behaviours)
    raise ConfigError(f"unknown behaviour {str(behaviour)!r} (known: {known})")


def split_settings(task: Task[Any], world: Mapping[str, Any], ga: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The world and GA setting values given (``--world``, ``--ga``; dicts of names and values), with every GA value
    that names a setting of ``task``'s world and none of the GA's moved to the world: the fuel task's Docking
    settings (``docking_sensors``, ...) were GA settings in runs saved before November 2026, and ``--ga docking_sensors=polar`` still
    says what it said.  A name given both ways is a ConfigError."""
    moved = {k: v for k, v in ga.items() if k in task.world_settings.model_fields and k not in GAConfig.model_fields}
    twice = sorted(k for k in moved if k in world)
    if twice:
        raise ConfigError(f"{', '.join(twice)}: given both as a GA and as a world setting; it is a world setting of "
                          f"task {task.name!r}: give it once, as --world {twice[0]}=...")
    return {**world, **moved}, {k: v for k, v in ga.items() if k not in moved}


def saved_settings(data: Mapping[str, Any]) -> dict[str, Any]:
    """A run's saved settings (run.json, worker.json, a learn directory's config.json, compare.json's spec: a dict
    with ``ga``, ``world`` and perhaps ``task``, by default :data:`DEFAULT_TASK`) as the run learned with them, so
    that it loads, resumes and replays as it was rather than under today's defaults: GA values its task now keeps
    in its world moved there (:func:`split_settings`), then every setting added since the run was saved filled in
    with its value from before (``saved_before`` of :class:`~coevo.config.GAConfig` and of the task's world
    model).  Anything not a dict, or an unknown task, is left for the reader to refuse."""
    out = dict(data)
    ga, world, name = out.get("ga"), out.get("world", {}), out.get("task", DEFAULT_TASK)
    if not isinstance(ga, dict) or not isinstance(world, dict):
        return out
    task = TASKS.get(name) if isinstance(name, str) else None
    if task is not None:
        world, ga = split_settings(task, world, ga)
        model = task.world_settings
        out["world"] = {**(model.saved_before if issubclass(model, Settings) else {}), **world}
    out["ga"] = saved_ga(ga)
    return out
