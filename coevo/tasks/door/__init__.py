"""The door traversal task (report Appendix B; docs/spec.md §5): cross a room through an opening in a wall.

A robot starts on a line 4 ft in front of the back wall facing a random way and
must pass through a 6 ft opening, at a random place in a wall across the room, to
a goal line beyond it, sensing with seven sonars that may fail.  One behaviour,
``door``, learns alone (regime ``independent``, no partners).  The world is in
:mod:`.world` (batched, numpy ray casting), the settings with the sonar failures in
:mod:`.settings`, the rule schema in :mod:`.sensors`, the evaluator and the external
performance measure in :mod:`.evaluate`, its display (pictures) in :mod:`.pictures`, and the
restart on a change of capabilities (report §6) in :func:`restart`.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from importlib import resources
from typing import TYPE_CHECKING

import numpy as np

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet
from coevo.policy.text import parse_ruleset
from coevo.tasks.base import Partners, Task, check_behaviour
from coevo.tasks.door.evaluate import DoorEvaluator, measure
from coevo.tasks.door.sensors import DOOR
from coevo.tasks.door.settings import DOOR_GA, SONARS, DoorConfig, capability_label, door_ga

if TYPE_CHECKING:
    from coevo.ga import GA
    from coevo.tasks.showing import TaskDisplay

__all__ = ["DoorTask", "DoorConfig", "DOOR", "SONARS", "DOOR_GA", "door_ga", "default_ruleset", "restart",
           "capability_label"]


@cache
def default_ruleset() -> RuleSet:
    """The shipped initial rules: the direction to the goal line, nothing about walls (report §7)."""
    text = resources.files(__name__).joinpath("defaults/door.rules").read_text(encoding="utf-8")
    return parse_ruleset(text, DOOR)


class DoorTask(Task[DoorConfig]):
    name = "door"
    behaviours = (DOOR,)
    regimes = ("independent",)
    world_settings = DoorConfig
    flags = {"fail": "failed"}  # --fail front,front_right: the sonars that fail, in any spelling

    def initial_rules(self, behaviour: str, world: DoorConfig) -> RuleSet:
        check_behaviour(self, behaviour)
        return default_ruleset()

    def default_ga(self, **overrides: object) -> GAConfig:
        """GAConfig for this task: its defaults with :data:`DOOR_GA` on top, then ``overrides``."""
        return door_ga(**overrides)

    def evaluator(self, behaviour: str, world: DoorConfig, ga: GAConfig) -> DoorEvaluator:
        check_behaviour(self, behaviour)
        return DoorEvaluator(world, ga)

    def status_measures(self, behaviour: str, measures: Mapping[str, float | None]) -> dict[str, float]:
        return {"success": float(measures.get("success") or 0.0)}

    def final_measures(self, behaviour: str, best: RuleSet, *, world: DoorConfig, partners: Partners,
                       epochs: int, seed: int) -> Mapping[str, float | int | None]:
        """External performance (report §8.1): ``best`` on ``epochs`` fresh trials (100 in the report)."""
        check_behaviour(self, behaviour)
        return measure(best, world, trials=epochs, seed=seed)

    def display(self) -> TaskDisplay[DoorConfig]:
        """Its pictures (:mod:`coevo.tasks.door.pictures`), imported only when something is drawn."""
        from coevo.tasks.door.pictures import DoorDisplay

        return DoorDisplay()


def restart(ga: GA, world: DoorConfig, *, keep: float = 0.5) -> None:
    """Restart ``ga`` on a changed world (report §6): keep ``keep`` of its population, the rest become copies
    of the initial rules; its best so far is forgotten (the execution module uses the best found since
    the last change, report §7).

    Which individuals stay *(ours)*: the elite, then a random draw from the GA's own generator (the
    population has just been bred and has no fitness yet).

    This is the offline benchmark's restart (``coevo seeds --task door``, whose numbers depend on this exact
    draw); it sets the GA's attributes from outside.  The CEL architecture's proper home for it is
    :meth:`coevo.cel.learning.LearningModule.restart`: the same half kept, through :meth:`GA.replace`,
    with a simulation model the GA's evaluator follows, and optionally a case base.
    """
    if not 0.0 <= keep <= 1.0:
        raise ConfigError(f"keep must be a fraction in [0, 1], got {keep}")
    n = len(ga.population)
    n_keep = int(round(keep * n))
    elite = min(ga.cfg.elite, n_keep)
    rest = ga.rng.permutation(np.arange(elite, n))[: n_keep - elite]
    kept = list(range(elite)) + sorted(int(i) for i in rest)
    initial = default_ruleset()
    ga.population = [ga.population[i] for i in kept] + [initial] * (n - n_keep)
    ga.genes = np.concatenate([ga.genes[kept], np.zeros(n - n_keep, dtype=ga.genes.dtype)])
    ga.world_cfg = world
    ga.evaluator = ga.task.evaluator(ga.behaviour, world, ga.cfg)
    ga.best, ga.best_fitness = None, -np.inf
