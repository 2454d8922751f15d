"""The task interface: the core names no task, and a second task plugs in beside the fuel task."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from coevo.config import GAConfig
from coevo.errors import ConfigError, RuleSetError
from coevo.ga import GA
from coevo.policy.rules import RuleSet, random_ruleset
from coevo.policy.schema import registered, schema
from coevo.policy.text import format_ruleset, parse_ruleset
from coevo.tasks import TASKS, get_task, task_of, usable_tasks
from coevo.tasks.base import check_behaviour, check_regime
from coevo.tasks.checker import check_task
from coevo.tasks.corridor import CorridorConfig, CorridorTask

CORRIDOR_GA = GAConfig(generations=12, population=20, episodes=12, best_episodes=24, initial_rules=6, max_rules=16)


def test_every_task_declares_its_behaviours_with_unique_names() -> None:
    names = [b for t in usable_tasks().values() for b in t.behaviours]
    assert len(names) == len(set(names))
    assert set(names) <= set(registered())
    for t in usable_tasks().values():
        for b in t.behaviours:
            assert task_of(b) is t and check_behaviour(t, b) == b and schema(b).behaviour == b
            assert t.world_settings()  # every setting has a default


def test_unknown_tasks_behaviours_and_regimes_are_named() -> None:
    with pytest.raises(ConfigError, match="'maze'"):
        get_task("maze")
    with pytest.raises(ConfigError, match="'flying'"):
        task_of("flying")
    with pytest.raises(RuleSetError, match="'flying'"):
        schema("flying")
    with pytest.raises(ConfigError, match="'mutual'"):
        check_regime(get_task("corridor"), "mutual")


@pytest.mark.parametrize("name", sorted(TASKS))
def test_every_task_passes_the_task_checker(name: str) -> None:
    assert check_task(get_task(name)) == []


class _Noisy(CorridorTask):
    """A corridor whose evaluation draws from the global random state (not the seed it is given)."""

    def evaluator(self, behaviour, world, ga):  # type: ignore[no-untyped-def]
        inner = super().evaluator(behaviour, world, ga)
        real = inner.evaluate

        def evaluate(*args, **kw):  # type: ignore[no-untyped-def]
            ev = real(*args, **kw)
            ev.fitness = np.clip(ev.fitness + np.random.default_rng().random(len(ev.fitness)) * 0.1, 0, 1)
            return ev

        inner.evaluate = evaluate  # type: ignore[method-assign]
        return inner


class _Careless(CorridorTask):
    """A corridor that names a partner it does not have and leaves a GA setting to nobody."""

    def partners_needed(self, behaviour: str, regime: str) -> tuple[str, ...]:
        return ("executive",)

    def ga_choices(self, behaviour: str) -> dict[str, object]:
        return {"max_rules": None}


def test_the_task_checker_names_what_a_broken_task_gets_wrong() -> None:
    noisy = check_task(_Noisy())
    assert any("evaluation must be deterministic" in p for p in noisy), noisy
    careless = check_task(_Careless(), pictures=False)
    assert any("partners_needed names ['executive']" in p for p in careless), careless
    assert any("leaves" in p and "max_rules" in p for p in careless), careless
    assert check_task(CorridorTask()) == []  # the same checks pass the real one


class _Blind(CorridorTask):
    """A corridor without pictures."""

    def display(self) -> None:
        return None


def test_a_task_without_pictures_says_so_and_still_passes_the_checker(tmp_path: Path) -> None:
    from coevo.runs.learn import learn
    from coevo.tasks.showing import display_of

    with pytest.raises(ConfigError, match="task 'corridor' has no pictures: coevo show cannot draw it"):
        display_of(_Blind())
    assert check_task(_Blind()) == []
    # the corridor's display draws no best.png (TaskDisplay.picture's default): coevo learn writes none
    assert not (learn("corridor", world=CorridorConfig(), ga=CORRIDOR_GA.model_copy(update={"generations": 1}),
                      seed=0, out_dir=tmp_path / "l", measure_epochs=2).out_dir / "best.png").exists()


def test_a_corridor_rule_set_prints_and_parses_like_any_other() -> None:
    rs = random_ruleset("corridor", 5, np.random.default_rng(1))
    assert parse_ruleset(format_ruleset(rs)) == rs
    assert RuleSet.from_dict(rs.to_dict()) == rs


def test_the_same_ga_learns_the_corridor_and_replays_it_exactly() -> None:
    task = get_task("corridor")
    world = CorridorConfig()

    def run() -> list[dict]:
        ga = GA(task, "corridor", world=world, ga=CORRIDOR_GA, seed=4)
        return [ga.generation({}).as_dict() for _ in range(CORRIDOR_GA.generations)]

    first, again = run(), run()
    for row in (*first, *again):
        row.pop("seconds")
    assert first == again
    assert set(first[0]) >= {"generation", "best_fitness", "arrived"}
    # Learning: the best so far beats the random first population by far, and always arrives.
    assert first[-1]["best_so_far"] > first[0]["population_mean"] + 0.2
    assert first[-1]["arrived"] == 100.0


def test_a_task_refuses_another_tasks_settings() -> None:
    """Settings enter through the task's own model (run.json, --world); inside, a Task[W] takes only a W (mypy)."""
    from coevo.rundir.settings import RunSettings
    from coevo.tasks.fuel.settings import WorldConfig

    with pytest.raises(ConfigError, match="CorridorConfig.*arena"):
        RunSettings.make(run="c", task="corridor", regime="independent", world=WorldConfig().model_dump())


@pytest.mark.service
def test_the_same_worker_and_broker_run_the_corridor(tmp_path: Path) -> None:
    """coevo run: a broker and the corridor's worker as real processes, then coevo check replays it."""
    r = subprocess.run([sys.executable, "-m", "coevo", "run", "--task", "corridor", "--run", "c", "--root", str(tmp_path),
                        "--generations", "6", "--population", "10", "--episodes", "10", "--quiet", "--measure-epochs", "20"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "arrived" in r.stdout
    settings = json.loads((tmp_path / "c" / "run.json").read_text())
    assert settings["task"] == "corridor" and settings["world"] == CorridorConfig().model_dump()
    c = subprocess.run([sys.executable, "-m", "coevo", "check", str(tmp_path / "c")], capture_output=True, text=True,
                       timeout=120)
    assert c.returncode == 0 and "complete (replay exact)" in c.stdout, c.stdout + c.stderr
