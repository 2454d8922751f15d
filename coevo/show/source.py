"""What to show: the task and robot held by a run directory, a rule file, or a behaviour's default rules.

The task is found from what was given, never assumed, and its display
(:class:`~coevo.tasks.showing.TaskDisplay`, ``Task.display()``) makes the robot; every way of naming partners is checked here so that the error names the
missing file.  Anything wrong with a directory is one :class:`~coevo.errors.RunDirError` naming it.

    FILE.rules                      its behaviour (so its task) from the '# behaviour:' header
    runs/ID/  (coevo run, cel)      workers/BEHAVIOUR/best.rules of each of the task's behaviours; task and
                                    world from run.json
    runs/learn-.../ (coevo learn)   best.rules; task and world from config.json; the partners it learned
                                    against from the BEHAVIOUR.rules learn wrote beside it
    --default BEHAVIOUR             the behaviour's shipped default rule set
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from coevo.config import build
from coevo.errors import ConfigError, RunDirError
from coevo.policy.rules import RuleSet
from coevo.policy.text import read_rule_file
from coevo.rundir.layout import LearnPaths, RunPaths, read_json
from coevo.rundir.settings import SETTINGS_VERSION
from coevo.plugins import PluginError
from coevo.tasks import DEFAULT_TASK, TASKS, Task, get_task, saved_settings, task_of, usable_tasks
from coevo.tasks.showing import TaskDisplay, display_of

__all__ = ["Shown", "find_task", "task_names", "from_default", "from_path", "check_world"]

_MAX_PROBLEM = 300  # characters of a validation message quoted in a one-line error


@dataclass(frozen=True)
class Shown:
    """What ``coevo show`` plays: a task, its display and its robot (the display's own object, with a name and a
    world)."""

    task: Task[Any]
    display: TaskDisplay[Any]
    robot: Any


def _shown(task: Task[Any], name: str, world: BaseModel, rules: Mapping[str, RuleSet]) -> Shown:
    """The robot ``rules`` make in ``world``, made by ``task``'s display (a ConfigError if it has none)."""
    display = display_of(task)
    return Shown(task, display, display.show_robot(name, world, rules))


def task_names() -> list[str]:
    return TASKS.names()


def find_task(name: str) -> Task:
    """The installed task called ``name`` (or by one of its older names, which every task is loaded to find)."""
    if name in TASKS:
        return get_task(name)
    for t in usable_tasks().values():
        if name in t.aliases:
            return t
    raise ConfigError(f"--task {name!r}: unknown task (known: {', '.join(TASKS.names())})")


def check_world(over: Mapping[str, Any]) -> dict[str, Any]:
    """``--world`` values: numbers must be finite (JSON lets NaN and Infinity through; no world has a use for them)."""
    for k, v in over.items():
        if isinstance(v, float) and not math.isfinite(v):
            raise ConfigError(f"--world {k}={v}: expected a finite number")
    return dict(over)


def _world(task: Task, values: Mapping[str, Any]) -> BaseModel:
    return build(task.world_settings, dict(values))


def _short(msg: str) -> str:
    return msg if len(msg) <= _MAX_PROBLEM else msg[:_MAX_PROBLEM].rstrip() + " ..."


def _check_task(task: Task, wanted: Task | None, where: Path) -> Task:
    if wanted is not None and wanted is not task:
        raise RunDirError(f"{str(where)!r} is a {task.name!r} run, not {wanted.name!r} (--task {wanted.name})")
    return task


def _partners_of(task: Task, partners: Mapping[str, RuleSet], what: str) -> None:
    foreign = [b for b in partners if b not in task.behaviours]
    if foreign:
        raise ConfigError(f"--{foreign[0]} is a partner in the {task_of(foreign[0]).name!r} task; {what} is a "
                          f"{task.name!r} robot")


def from_default(behaviour: str, world_over: Mapping[str, Any], *, wanted: Task | None) -> Shown:
    """A behaviour's shipped default rules, in a world of its task's defaults with ``world_over`` (the rules a GA
    starts from there: :meth:`~coevo.tasks.base.Task.initial_rules`)."""
    def none_there() -> ConfigError:
        have = [b for t in usable_tasks().values() for b in t.behaviours
                if t.initial_rules(b, t.world_settings()) is not None]
        return ConfigError(f"--default {behaviour!r}: only {', '.join(have)} have default rules")

    try:
        task = task_of(behaviour)
    except ConfigError:
        raise none_there() from None
    if wanted is not None and wanted is not task:
        raise ConfigError(f"--default {behaviour!r} is a {task.name!r} behaviour, not {wanted.name!r} (--task)")
    world = _world(task, world_over)
    rs = task.initial_rules(behaviour, world)
    if rs is None:
        raise none_there()
    return _shown(task, f"default-{behaviour}", world, {behaviour: rs})


