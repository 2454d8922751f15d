"""``coevo learn``: one behaviour learns offline, in one process, with no network.

A behaviour learns in its task's ``independent`` regime: against fixed rule sets
of the partners that regime gives it (the fuel task's Executive against Tracking
and Docking), or, where it needs none, alone (Tracking and Docking with the
trivial Executive that always picks them).  Given partners' rule sets that regime does not take, it learns in the
first of its task's regimes that takes them (a competitive task's side against a given opponent: ``mutual``).  The run directory
gets the learning curve (CSV and JSON), the best rule set as text, and the
measures of that best policy (docs/spec.md §1).
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from pydantic import BaseModel

from coevo import __version__
from coevo.agents.history import HistoryFeed
from coevo.agents.models import PartnerModels
from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga import GA, GenerationReport
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.rundir.layout import LearnPaths, staged_dir, write_csv, write_json, write_text
from coevo.tasks import Task, task_of

__all__ = ["learn", "LearnResult", "default_out"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LearnResult:
    out_dir: Path
    best: RuleSet
    curve: list[GenerationReport]
    measures: dict[str, float | int | None]
    seconds: float


def default_out(behaviour: str, seed: int) -> Path:
    """Where a learn run goes unless told: runs/learn-BEHAVIOUR-seedN-TIME."""
    return Path("runs") / f"learn-{behaviour}-seed{seed}-{time.strftime('%Y%m%d-%H%M%S')}"


def _regime_for(task: Task, behaviour: str, given: set[str]) -> str:
    """The regime an offline learner learns in: ``independent``, unless the partners given fit only another."""
    first = "independent" if "independent" in task.regimes else task.regimes[0]
    if given <= set(task.partners_needed(behaviour, first)):
        return first
    return next((r for r in task.regimes if given <= set(task.partners_needed(behaviour, r))), first)


def learn(
    behaviour: str,
    *,
    world: BaseModel,
    ga: GAConfig,
    seed: int,
    out_dir: Path,
    partners: dict[str, RuleSet] | None = None,
    seed_policy: RuleSet | None = None,
    measure_epochs: int = 100,
    on_generation: Callable[[GenerationReport], None] | None = None,
    history: Path | None = None,
    rate: float = 1.0,
) -> LearnResult:
    task = task_of(behaviour)
    behaviour = str(behaviour)
    partners = dict(partners or {})
    regime = _regime_for(task, behaviour, set(partners))
    needed = task.partners_needed(behaviour, regime)
    feed = None
    extra = sorted(set(partners) - set(needed))
    if extra:
        raise ConfigError(f"{behaviour} learns offline without {' and '.join(extra)}; "
                          f"{'its partners are ' + ' and '.join(needed) if needed else 'it needs no partner'}")
    if history is not None:
        if not needed:
            raise ConfigError(f"--history feeds recorded partner policies to a behaviour that has partners; {behaviour} has none")
        feed = HistoryFeed(Path(history), rate, partners=needed)
        models = PartnerModels(task, behaviour, regime, seed, ga=ga, world=world)
        partners = dict(models.partners())
    elif set(partners) != set(needed):
        missing = [b for b in needed if b not in partners]
        raise ConfigError(
            f"{behaviour} learns against fixed {' and '.join(needed)} rule sets: give "
            f"{' and '.join(f'--{b} FILE' for b in missing)} (e.g. the best.rules of 'coevo learn --behaviour {missing[0]}')"
        )
    t0 = time.perf_counter()
    with staged_dir(out_dir) as tmp_dir:
        tmp = LearnPaths(tmp_dir)
        write_json(tmp.config, {
            "coevo": __version__, "task": task.name, "behaviour": behaviour, "seed": seed,
            "world": world.model_dump(), "ga": ga.model_dump(),
            "history": str(history) if history else None, "rate": rate if history else None,
        })
        engine = GA(task, behaviour, world=world, ga=ga, seed=seed, seed_policy=seed_policy)
        curve: list[GenerationReport] = []
        adoptions: list[dict[str, object]] = []
        for g in range(ga.generations):
            if feed is not None:
                for m in feed.due(g):
                    if models.adopt(m.behaviour, m.version, m.ruleset()):
                        adoptions.append({"generation": g, "partner": m.behaviour, "version": m.version,
                                          "from_worker": m.worker, "partner_generation": m.generation})
                partners = dict(models.partners())
            rep = engine.generation(partners)
            curve.append(rep)
            if on_generation is not None:
                on_generation(rep)
        best = engine.played(engine.best_rules())  # as everyone else reads it: with its mirror images if symmetric
        _write_curve(tmp, curve, best, adoptions if feed is not None else None, partners)
        measures: dict[str, float | int | None] = {
            "best_fitness": engine.best_fitness,
            **task.final_measures(behaviour, best, world=world, partners=partners, epochs=measure_epochs,
                                  seed=seed + 1_000_003)}
        write_json(tmp.measures, measures)
        if (display := task.display()) is not None:  # a task without pictures draws no best.png
            display.picture(tmp.picture, behaviour, best, world=world, partners=partners, seed=seed + 1_000_003,
                            name=Path(out_dir).name)
        seconds = time.perf_counter() - t0
        write_json(tmp.timing, {"seconds": seconds, "generations": ga.generations})
    log.info("learned %s in %.1f s -> %s", behaviour, seconds, out_dir)
    return LearnResult(Path(out_dir), best, curve, measures, seconds)



def _write_curve(tmp: LearnPaths, curve: list[GenerationReport], best: RuleSet, adoptions: list[dict[str, object]] | None,
                 partners: dict[str, RuleSet]) -> None:
    """The learning curve (CSV and JSON), the best rules, the adoptions (with ``--history``) and the partners."""
    rows = [r.as_dict() for r in curve]
    write_csv(tmp.curve_csv, rows)
    write_json(tmp.curve_json, rows)
    write_text(tmp.best_rules, format_ruleset(best))
    if adoptions is not None:
        write_text(tmp.adoptions, "".join(json.dumps(a) + "\n" for a in adoptions))
    for b, rules in partners.items():
        # The partners it was measured with, so that 'coevo show DIR' can replay them together.
        write_text(tmp.partner_rules(b), format_ruleset(rules))
