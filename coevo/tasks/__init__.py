"""The tasks: worlds whose behaviours the GA learns (the interface is :mod:`coevo.tasks.base`), found by name.

Tasks are plugins (:mod:`coevo.plugins`), coevo's own included: each is an entry point of the group
``coevo.tasks`` in its package's metadata, and its module is imported the first time its name is asked for,
so a process imports only the task it runs.  coevo's own, declared in its pyproject.toml:

* ``fuel``: tracking under fuel constraints (report Appendix A): Tracking, Docking, Executive;
* ``door``: door traversal with seven sonars that may fail (report Appendix B): one behaviour, door;
* ``corridor``: a one-cell-wide corridor to walk to its end, small enough for tests to learn
  in a second; it shows that the GA, worker, broker, replay and check name no task.

Another package adds its own the same way (docs/own-task.md); a script or a test with :func:`register_task`.
A task registers its behaviours' rule schemas when it is imported; a behaviour asked for by name before its
task was (a rule file, a message on the bus) has its task found by :func:`task_of`.

Settings as given and as saved: :func:`split_settings` reads ``--ga`` values that name a setting
of the task's world (and none of the GA's) as world settings; :func:`saved_settings` reads a
saved run's settings as the run learned with them (both for the fuel task's Docking settings,
GA settings in the runs saved before November 2026, world settings since).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from coevo.config import GAConfig, Settings, saved_ga
from coevo.errors import ConfigError
from coevo.plugins import TASKS_GROUP, Plugins
from coevo.policy import schema as _schema
from coevo.tasks.base import Evaluation, Evaluator, Partners, Task

__all__ = ["Task", "Evaluator", "Evaluation", "Partners", "TASKS", "get_task", "task_of", "task_names", "usable_tasks",
           "register_task", "measure_labels", "DEFAULT_TASK", "split_settings", "saved_settings"]

DEFAULT_TASK = "fuel"  # the report's task: what every command runs unless told


def _make_task(name: str, obj: object) -> Task[Any]:
    """A task from what its entry point names: a Task subclass (made with no arguments) or a Task."""
    task = obj() if isinstance(obj, type) and issubclass(obj, Task) else obj
    if not isinstance(task, Task):
        raise TypeError(f"{obj!r} is not a coevo task (a subclass or instance of coevo.tasks.base.Task)")
    if task.name != name:
        raise TypeError(f"it is installed as {name!r} but calls itself {task.name!r}")
    if not task.behaviours or not all(isinstance(b, str) for b in task.behaviours):
        raise TypeError(f"its behaviours {task.behaviours!r} are not a tuple of names")
    return task


#: Every task installed or registered, by name; a task's module is imported when its name is first asked for.
TASKS: Plugins[Task[Any]] = Plugins(TASKS_GROUP, "task", _make_task)


def get_task(name: str) -> Task[Any]:
    """The task called ``name``, imported on first use (a ConfigError for an unknown name, a PluginError naming
    the package for one that cannot be used)."""
    if not isinstance(name, str):
        raise ConfigError(f"a task is named by a string, not {name!r}")
    return TASKS.get(name)


def task_names() -> list[str]:
    """The names of the tasks installed or registered (nothing is imported)."""
    return TASKS.names()


def usable_tasks() -> dict[str, Task[Any]]:
    """Every task that loads, by name (each imported; one that cannot be is logged and left out)."""
    return TASKS.usable()


def register_task(task: Task[Any] | type[Task[Any]] | str, name: str | None = None) -> None:
    """Make a task known in this process without installing a package (a script, a notebook, a test): a Task, a
    Task subclass, or ``"module:Class"`` imported when first named (then ``name`` is needed)."""
    if name is None:
        if isinstance(task, str):
            raise ConfigError(f"register_task({task!r}) needs the task's name: register_task('module:Class', name=...)")
        name = task.name
    TASKS.register(name, task)


def measure_labels(behaviours: Iterable[str] = ()) -> dict[str, str]:
    """The short names of the status measures of the tasks of ``behaviours`` (found and loaded if need be) and of
    every task loaded so far."""
    for b in behaviours:
        try:
            task_of(b)
        except ConfigError:
            pass  # an unknown behaviour's measures keep their own names
    return {k: v for t in TASKS.loaded().values() for k, v in t.measure_labels.items()}


def task_of(behaviour: str) -> Task[Any]:
    """The task a behaviour belongs to (behaviour names are unique across tasks): among the tasks loaded so far,
    else the others, imported one at a time until one declares it."""
    name = str(behaviour)
    for t in TASKS.loaded().values():
        if name in t.behaviours:
            return t
    for task_name in TASKS.names():
        if task_name in TASKS.loaded():
            continue
        try:
            t = TASKS.get(task_name)
        except ConfigError:
            continue  # a task that cannot be used declares nothing (coevo plugins says why)
        if name in t.behaviours:
            return t
    known = ", ".join(b for t in TASKS.loaded().values() for b in t.behaviours)
    raise ConfigError(f"unknown behaviour {name!r} (known: {known})")


def _find_schema(behaviour: str) -> None:
    """The rule schemas' finder: a behaviour not registered yet has its task loaded, if any task declares it."""
    try:
        task_of(behaviour)
    except ConfigError:
        pass


_schema.set_finder(_find_schema)


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
    task = get_task(name) if isinstance(name, str) and name in TASKS else None
    if task is not None:
        world, ga = split_settings(task, world, ga)
        model = task.world_settings
        out["world"] = {**(model.saved_before if issubclass(model, Settings) else {}), **world}
    out["ga"] = saved_ga(ga)
    return out
