"""The learning module (report Appendix B §6): a GA on a simulation model that follows the capability list.

The module owns the simulation model, a :class:`~coevo.tasks.door.DoorConfig` whose
``failed`` sonars are the complement of the capability list it was last given
(:meth:`LearningModule.set_capabilities`); its GA evaluates every individual on that
model.  It never sees the execution module's world.

On a change it restarts (report §6): 50 % of the population stays, the other 50 %
becomes copies of the initial rules, or, with a :class:`~coevo.cel.casebase.CaseBase`,
the nearest cases by capability list.  Which half stays *(ours)*: the elite, then a
random draw from the module's own generator (the population has just been bred and
has no fitness yet).  With a case base *(ours)*: the replaced half is filled with the
``cases`` nearest cases in turn, nearest first; before the restart the best since the
last change is stored as a case under the capability list it was learned with.

What the execution module gets (report §7: "the best rules discovered by the
learning system since the last change"): after each generation whose best
individual, re-evaluated on ``best_episodes`` trials, beats the best since the last
change, that individual (:attr:`GenerationStep.new_best`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from coevo.cel.casebase import Case, CaseBase
from coevo.cel.monitor import check_capabilities
from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga import GA, GenerationReport
from coevo.policy.rules import RuleSet
from coevo.tasks.base import Evaluation, Partners, Tick, check_behaviour
from coevo.tasks.door import DOOR, DoorTask, default_ruleset
from coevo.tasks.door.evaluate import DoorEvaluator
from coevo.tasks.door.settings import SONARS, DoorConfig

__all__ = ["LearningModule", "GenerationStep", "KEEP", "CASES"]

KEEP = 0.5  # report §6: "we use 50% of the population at the time of the detected failure"
CASES = 3  # (ours) how many nearest cases fill the replaced half, in turn


@dataclass(frozen=True)
class GenerationStep:
    """One generation of the learner: the GA's report, the capability list it ran under, and the new best
    since the last change for the execution module (None when this generation did not beat it)."""

    report: GenerationReport
    capabilities: tuple[str, ...]
    new_best: RuleSet | None


class _ModelEvaluator(DoorEvaluator):
    """A door evaluator that always plays the learning module's current simulation model."""

    def __init__(self, module: LearningModule, ga: GAConfig) -> None:
        super().__init__(module.model, ga)
        self._module = module

    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        self.world_cfg = self._module.model
        return super().evaluate(policies, partners, rng, episodes=episodes, tick=tick)



class _ModelTask(DoorTask):
    """The door task whose evaluator follows a learning module's model (so the GA needs no new world)."""

    def __init__(self, module: LearningModule) -> None:
        self._module = module

    def evaluator(self, behaviour: str, world: DoorConfig, ga: GAConfig) -> _ModelEvaluator:
        check_behaviour(self, behaviour)
        return _ModelEvaluator(self._module, ga)


class LearningModule:
    """A GA on the door task with a changing simulation model; see the module docstring."""

    def __init__(self, world: DoorConfig, ga: GAConfig, *, seed: int, case_base: CaseBase | None = None,
                 keep: float = KEEP, cases: int = CASES) -> None:
        if not 0.0 <= keep <= 1.0:
            raise ConfigError(f"keep must be a fraction in [0, 1], got {keep}")
        if cases < 1:
            raise ConfigError(f"cases must be at least 1, got {cases}")
        if not isinstance(world, DoorConfig):
            raise ConfigError(f"the learning module needs DoorConfig settings, got {type(world).__name__}")
        self.model = world
        self.keep, self.cases = keep, cases
        self.case_base = case_base
        self.initial = default_ruleset()
        self.rng = np.random.default_rng([seed, 1])  # the module's own choices; the GA has its generator
        self.ga = GA(_ModelTask(self), DOOR, world=world, ga=ga, seed=seed)
        self.best: RuleSet | None = None  # the best since the last change
        self.best_fitness = -np.inf
        self.changes = 0
        self.last_case: Case | None = None  # the case the last change stored (None: none, or no case base)
        self.last_cases: list[Case] = []  # the cases the last restart seeded the population with

    @property
    def capabilities(self) -> tuple[str, ...]:
        """The capability list the simulation model follows."""
        return self.model.capabilities

    @property
    def generation_no(self) -> int:
        return self.ga.generation_no

    def generation(self, tick: Tick | None = None) -> GenerationStep:
        """One GA generation on the current model (``tick``: called between evaluation rounds, as by the GA)."""
        rep = self.ga.generation({}, tick=tick)
        new = None
        if rep.best_fitness > self.best_fitness and self.ga.current is not None:
            self.best, self.best_fitness = self.ga.current, rep.best_fitness
            new = self.best
        return GenerationStep(rep, self.capabilities, new)

    def state_dict(self) -> dict[str, Any]:
        """The GA's state, the model's failed sonars, the module's generator and its best since the last
        change, as plain data (the case base is kept apart, in its own JSON lines)."""
        return {"ga": self.ga.state_dict(), "failed": list(self.model.failed),
                "rng": json.dumps(self.rng.bit_generator.state), "changes": self.changes,
                "best": None if self.best is None else self.best.to_dict(),
                "best_fitness": None if self.best is None else float(self.best_fitness)}

    def load_state(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state_dict` of a module with the same settings."""
        try:
            model = DoorConfig.model_validate({**self.model.model_dump(), "failed": state["failed"]})
            rng_state = json.loads(state["rng"])
            best = None if state["best"] is None else RuleSet.from_dict(state["best"])
            changes = int(state["changes"])
        except (KeyError, TypeError, ValueError) as exc:  # pydantic's ValidationError is a ValueError
            raise ConfigError(f"not a learning module state: {exc}") from exc
        self.ga.load_state(state["ga"])
        self.model, self.changes = model, changes
        self.rng.bit_generator.state = rng_state
        self.best = best
        self.best_fitness = -np.inf if best is None else float(state["best_fitness"])

    def set_capabilities(self, capabilities: Sequence[str]) -> bool:
        """The monitor's new capability list: fail the other sonars in the model and restart.  Returns False
        (and does nothing) when the list is the one in force."""
        caps = check_capabilities(capabilities)
        if caps == self.capabilities:
            return False
        self.remember()
        self.model = DoorConfig.model_validate({**self.model.model_dump(), "failed": [s for s in SONARS if s not in caps]})
        self.restart()
        self.changes += 1
        return True

    def remember(self) -> None:
        """Store the best since the last change in the case base (if any), under the model's capability list."""
        self.last_case = None
        if self.case_base is not None and self.best is not None:
            self.last_case = self.case_base.add(self.capabilities, self.best, fitness=self.best_fitness,
                                                generation=self.generation_no)

    def restart(self) -> list[int]:
        """Keep ``keep`` of the population, refill the rest (see the module docstring) and forget the best
        since the last change.  Returns the indices replaced."""
        n = len(self.ga.population)
        n_keep = int(round(self.keep * n))
        elite = min(self.ga.cfg.elite, n_keep)
        kept = set(range(elite)) | {int(i) for i in self.rng.permutation(np.arange(elite, n))[: n_keep - elite]}
        replaced = [i for i in range(n) if i not in kept]
        self.ga.replace(replaced, self._newcomers(len(replaced)))
        self.best, self.best_fitness = None, -np.inf
        return replaced

    def _newcomers(self, n: int) -> list[RuleSet]:
        nearest = self.case_base.nearest(self.capabilities, self.cases) if self.case_base else []
        self.last_cases = nearest
        if not nearest:
            return [self.initial] * n
        return [nearest[i % len(nearest)].rules for i in range(n)]
