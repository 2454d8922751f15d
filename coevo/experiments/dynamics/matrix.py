"""Every published version of a behaviour against every published version of a partner, on fresh episodes.

A run's store holds each behaviour's published policies: a new version whenever a generation's best beat the
best so far (its ``generation`` says when).  For each behaviour ``A`` and each partner ``B`` it learned against in
the run's regime (the task's ``partners_needed``), :func:`play_matrix` evaluates every version of ``A`` with every
version of ``B`` (any other partner at its final version) on the same fresh episodes from one seed (common random
numbers: the cells differ by the policies only), with the task's own evaluator.  ``fitness[i, j]`` is version
``i`` of ``A``'s mean payoff with version ``j`` of ``B``: the CIAO matrix (Current Individual vs Ancestral
Opponents) when ``i`` is read as the present and ``j <= i`` as its ancestors, and each row's mean the master
tournament's score of that version.  A cooperative run reads the same way: what a Mutual run's Executive would
have earned with each generation's Docking.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coevo.errors import RunDirError
from coevo.policy.rules import RuleSet
from coevo.rundir.layout import RunPaths, read_store

__all__ = ["DONE", "interval", "Versions", "Matrix", "versions_of", "adopted_versions", "within", "pairs_of", "play_matrix", "read_run",
           "check_finished"]

#: What a run's dynamics/ says it was played with, written last (a folder of runs' summary reads it).
DONE = "dynamics.json"


def interval(x: Any) -> tuple[float | None, float | None]:
    """A 95 % t interval of the mean of ``x``; none below three values (too few for one to hold)."""
    from scipy import stats

    if len(x) < 3:
        return None, None
    half = float(stats.t.ppf(0.975, len(x) - 1) * np.std(x, ddof=1) / np.sqrt(len(x)))
    return round(float(np.mean(x)) - half, 6), round(float(np.mean(x)) + half, 6)


@dataclass(frozen=True)
class Versions:
    """One behaviour's published policies in order: their versions, the generation each was published at."""

    behaviour: str
    version: tuple[int, ...]
    generation: tuple[int, ...]
    rules: tuple[RuleSet, ...]


@dataclass(frozen=True)
class Matrix:
    """``fitness[i, j]``: version ``i`` of ``learner`` with version ``j`` of ``partner``, on ``episodes`` episodes."""

    learner: Versions
    partner: Versions
    fitness: np.ndarray
    episodes: int
    seed: int


def versions_of(run: RunPaths, behaviour: str) -> Versions:
    """The published versions of ``behaviour`` in the run's store (a version stored twice counts once)."""
    try:
        updates = read_store(run.store_file(behaviour))
    except RunDirError as exc:
        raise RunDirError(f"{run.dir}: {exc}") from None
    by_version = {u.version: u for u in updates}
    if not by_version:
        raise RunDirError(f"{run.store_file(behaviour)} holds no published {behaviour} policy")
    ordered = [by_version[v] for v in sorted(by_version)]
    return Versions(behaviour, tuple(u.version for u in ordered), tuple(u.generation for u in ordered),
                    tuple(u.ruleset() for u in ordered))


def adopted_versions(run: RunPaths, behaviour: str, task: Any, regime: str) -> Versions:
    """The versions of ``behaviour`` its partners adopted (their adoption logs hold the rules): under a model by each
    generation's best (``current``, ``hall``) every generation's best they met, by generation (the version is the
    generation), which the store does not hold."""
    from coevo.rundir.layout import read_jsonl
    from coevo.rundir.records import AdoptionLine

    met: dict[int, RuleSet] = {}
    for a in task.behaviours:
        if behaviour in task.partners_needed(a, regime):
            for row in read_jsonl(run.worker(a).adoptions, schema=AdoptionLine):
                if row["partner"] == behaviour and row.get("rules") is not None:
                    met.setdefault(int(row["version"]), RuleSet.from_dict(row["rules"]))
    if not met:
        raise RunDirError(f"{run.dir}: no partner of {behaviour} adopted any of its generations' bests")
    order = sorted(met)
    return Versions(behaviour, tuple(order), tuple(order), tuple(met[v] for v in order))


def within(v: Versions, first: int, last: int) -> Versions:
    """The versions of ``v`` published at generations ``first`` to ``last``, and the one in play at ``first`` (the
    last published by then) ahead of them."""
    keep = [i for i, g in enumerate(v.generation) if first <= g <= last]
    before = [i for i, g in enumerate(v.generation) if g < first]
    keep = before[-1:] + keep
    if not keep:
        raise RunDirError(f"no {v.behaviour} version was published by generation {last}: choose a later --generations")
    return Versions(v.behaviour, tuple(v.version[i] for i in keep), tuple(v.generation[i] for i in keep),
                    tuple(v.rules[i] for i in keep))


def pairs_of(task: Any, regime: str) -> list[tuple[str, str]]:
    """(learner, partner) for every partner a behaviour learned against in ``regime``."""
    return [(a, b) for a in task.behaviours for b in task.partners_needed(a, regime)]


def play_matrix(task: Any, world: Any, ga: Any, learner: Versions, partner: Versions,
                others: dict[str, RuleSet], *, episodes: int, seed: int,
                tick: Callable[[int, int], None] | None = None) -> Matrix:
    """Every version of ``learner`` with every version of ``partner`` (``others``: the rest of its partners)."""
    evaluator = task.evaluator(learner.behaviour, world, ga)
    fitness = np.zeros((len(learner.rules), len(partner.rules)))
    for j, rs in enumerate(partner.rules):
        ev = evaluator.evaluate(list(learner.rules), {**others, partner.behaviour: rs}, np.random.default_rng(seed),
                                episodes=episodes)
        fitness[:, j] = ev.fitness
        if tick is not None:
            tick(j + 1, len(partner.rules))
    return Matrix(learner, partner, fitness, episodes, seed)


def read_run(run_dir: Path) -> tuple[Any, Any, Any, Any, RunPaths]:
    """(settings, task, world, GA settings, paths) of a finished run directory."""
    from coevo.rundir.settings import RunSettings

    paths = RunPaths(Path(run_dir))
    if not paths.run_json.is_file():
        raise RunDirError(f"{str(run_dir)!r} is not a run directory (no run.json)")
    settings = RunSettings.load(paths.run_json)
    return settings, settings.the_task, settings.world_config(), settings.ga, paths


def check_finished(paths: RunPaths, task: Any, generations: int) -> None:
    """A RunDirError naming the first worker of the run whose ``done.json`` does not say it finished (a run still
    going, or stopped and not yet resumed)."""
    from coevo.rundir.layout import read_json

    run_dir = paths.dir
    for b in task.behaviours:
        w = paths.worker(b)
        if not w.done.is_file():
            raise RunDirError(f"{str(run_dir)!r} is not finished: its {b} worker has no {w.done.name} (still going, "
                              f"or stopped: continue it with coevo run --resume {run_dir})")
        done = read_json(w.done, what=f"{b} worker's done.json")
        if done.get("finished") is not True:
            raise RunDirError(f"{str(run_dir)!r} is not finished: its {b} worker stopped after "
                              f"{done.get('generations')!r} of {generations} generations (continue it with coevo "
                              f"run --resume {run_dir})")
