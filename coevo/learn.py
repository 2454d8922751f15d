"""``coevo learn``: one behaviour learns offline, in one process, with no network.

Tracking and Docking learn with the trivial Executive that always picks them; the
Executive learns against fixed Tracking and Docking rule sets.  The run directory
gets the learning curve (CSV and JSON), the best rule set as text, and the SPEC
measures of that best policy.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from coevo import __version__
from coevo.agents.history import HistoryFeed
from coevo.agents.models import PartnerModels
from coevo.behaviours import Behaviour
from coevo.config import GAConfig, WorldConfig
from coevo.errors import ConfigError
from coevo.ga import GA, GenerationReport, Partners
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.robot import measure_behaviour
from coevo.rundir import staged_dir, write_csv, write_json, write_text

__all__ = ["learn", "LearnResult"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LearnResult:
    out_dir: Path
    best: RuleSet
    curve: list[GenerationReport]
    measures: dict[str, float | int]
    seconds: float


def learn(
    behaviour: Behaviour | str,
    *,
    world: WorldConfig,
    ga: GAConfig,
    seed: int,
    out_dir: Path,
    tracking: RuleSet | None = None,
    docking: RuleSet | None = None,
    seed_policy: RuleSet | None = None,
    measure_epochs: int = 100,
    on_generation: Callable[[GenerationReport], None] | None = None,
    history: Path | None = None,
    rate: float = 1.0,
) -> LearnResult:
    behaviour = Behaviour(behaviour)
    feed = None
    if history is not None:
        if behaviour is not Behaviour.EXECUTIVE:
            raise ConfigError("--history feeds recorded Tracking/Docking policies to the executive only")
        feed = HistoryFeed(Path(history), rate)
        models = PartnerModels(behaviour, "independent", seed, initial_rules=ga.initial_rules, initial=ga.initial)
        partners = models.partners()
    elif behaviour is Behaviour.EXECUTIVE:
        if tracking is None or docking is None:
            raise ConfigError(
                "the Executive learns against fixed Tracking and Docking rule sets: give --tracking FILE and "
                "--docking FILE (e.g. the best.rules of 'coevo learn --behaviour tracking' and '... docking')"
            )
        partners = Partners(tracking=tracking, docking=docking)
    else:
        if tracking is not None or docking is not None:
            raise ConfigError(f"{behaviour} learns offline with the trivial Executive; --tracking/--docking are for the executive")
        partners = Partners()
    t0 = time.perf_counter()
    with staged_dir(out_dir) as tmp:
        write_json(tmp / "config.json", {
            "coevo": __version__, "behaviour": behaviour.value, "seed": seed,
            "world": world.model_dump(), "ga": ga.model_dump(),
            "history": str(history) if history else None, "rate": rate if history else None,
        })
        engine = GA(behaviour, world=world, ga=ga, seed=seed, seed_policy=seed_policy)
        curve: list[GenerationReport] = []
        adoptions: list[dict[str, object]] = []
        for g in range(ga.generations):
            if feed is not None:
                for m in feed.due(g):
                    if models.adopt(m.behaviour, m.version, m.ruleset()):
                        adoptions.append({"generation": g, "partner": m.behaviour.value, "version": m.version,
                                          "from_worker": m.worker, "partner_generation": m.generation})
                partners = models.partners()
            rep = engine.generation(partners)
            curve.append(rep)
            if on_generation is not None:
                on_generation(rep)
        if engine.best is None:  # GAConfig allows no fewer than one generation, so this is a bug
            raise RuntimeError("no generation ran: the GA has no best policy")
        rows = [r.as_dict() for r in curve]
        write_csv(tmp / "curve.csv", rows)
        write_json(tmp / "curve.json", rows)
        write_text(tmp / "best.rules", format_ruleset(engine.best))
        if feed is not None:
            write_text(tmp / "adoptions.jsonl", "".join(json.dumps(a) + "\n" for a in adoptions))
            tracking, docking = partners.tracking, partners.docking
        if behaviour is Behaviour.EXECUTIVE and tracking is not None and docking is not None:
            # The partners it was measured with, so that 'coevo show DIR' can replay the combined robot.
            write_text(tmp / "tracking.rules", format_ruleset(tracking))
            write_text(tmp / "docking.rules", format_ruleset(docking))
        measures = measure_behaviour(
            behaviour, engine.best, world=world, tracking=tracking, docking=docking, epochs=measure_epochs, seed=seed + 1_000_003
        )
        measures = {"best_fitness": engine.best_fitness, **measures}
        write_json(tmp / "measures.json", measures)
        _picture(tmp / "best.png", behaviour, engine.best, world=world, tracking=tracking, docking=docking,
                 seed=seed + 1_000_003, name=Path(out_dir).name)
        seconds = time.perf_counter() - t0
        write_json(tmp / "timing.json", {"seconds": seconds, "generations": ga.generations})
    log.info("learned %s in %.1f s -> %s", behaviour, seconds, out_dir)
    return LearnResult(Path(out_dir), engine.best, curve, measures, seconds)


PICTURE_EPISODES = 3  # Tracking or Docking alone; an Executive's picture is one epoch


def _picture(path: Path, behaviour: Behaviour, best: RuleSet, *, world: WorldConfig, tracking: RuleSet | None,
             docking: RuleSet | None, seed: int, name: str) -> None:
    """best.png: the best policy playing a few episodes (or, for the Executive, one epoch); ~0.5 s."""
    from coevo.show import picture, robot_from_rules

    rules = {behaviour: best}
    if behaviour is Behaviour.EXECUTIVE and tracking is not None and docking is not None:
        rules |= {Behaviour.TRACKING: tracking, Behaviour.DOCKING: docking}
    robot = robot_from_rules(name, world, rules)
    picture(robot, path, seed=seed, episodes=None if robot.combined else PICTURE_EPISODES,
            title=f"{name}: the best {behaviour.value} policy, seed {seed}")
