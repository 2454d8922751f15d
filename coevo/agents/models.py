"""A worker's models of the other behaviours it learns against.

Which partners a behaviour needs in which regime is its task's to say
(:meth:`~coevo.tasks.base.Task.partners_needed`; the fuel task's regimes are in
:mod:`coevo.tasks.fuel`).  Until a partner has published anything, its model is
the partner's initial behaviour *(ours)*: "best so far" of a GA that has not
finished a generation is one of its initial policies, so its task's shipped
default rule set (``GAConfig.initial = "default"``), else a random rule set drawn
from the worker's seed.  Model kinds: ``best`` (the newest published best so far,
the report's choice), ``current`` (the partner's current policy: the best
individual of its latest generation, published every generation on its own key)
and ``recent`` (each generation, one of the last ``recent`` bests at random).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import BaseModel

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet
from coevo.config import MODELS
from coevo.tasks.base import Partners, Task, initial_model

__all__ = ["MODELS", "PartnerModels"]



@dataclass
class PartnerModels:
    """The partner policies a worker evaluates against, with the versions in use."""

    task: Task[Any]
    behaviour: str
    regime: str
    seed: int
    kind: str = "best"
    recent: int = 5
    ga: GAConfig = field(default_factory=GAConfig)  # its initial and initial_rules model unpublished partners
    world: BaseModel | None = None  # the world whose initial rules model them (None: the task's default world)
    versions: dict[str, int] = field(default_factory=dict)
    _bests: dict[str, list[RuleSet]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in MODELS:
            raise ConfigError(f"unknown partner model {self.kind!r} (use {' or '.join(MODELS)})")
        self.behaviour = str(self.behaviour)
        self.needed = self.task.partners_needed(self.behaviour, self.regime)
        world = self.task.world_settings() if self.world is None else self.world
        for b in self.needed:
            rng = np.random.default_rng([self.seed, self.task.behaviours.index(b), 7])
            self._bests[b] = [initial_model(self.task, b, world, self.ga, rng)]
            self.versions[b] = 0
        self._rng = np.random.default_rng([self.seed, 11])

    def adopt(self, behaviour: str, version: int, rules: RuleSet) -> bool:
        """Take a newer version of a partner; False if it is not newer or not needed."""
        if behaviour not in self.needed or version <= self.versions.get(behaviour, 0):
            return False
        self.versions[behaviour] = version
        self._bests[behaviour] = (self._bests[behaviour] + [rules])[-self.recent :]
        return True

    def state_dict(self) -> dict[str, Any]:
        """The models, versions and generator state, as plain data (for checkpoints)."""
        return {
            "versions": dict(self.versions),
            "bests": {b: [r.to_dict() for r in rs] for b, rs in self._bests.items()},
            "rng": json.dumps(self._rng.bit_generator.state),
        }

    def load_state(self, state: dict[str, Any]) -> None:
        for b in self.needed:
            self.versions[b] = int(state["versions"][b])
            self._bests[b] = [RuleSet.from_dict(d) for d in state["bests"][b]]
        self._rng.bit_generator.state = json.loads(state["rng"])

    def partners(self) -> Partners:
        """The models for the next generation (draws, for ``recent``, from this worker's own RNG)."""
        pick: dict[str, RuleSet] = {}
        for b in self.needed:
            bests = self._bests[b]
            pick[b] = bests[-1] if self.kind == "best" else bests[int(self._rng.integers(len(bests)))]
        return pick
