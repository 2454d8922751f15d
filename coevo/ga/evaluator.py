"""What the GA loop runs over: an evaluator of populations (the problem that makes one: :mod:`coevo.ga.problem`).

The GA (:mod:`coevo.ga.engine`) names no task.  A task (:class:`coevo.tasks.base.Task`) is a
:class:`~coevo.ga.problem.Problem`: it gives a behaviour's initial rules and makes an
:class:`Evaluator` that plays a population of rule sets in its world and returns an
:class:`Evaluation`: a fitness per individual and the experience the Lamarckian operators
read.  Partners and ticks are plain arguments, so an asynchronous worker can swap partner
policies and hang a heartbeat on every evaluation without the GA knowing.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coevo.ga.operators import Experience
from coevo.policy.rules import RuleSet

__all__ = ["Evaluator", "Evaluation", "Partners", "Tick", "ChildRng", "Mixture", "pooled"]

#: The learner's models of the other behaviours it needs, by name; a behaviour that is
#: absent is played by the task's trivial stand-in (e.g. an Executive that always picks the learner).
Partners = Mapping[str, RuleSet]
#: Several partner sets for one evaluation, each with the episodes played against it (a hall of fame's sample
#: beside the newest partners: :mod:`coevo.agents.models`).
Mixture = Sequence[tuple[Partners, int]]
#: Called between episode rounds of a long evaluation (a worker's heartbeat).
Tick = Callable[[], None]
#: Draws a fresh generator from the GA's own stream, only when a measure needs one.
ChildRng = Callable[[], np.random.Generator]


@dataclass
class Evaluation:
    """Fitness of each individual, with what each did (for the Lamarckian operators)."""

    fitness: np.ndarray
    episodes: np.ndarray  # episodes each individual controlled (0: starved of experience)
    experience: list[Experience]
    details: Any = field(default=None, repr=False)  # the task's own record (its measures read it)


class Evaluator(ABC):
    """Plays populations of one behaviour in a task's batched world."""

    behaviour: str

    @abstractmethod
    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        """Fitness of every policy against ``partners`` (``episodes``: by default the GA's setting)."""

    @abstractmethod
    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        """The task's measures of a generation's best, from its re-evaluation ``check``; the same
        keys every generation (they are the learning curve's columns)."""


def pooled(parts: Sequence[Evaluation]) -> Evaluation:
    """One evaluation of the same policies from evaluations against several partner sets: each policy's episodes
    counted together, its fitness the mean of the parts' fitness weighted by the episodes it played in each (the mean
    payoff over all its episodes where a fitness is a mean payoff), its experience the parts' one after another.  The
    parts' own records (``details``) are kept as a list."""
    counts = np.stack([p.episodes for p in parts]).astype(np.float64)  # (parts, policies)
    fits = np.stack([p.fitness for p in parts])
    total = counts.sum(axis=0)
    weighted = (fits * counts).sum(axis=0)
    fitness = np.divide(weighted, total, out=np.zeros_like(weighted), where=total > 0)
    return Evaluation(fitness, np.stack([p.episodes for p in parts]).sum(axis=0),
                      [_joined([p.experience[i] for p in parts]) for i in range(len(parts[0].experience))],
                      [p.details for p in parts])


def _joined(exps: Sequence[Experience]) -> Experience:
    """One policy's experiences, one after another (the decision log's episode numbers shifted to match)."""
    offsets = np.cumsum([0] + [e.payoff.size for e in exps[:-1]])
    return Experience(np.concatenate([e.fired for e in exps]), np.concatenate([e.payoff for e in exps]),
                      np.concatenate([e.bins for e in exps]), np.concatenate([e.rule for e in exps]),
                      np.concatenate([e.full for e in exps]),
                      np.concatenate([e.episode + o for e, o in zip(exps, offsets)]), exps[0].high_quantile)