def from_path(path: Path, *, world_over: Mapping[str, Any], partners: Mapping[str, RuleSet],
              wanted: Task | None) -> Shown:
    """The robot held by a rule file or a run directory; ``partners`` overrides or completes it;
    ``world_over`` changes its world's settings."""
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"no such file or directory: {str(path)!r}")
    if path.is_dir():
        if RunPaths(path).run_json.exists():
            return _from_run(path, world_over, partners, wanted)
        if LearnPaths(path).best_rules.exists() or LearnPaths(path).config.exists():
            return _from_learn(path, world_over, partners, wanted)
        raise RunDirError(f"{str(path)!r} holds no policies: neither a coevo run (run.json, workers/*/best.rules) "
                          "nor a coevo learn directory (best.rules)")
    rs = read_rule_file(path)
    task = task_of(rs.behaviour)
    if wanted is not None and wanted is not task:
        raise ConfigError(f"{str(path)!r} holds {rs.behaviour} rules of the {task.name!r} task, not {wanted.name!r} (--task)")
    _partners_of(task, partners, str(path))
    if (run := _run_of(path)) is not None:  # a worker's rule file: its partners and world are its run's
        f = RunPaths(run).run_json
        meta = _meta(f)
        needed = task.partners_needed(rs.behaviour, str(meta.get("regime", task.regimes[0])))
        rules = RunPaths(run).final_rules(needed, partners)
        return _shown(task, path.stem, _run_world(task, meta, f, world_over, ""), {**rules, rs.behaviour: rs})
    return _shown(task, path.stem, _world(task, world_over), {**partners, rs.behaviour: rs})


def _run_of(path: Path) -> Path | None:
    """The run directory a worker's rule file sits in (``RUN/workers/BEHAVIOUR/FILE`` with ``RUN/run.json``)."""
    run = path.resolve().parent.parent.parent
    return run if path.resolve().parent.parent.name == "workers" and RunPaths(run).run_json.exists() else None


def _meta(f: Path) -> dict[str, Any]:
    return read_json(f, what="a run's settings")


def _named_task(meta: Mapping[str, Any], f: Path, default: str) -> Task:
    name = meta.get("task", default)
    if not isinstance(name, str):
        raise RunDirError(f"{str(f)!r} names task {name!r}, which is not a name")
    try:
        return find_task(name)
    except PluginError:
        raise
    except ConfigError:
        raise RunDirError(f"{str(f)!r} names task {name!r}, unknown to this coevo (it knows "
                          f"{', '.join(TASKS.names())}; written by another version, or by a task's package not "
                          "installed here?)") from None


def _run_world(task: Task, meta: Mapping[str, Any], f: Path, over: Mapping[str, Any], version: str) -> BaseModel:
    """The world in ``f`` (a RunDirError naming it when it is not the task's), with ``over`` on top (a ConfigError);
    a run saved before some world setting existed, or when it was a GA setting, as it learned
    (:func:`~coevo.tasks.saved_settings`)."""
    try:
        values = saved_settings({**meta, "task": task.name}).get("world", {})
    except ConfigError as exc:
        raise RunDirError(f"{str(f)!r}: {exc}") from None
    if not isinstance(values, dict):
        raise RunDirError(f"{str(f)!r}: its world is not a JSON object of settings")
    try:
        check_world(values)
    except ConfigError as exc:
        raise RunDirError(f"{str(f)!r}: {str(exc).replace('--world ', 'world setting ', 1)}") from None
    try:
        world = _world(task, values)
    except ConfigError as exc:
        raise RunDirError(f"{str(f)!r} does not hold {task.name!r} world settings{version}: {_short(str(exc))}") from None
    return _world(task, {**world.model_dump(), **over}) if over else world


def _from_run(d: Path, over: Mapping[str, Any], partners: Mapping[str, RuleSet], wanted: Task | None) -> Shown:
    """A co-evolution run (coevo run, coevo cel): its workers' final best rule sets."""
    f = RunPaths(d).run_json
    meta = _meta(f)
    version = meta.get("settings_version", SETTINGS_VERSION)
    if version != SETTINGS_VERSION:
        raise RunDirError(f"{str(f)!r} has settings version {version!r}; this coevo reads version {SETTINGS_VERSION} "
                          "(written by another version of coevo)")
    task = _check_task(_named_task(meta, f, DEFAULT_TASK), wanted, d)
    _partners_of(task, partners, str(d))
    world = _run_world(task, meta, f, over, "")
    rules = RunPaths(d).final_rules(task.behaviours, partners)
    return _shown(task, d.name, world, rules)


def _from_learn(d: Path, over: Mapping[str, Any], partners: Mapping[str, RuleSet], wanted: Task | None) -> Shown:
    """A ``coevo learn`` directory: its best rule set, with the partners it learned against."""
    paths = LearnPaths(d)
    if not paths.best_rules.exists():
        raise RunDirError(f"learn directory {str(d)!r} holds no best.rules (was the run interrupted?)")
    rs = read_rule_file(paths.best_rules)
    task = task_of(rs.behaviour)
    meta = _meta(paths.config) if paths.config.exists() else {}
    named = _named_task(meta, paths.config, task.name)
    if named is not task:
        raise RunDirError(f"{str(d)!r}: its config.json names task {named.name!r} but its best.rules holds "
                          f"{rs.behaviour} rules of the {task.name!r} task")
    _check_task(task, wanted, d)
    _partners_of(task, partners, str(d))
    from coevo import __version__

    written = meta.get("coevo")
    version = f" (written by coevo {written}, this is {__version__})" if written and written != __version__ else ""
    world = _run_world(task, meta, paths.config, over, version)
    rules = {rs.behaviour: rs}
    for b in task.partners_needed(rs.behaviour, "independent"):
        f = paths.partner_rules(b)
        if b in partners:
            rules[b] = partners[b]
        elif f.exists():
            rules[b] = read_rule_file(f, b)
        else:
            raise RunDirError(f"{rs.behaviour} learn directory {str(d)!r} does not hold its {b} partner ({f.name}; "
                              f"learn runs before coevo show did not keep it): give --{b} FILE")
    return _shown(task, d.name, world, rules)
