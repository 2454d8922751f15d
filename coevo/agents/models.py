"""A worker's models of the other behaviours it learns against.

Which partners a behaviour needs in which regime is its task's to say
(:meth:`~coevo.tasks.base.Task.partners_needed`; the fuel task's regimes are in
:mod:`coevo.tasks.fuel`).  Until a partner has published anything, its model is
the partner's initial behaviour *(ours)*: "best so far" of a GA that has not
finished a generation is one of its initial policies, so its task's shipped
default rule set (``GAConfig.initial = "default"``), else a random rule set drawn
from the worker's seed.  Model kinds: ``best`` (the newest published best so far,
the report's choice), ``current`` (the partner's current policy: the best
individual of its latest generation, published every generation on its own key),
``recent`` (each generation, one of the last ``recent`` bests at random) and ``hall``
(a hall of fame, after Rosin & Belew: every generation's best the partner published,
as ``current`` takes them, its initial model first; the newest, as ``current``, and
beside it ``hall_sample`` of the earlier ones, drawn afresh every generation without
replacement; the population plays a share ``hall_share`` of its episodes against
them, split evenly, the rest against the newest, so a generation costs what it
costs under ``best``; the best's re-evaluation, and so the learning curve, is
against the newest alone.  Where a task needs several partners, each sampled
opponent is one past best of each (the newest where a partner has no past yet).
docs/competition.md says why.)
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import BaseModel

from coevo.config import HALL_SAMPLE, HALL_SHARE, MODELS, GAConfig
from coevo.errors import ConfigError
from coevo.ga.evaluator import Mixture
from coevo.policy.rules import RuleSet
from coevo.tasks.base import Partners, Task, initial_model

__all__ = ["MODELS", "PartnerModels", "hall_settings"]


def hall_settings(kind: str, sample: int, share: float) -> dict[str, Any]:
    """A hall of fame's settings as a worker records them (worker.json) and :class:`PartnerModels` takes them; none for
    another kind of model (so the workers of other kinds record what they always did)."""
    return {"hall_sample": sample, "hall_share": share} if kind == "hall" else {}


@dataclass
class PartnerModels:
    """The partner policies a worker evaluates against, with the versions in use."""

    task: Task[Any]
    behaviour: str
    regime: str
    seed: int
    kind: str = "best"
    recent: int = 5
    hall_sample: int = HALL_SAMPLE  # kind "hall": past bests sampled for each generation
    hall_share: float = HALL_SHARE  # kind "hall": the share of the population's episodes played against them
    ga: GAConfig = field(default_factory=GAConfig)  # its initial and initial_rules model unpublished partners
    world: BaseModel | None = None  # the world whose initial rules model them (None: the task's default world)
    versions: dict[str, int] = field(default_factory=dict)
    _bests: dict[str, list[RuleSet]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in MODELS:
            raise ConfigError(f"unknown partner model {self.kind!r} (use {' or '.join(MODELS)})")
        if self.hall_sample < 1 or not 0.0 < self.hall_share < 1.0:
            raise ConfigError(f"a hall of fame samples at least 1 past best (got {self.hall_sample}) for a share of "
                              f"the episodes above 0 and below 1 (got {self.hall_share})")
        self.behaviour = str(self.behaviour)
        self.needed = self.task.partners_needed(self.behaviour, self.regime)
        world = self.task.world_settings() if self.world is None else self.world
        for b in self.needed:
            rng = np.random.default_rng([self.seed, self.task.behaviours.index(b), 7])
            self._bests[b] = [initial_model(self.task, b, world, self.ga, rng)]
            self.versions[b] = 0
        self._rng = np.random.default_rng([self.seed, 11])

    @property
    def generational(self) -> bool:
        """Does it model partners by each generation's best (their ``current`` key), not by their published bests?"""
        return self.kind in ("current", "hall")

    def adopt(self, behaviour: str, version: int, rules: RuleSet) -> bool:
        """Take a newer version of a partner; False if it is not newer or not needed."""
        if behaviour not in self.needed or version <= self.versions.get(behaviour, 0):
            return False
        self.versions[behaviour] = version
        kept = self._bests[behaviour] + [rules]
        self._bests[behaviour] = kept if self.kind == "hall" else kept[-self.recent :]  # a hall keeps every one
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
            pick[b] = bests[-1] if self.kind in ("best", "hall") else bests[int(self._rng.integers(len(bests)))]
        return pick

    def mixture(self, episodes: int) -> Mixture | None:
        """For ``hall``: the partner sets one generation's population plays, each with its episodes out of
        ``episodes`` (the newest bests first, then the sample of past bests); None for the other kinds, or while no
        partner has a past (the newest alone).  Draws from this worker's own RNG."""
        if self.kind != "hall" or not self.needed:
            return None
        past = {b: len(self._bests[b]) - 1 for b in self.needed}
        share = min(int(round(episodes * self.hall_share)), episodes - 1)  # the newest keeps one at least
        m = min(self.hall_sample, share, max(past.values()))
        if m == 0:
            return None
        drawn = {b: self._rng.choice(n, size=m, replace=n < m) if n else None for b, n in past.items()}
        sampled = [{b: self._bests[b][-1] if d is None else self._bests[b][int(d[j])] for b, d in drawn.items()}
                   for j in range(m)]
        split = [share // m + (1 if j < share % m else 0) for j in range(m)]
        return [(self.partners(), episodes - share), *zip(sampled, split)]
