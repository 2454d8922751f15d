"""What every task must do, checked on any task: ``check_task(task)`` lists what is missing or wrong.

The GA, the workers, the broker, replay and check name no task; they rely on the interface of
:class:`coevo.tasks.base.Task`.  This checker plays a task at a tiny size and says, in one line each,
where it breaks that interface: its names and settings, each behaviour's rule schema and default
rules, the GA settings it fills in, the partners it asks for, an evaluation (shapes, payoffs in
[0, 1], the same numbers from the same seed), its measures (the same keys every generation, numbers
in the documented ranges) and, where ``display()`` gives them, its pictures (a robot played twice from one
seed the same way, a scene, rule tables, a PNG).  The suite runs it on every task
(``tests/test_tasks.py``); a new task runs it first (docs/architecture.md, "Adding things").

After Gymnasium's ``utils/env_checker.py``: the interface as executable checks, not only as prose.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel

from coevo.config import GAConfig, build
from coevo.errors import RuleSetError
from coevo.ga.evaluator import Evaluation, Partners
from coevo.policy.rules import RuleSet
from coevo.policy.schema import schema
from coevo.tasks.base import Task, Term, check_behaviour, check_ga, ga_settings, initial_model
from coevo.tasks.showing import TaskDisplay

__all__ = ["check_task", "TINY_GA"]

#: The size it plays at: a few episodes of two policies (seconds for every built-in task).
TINY_GA = {"population": 2, "episodes": 2, "best_episodes": 2, "generations": 1, "initial_rules": 6}


def check_task(task: Task[Any], *, seed: int = 0, pictures: bool = True) -> list[str]:
    """Problems with ``task`` as the interface of :class:`Task` defines it; empty when it passes."""
    problems: list[str] = []
    say = problems.append
    _identity(task, say)
    if problems:
        return problems  # without its names and settings nothing else can be tried
    world = task.world_settings()
    for behaviour in task.behaviours:
        _guard(say, f"{behaviour}: rules", partial(_rules, task, behaviour, world, say))
        _guard(say, f"{behaviour}: GA settings", partial(_ga, task, behaviour, say))
        _guard(say, f"{behaviour}: partners", partial(_partners, task, behaviour, say))
        _guard(say, f"{behaviour}: evaluation", partial(_evaluation, task, behaviour, world, seed, say))
    if pictures:
        _guard(say, "pictures", lambda: _pictures(task, world, seed, say))
    return problems


def _guard(say: Callable[[str], None], what: str, check: Callable[[], None]) -> None:
    """Run one group of checks; an exception it raises is itself a problem, named (the rest still run)."""
    try:
        check()
    except Exception as exc:  # noqa: BLE001 - a task's bug of any kind is what this reports
        say(f"{what}: raised {type(exc).__name__}: {exc}")


def _identity(task: Task[Any], say: Callable[[str], None]) -> None:
    name = getattr(task, "name", None)
    if not isinstance(name, str) or not name.isidentifier():
        say(f"name {name!r}: give the task a short identifier (it is used on the command line and in run.json)")
    behaviours = getattr(task, "behaviours", None)
    if not isinstance(behaviours, tuple) or not behaviours or len(set(behaviours)) != len(behaviours):
        say(f"behaviours {behaviours!r}: give a non-empty tuple of distinct names")
    regimes = getattr(task, "regimes", None)
    if not isinstance(regimes, tuple) or not regimes:
        say(f"regimes {regimes!r}: give a non-empty tuple (e.g. ('independent',))")
    settings = getattr(task, "world_settings", None)
    if not (isinstance(settings, type) and issubclass(settings, BaseModel)):
        say(f"world_settings {settings!r}: give the pydantic model of the world's settings")
        return
    try:
        settings()
    except Exception as exc:  # noqa: BLE001
        say(f"world_settings: its defaults do not make a world ({exc})")
    if not isinstance(getattr(task, "measure_labels", None), dict):
        say("measure_labels: give a dict (measure -> short label), empty if none")
    terms = getattr(task, "measure_terms", None)
    if not (isinstance(terms, Mapping) and all(isinstance(t, Term) for t in terms.values())):
        say("measure_terms: give a dict (measure -> coevo.tasks.base.Term: name, unit, definition), empty if none")


def _rules(task: Task[Any], behaviour: str, world: BaseModel, say: Callable[[str], None]) -> None:
    try:
        sch = schema(check_behaviour(task, behaviour))
    except RuleSetError:
        say(f"{behaviour}: no rule schema is registered under {behaviour!r} (register it when the task is imported)")
        return
    if not sch.sensors or not sch.actions:
        say(f"{behaviour}: its rule schema needs at least one sensor and one action")
    default = task.initial_rules(behaviour, world)
    if default is not None:
        _is_ruleset(default, behaviour, "initial_rules", say)
    ga = ga_settings(task, behaviour, build(GAConfig, TINY_GA))
    model = initial_model(task, behaviour, world, ga, np.random.default_rng(0))
    _is_ruleset(model, behaviour, "initial_model", say)
    usable = task.learnable_sensors(behaviour, world)
    if usable is not None and (np.shape(usable) != (sch.n_sensors,) or np.asarray(usable).dtype != bool
                               or not np.asarray(usable).any()):
        say(f"{behaviour}: learnable_sensors must be None or {sch.n_sensors} booleans, some true")


def _is_ruleset(rs: Any, behaviour: str, what: str, say: Callable[[str], None]) -> None:
    if not isinstance(rs, RuleSet):
        say(f"{behaviour}: {what} gave {type(rs).__name__}, not a RuleSet")
    elif rs.behaviour != behaviour:
        say(f"{behaviour}: {what} gave a {rs.behaviour} rule set")
    elif RuleSet.from_dict(rs.to_dict()) != rs:
        say(f"{behaviour}: {what} does not survive its own round trip through to_dict/from_dict")


def _ga(task: Task[Any], behaviour: str, say: Callable[[str], None]) -> None:
    filled = ga_settings(task, behaviour, GAConfig())
    left = sorted(k for k, v in filled.model_dump().items() if v is None)
    if left:
        say(f"{behaviour}: ga_settings leaves {', '.join(left)} unset (ga_choices may not choose None for a "
            "setting left to the task)")
    if check_ga(task, GAConfig()) != GAConfig():
        say("check_ga must return the settings it was given, not change them")


def _partners(task: Task[Any], behaviour: str, say: Callable[[str], None]) -> None:
    for regime in task.regimes:
        needed = task.partners_needed(behaviour, regime)
        strangers = [p for p in needed if p not in task.behaviours or p == behaviour]
        if strangers:
            say(f"{behaviour} in {regime}: partners_needed names {strangers}, not other behaviours of the task")


def _partner_models(task: Task[Any], behaviour: str, world: BaseModel, ga: GAConfig) -> Partners:
    needed = {p for r in task.regimes for p in task.partners_needed(behaviour, r)}
    return {p: initial_model(task, p, world, ga_settings(task, p, ga), np.random.default_rng(7)) for p in sorted(needed)}


def _evaluation(task: Task[Any], behaviour: str, world: BaseModel, seed: int, say: Callable[[str], None]) -> None:
    ga = ga_settings(task, behaviour, build(GAConfig, TINY_GA))
    partners = _partner_models(task, behaviour, world, ga)
    policies = [initial_model(task, behaviour, world, ga, np.random.default_rng(seed + k)) for k in range(2)]

    def evaluate() -> Evaluation:
        return task.evaluator(behaviour, world, ga).evaluate(policies, partners, np.random.default_rng(seed))

    first, again = evaluate(), evaluate()
    fit = np.asarray(first.fitness)
    if fit.shape != (2,) or not np.all(np.isfinite(fit)) or np.any(fit < 0) or np.any(fit > 1):
        say(f"{behaviour}: fitness must be one payoff in [0, 1] per policy, got {fit!r}")
    if np.shape(first.episodes) != (2,) or len(first.experience) != 2:
        say(f"{behaviour}: an evaluation of 2 policies must give 2 episode counts and 2 experiences")
    if not (np.array_equal(fit, again.fitness) and np.array_equal(first.episodes, again.episodes)):
        say(f"{behaviour}: the same policies, partners and seed gave other numbers "
            f"({fit.tolist()} then {np.asarray(again.fitness).tolist()}): evaluation must be deterministic")
    evaluator = task.evaluator(behaviour, world, ga)
    measured = [evaluator.measures(policies[0], partners, first, lambda: np.random.default_rng(seed)) for _ in range(2)]
    if measured[0] != measured[1]:
        say(f"{behaviour}: measures() of the same evaluation differ between calls")
    _numbers(measured[0], f"{behaviour}: measures", say)
    status = task.status_measures(behaviour, measured[0])
    _numbers(status, f"{behaviour}: status_measures", say, none_ok=False)
    final = task.final_measures(behaviour, policies[0], world=world, partners=partners, epochs=2, seed=seed)
    _numbers(final, f"{behaviour}: final_measures", say)


def _numbers(values: Mapping[str, Any], what: str, say: Callable[[str], None], *, none_ok: bool = True) -> None:
    if not isinstance(values, Mapping):
        say(f"{what} must be a mapping of names to numbers, got {type(values).__name__}")
        return
    for k, v in values.items():
        ok = (v is None and none_ok) or (isinstance(v, (int, float, np.number)) and not isinstance(v, bool)
                                         and math.isfinite(float(v)))
        if not isinstance(k, str) or not ok:
            say(f"{what}: {k!r} = {v!r} is not a finite number{' or None' if none_ok else ''}")


def _pictures(task: Task[Any], world: BaseModel, seed: int, say: Callable[[str], None]) -> None:
    display = task.display()
    if display is None:
        return  # a task without pictures says so (coevo show names it); nothing more to check
    if not isinstance(display, TaskDisplay):
        say(f"pictures: display() gave {type(display).__name__}, not a TaskDisplay (or None for no pictures)")
        return
    ga = build(GAConfig, TINY_GA)
    rules = {b: initial_model(task, b, world, ga_settings(task, b, ga), np.random.default_rng(seed))
             for b in task.behaviours}
    played = display.show_play(display.show_robot("checked", world, rules), seed=seed, episodes=1)
    again = display.show_play(display.show_robot("checked", world, rules), seed=seed, episodes=1)
    scene, replayed = display.show_scene(played), display.show_scene(again)
    if not scene.frames or not scene.spans:
        say("pictures: show_scene drew no frames or no episode spans from one episode")
    if replayed.captions != scene.captions or len(replayed.tracks) != len(scene.tracks) or not all(
            np.array_equal(a.xy, b.xy, equal_nan=True) for a, b in zip(replayed.tracks, scene.tracks)):
        say("pictures: the same robot and seed played another way (show_play must be deterministic)")
    if not display.show_rules(played):
        say("pictures: show_rules gave no rule tables")
    behaviour = task.behaviours[0]
    with tempfile.TemporaryDirectory() as tmp:
        png = Path(tmp) / "best.png"
        display.picture(png, behaviour, rules[behaviour], world=world, partners={}, seed=seed, name="checked")
        if png.exists() and png.read_bytes()[:8] != b"\x89PNG\r\n\x1a\n":
            say("pictures: picture() wrote a file that is not a PNG")
