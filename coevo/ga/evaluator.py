"""What the GA loop runs over: an evaluator of populations, and the problem that makes one.

The GA (:mod:`coevo.ga.engine`) names no task.  A task (:class:`coevo.tasks.base.Task`) is a
:class:`Problem`: it checks a behaviour's name, gives its initial rules and makes an
:class:`Evaluator` that plays a population of rule sets in its world and returns an
:class:`Evaluation`: a fitness per individual and the experience the Lamarckian operators
read.  Partners and ticks are plain arguments, so an asynchronous worker can swap partner
policies and hang a heartbeat on every evaluation without the GA knowing.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from pydantic import BaseModel

from coevo.config import GAConfig
from coevo.ga.operators import Experience
from coevo.policy.rules import RuleSet

__all__ = ["Problem", "Evaluator", "Evaluation", "Partners", "Tick", "ChildRng"]

#: The learner's models of the other behaviours it needs, by name; a behaviour that is
#: absent is played by the task's trivial stand-in (e.g. an Executive that always picks the learner).
Partners = Mapping[str, RuleSet]
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


class Problem(Protocol):
    """What the GA needs of a task (:class:`coevo.tasks.base.Task` is one)."""

    @property
    def mirror_symmetric(self) -> bool:
        """Its world is its own mirror image (GAConfig.symmetric_rules needs it)."""

    def ga_settings(self, behaviour: str, ga: GAConfig) -> GAConfig:
        """``ga`` with the settings it leaves to the task (None) filled in for ``behaviour``; a ConfigError if they
        cannot go together in this task."""

    def initial_rules(self, behaviour: str, world: BaseModel) -> RuleSet | None:
        """The rules a GA in ``world`` starts from, or None where it starts random."""

    def learnable_sensors(self, behaviour: str, world: BaseModel) -> np.ndarray | None:
        """(S,) bool: the sensors the GA may put conditions on in ``world`` (None: all)."""

    def check_behaviour(self, behaviour: str) -> str:
        """``behaviour`` if the task has it, else a ConfigError naming it."""

    def default_rules(self, behaviour: str) -> RuleSet | None:
        """The behaviour's initial rules, or None where it starts random."""

    def evaluator(self, behaviour: str, world: BaseModel, ga: GAConfig) -> Evaluator:
        """An evaluator of ``behaviour`` in a world with these settings."""
