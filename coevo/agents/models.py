"""A worker's models of the other agents, and the regimes that say which it needs.

Regimes (SPEC §2):

- ``independent``: Tracking and Docking learn with the trivial Executive that
  always picks them and need no partner; the Executive learns against Tracking's
  and Docking's best so far.
- ``mutual``: every agent learns against the other two's best so far, so
  Tracking and Docking only get the episodes the best-so-far Executive gives them.

Until a partner has published anything, its model is the partner's initial
behaviour *(ours)*: "best so far" of a GA that has not finished a generation is
one of its initial policies, so Tracking's and Docking's shipped default rule sets
(``GAConfig.initial = "default"``), else a random rule set drawn from the worker's
seed (the Executive's always).  Model kinds: ``best`` (the
newest published best so far, the report's choice), ``current`` (the partner's
current policy: the best individual of its latest generation, published every
generation on its own key) and ``recent`` (each generation, one of the last
``recent`` bests at random).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from coevo.behaviours import Behaviour
from coevo.errors import ConfigError
from coevo.ga.evaluate import Partners
from coevo.policy.defaults import default_ruleset
from coevo.policy.rules import RuleSet, random_ruleset

__all__ = ["REGIMES", "MODELS", "partners_needed", "PartnerModels"]

REGIMES = ("mutual", "independent")
MODELS = ("best", "current", "recent")
Regime = Literal["mutual", "independent"]


def partners_needed(behaviour: Behaviour, regime: str) -> tuple[Behaviour, ...]:
    if regime not in REGIMES:
        raise ConfigError(f"unknown regime {regime!r} (use mutual or independent)")
    others = tuple(b for b in Behaviour if b is not behaviour)
    if behaviour is Behaviour.EXECUTIVE or regime == "mutual":
        return others
    return ()


@dataclass
class PartnerModels:
    """The partner policies a worker evaluates against, with the versions in use."""

    behaviour: Behaviour
    regime: str
    seed: int
    kind: str = "best"
    recent: int = 5
    initial_rules: int = 16
    initial: str = "default"
    versions: dict[Behaviour, int] = field(default_factory=dict)
    _bests: dict[Behaviour, list[RuleSet]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in MODELS:
            raise ConfigError(f"unknown partner model {self.kind!r} (use {' or '.join(MODELS)})")
        self.needed = partners_needed(self.behaviour, self.regime)
        for b in self.needed:
            rng = np.random.default_rng([self.seed, list(Behaviour).index(b), 7])
            default = default_ruleset(b) if self.initial == "default" else None
            self._bests[b] = [default if default is not None else random_ruleset(b, self.initial_rules, rng)]
            self.versions[b] = 0
        self._rng = np.random.default_rng([self.seed, 11])

    def adopt(self, behaviour: Behaviour, version: int, rules: RuleSet) -> bool:
        """Take a newer version of a partner; False if it is not newer or not needed."""
        if behaviour not in self.needed or version <= self.versions.get(behaviour, 0):
            return False
        self.versions[behaviour] = version
        self._bests[behaviour] = (self._bests[behaviour] + [rules])[-self.recent :]
        return True

    def state_dict(self) -> dict[str, Any]:
        """The models, versions and generator state, as plain data (for checkpoints)."""
        return {
            "versions": {b.value: v for b, v in self.versions.items()},
            "bests": {b.value: [r.to_dict() for r in rs] for b, rs in self._bests.items()},
            "rng": json.dumps(self._rng.bit_generator.state),
        }

    def load_state(self, state: dict[str, Any]) -> None:
        for b in self.needed:
            self.versions[b] = int(state["versions"][b.value])
            self._bests[b] = [RuleSet.from_dict(d) for d in state["bests"][b.value]]
        self._rng.bit_generator.state = json.loads(state["rng"])

    def partners(self) -> Partners:
        """The models for the next generation (draws, for ``recent``, from this worker's own RNG)."""
        pick: dict[str, RuleSet | None] = {"executive": None, "tracking": None, "docking": None}
        for b in self.needed:
            bests = self._bests[b]
            pick[b.value] = bests[-1] if self.kind == "best" else bests[int(self._rng.integers(len(bests)))]
        return Partners(**pick)
