"""What the GA needs of a task (a :class:`Problem`), and the helpers every problem shares.

A problem says little: its name, its behaviours, whether its world is its own mirror image,
its own values for the GA settings a :class:`~coevo.config.GAConfig` leaves to it
(:meth:`Problem.ga_choices`), the rules a behaviour starts from and the sensors it may learn
over in a given world, and an :class:`~coevo.ga.evaluator.Evaluator` of a behaviour in that world.
:class:`coevo.tasks.base.Task` is one; the CEL learning module's door task over its changing
model is another.

What follows from that and is the same for every problem is here, as functions rather than
methods no task overrides: :func:`check_behaviour`, :func:`ga_settings` (the settings left to
the task, filled in), :func:`check_ga` (all of a problem's behaviours at once, for commands to call
before they write anything) and :func:`initial_model` (a partner that has published nothing yet).
The GA (:mod:`coevo.ga.engine`) calls them; :mod:`coevo.tasks.base` re-exports them for everyone else.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol, TypeVar

import numpy as np
from pydantic import BaseModel

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga.evaluator import Evaluator
from coevo.ga.symmetry import MAX_SYMMETRIC_RULES
from coevo.policy.rules import RuleSet, random_ruleset

__all__ = ["Problem", "TASK_CHOICE_OFF", "check_behaviour", "ga_settings", "check_ga", "initial_model"]

W_contra = TypeVar("W_contra", bound=BaseModel, contravariant=True)

#: What a GA setting left to the task (``None`` in :class:`GAConfig`) is when the task makes no choice of its own.
TASK_CHOICE_OFF: dict[str, object] = {"keep_evaluated": False, "best_candidates": 0, "split_rate": 0.0,
                                      "symmetric_rules": False, "max_rules": 48}


class Problem(Protocol[W_contra]):
    """What the GA needs of a task (:class:`coevo.tasks.base.Task` is one), whose world settings are ``W_contra``."""

    @property
    def name(self) -> str:
        """The task's name (in messages)."""

    @property
    def behaviours(self) -> tuple[str, ...]:
        """The behaviours it learns."""

    @property
    def mirror_symmetric(self) -> bool:
        """Its world is its own mirror image (GAConfig.symmetric_rules needs it)."""

    def ga_choices(self, behaviour: str) -> Mapping[str, object]:
        """Its own values, for ``behaviour``, of the GA settings a GAConfig leaves to the task (None)."""

    def initial_rules(self, behaviour: str, world: W_contra) -> RuleSet | None:
        """The rules a GA in ``world`` starts from (its task's shipped default rules), or None where it starts random."""

    def learnable_sensors(self, behaviour: str, world: W_contra) -> np.ndarray | None:
        """(S,) bool: the sensors the GA may put conditions on in ``world`` (None: all)."""

    def evaluator(self, behaviour: str, world: W_contra, ga: GAConfig) -> Evaluator:
        """An evaluator of ``behaviour`` in a world with these settings."""


def check_behaviour(problem: Problem[W_contra], behaviour: str) -> str:
    """``behaviour`` if the problem has it, else a ConfigError naming it and the ones it has."""
    if str(behaviour) not in problem.behaviours:
        raise ConfigError(f"task {problem.name!r} has no behaviour {str(behaviour)!r} "
                          f"(it has {', '.join(problem.behaviours)})")
    return str(behaviour)


def ga_settings(problem: Problem[W_contra], behaviour: str, ga: GAConfig) -> GAConfig:
    """``ga`` with every setting it leaves to the task (``None``) filled in: the task's choice for ``behaviour``
    (:meth:`Problem.ga_choices`), else off (:data:`TASK_CHOICE_OFF`).  Settings given explicitly are kept.  A
    ConfigError if the filled-in settings cannot go together here (symmetric rules without a mirror world or room
    for them)."""
    behaviour = check_behaviour(problem, behaviour)
    choices = {**TASK_CHOICE_OFF, **problem.ga_choices(behaviour)}
    filled = ga.model_copy(update={k: v for k, v in choices.items() if getattr(ga, k) is None})
    if filled.symmetric_rules:  # each rule also stands for its mirror image (coevo.ga.symmetry)
        if not problem.mirror_symmetric:
            raise ConfigError(f"symmetric_rules needs a world that is its own mirror image; task {problem.name!r}'s "
                              f"is not")
        if filled.max_rules is not None and filled.max_rules > MAX_SYMMETRIC_RULES:
            raise ConfigError(f"symmetric {behaviour} rules need max_rules <= {MAX_SYMMETRIC_RULES} (their mirror "
                              f"images take the rest of the matcher's 64), got max_rules={filled.max_rules}; "
                              f"symmetric_rules=false breeds up to 64")
    return filled


def check_ga(problem: Problem[W_contra], ga: GAConfig) -> GAConfig:
    """``ga`` if every behaviour's filled-in settings (:func:`ga_settings`) fit the problem, else the ConfigError:
    for commands to call before they write or start anything."""
    for b in problem.behaviours:
        ga_settings(problem, b, ga)
    return ga


def initial_model(problem: Problem[W_contra], behaviour: str, world: W_contra, ga: GAConfig,
                  rng: np.random.Generator) -> RuleSet:
    """How a partner that has not published yet is modelled: its initial behaviour (its initial rules in
    ``world`` with ``GAConfig.initial = "default"`` where it has some, else a random rule set drawn from ``rng``)."""
    default = problem.initial_rules(behaviour, world) if ga.initial == "default" else None
    return default if default is not None else random_ruleset(behaviour, ga.initial_rules, rng)
