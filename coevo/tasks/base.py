"""What a task is: the one interface the rules, GA, workers, broker and run tools are written against.

A task is a world with one or more *learning behaviours*.  For each behaviour it
declares the rule layout (sensors and actions, :class:`~coevo.policy.schema.Schema`),
its initial rules, the partners it learns against in each regime, and an
:class:`~coevo.ga.evaluator.Evaluator` (the GA's side of the contract, re-exported here) that plays a population of rule sets in its batched world and
returns a fitness, the experience the GA's Lamarckian operators read, and the
task's own measures.  The core never names a task or a behaviour: the
tracking-under-fuel task (:mod:`coevo.tasks.fuel`) is one implementation, the
corridor (:mod:`coevo.tasks.corridor`) a tiny second one that keeps the interface
honest.

``coevo show`` (generic: it names no task) finds a run's task and calls the task's show hooks
(``show_robot``, ``show_episodes``, ``show_play``, ``show_scene``, ``show_rules``, ``show_trace``);
a task draws with the task-agnostic :mod:`coevo.scene`.

Settings: a task's world settings are a frozen pydantic model (its
``world_settings``); the GA's are :class:`~coevo.config.GAConfig`, shared by all.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import BaseModel

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga.evaluator import ChildRng, Evaluation, Evaluator, Partners, Tick
from coevo.ga.symmetry import MAX_SYMMETRIC_RULES
from coevo.policy.rules import RuleSet, random_ruleset
from coevo.policy.schema import Schema, schema

if TYPE_CHECKING:
    from coevo.scene import Scene
    from coevo.tasks.showing import RuleTable, ShowPlay, ShowRobot

__all__ = ["Task", "Evaluator", "Evaluation", "Partners", "Tick", "ChildRng"]

#: What a GA setting left to the task (``None`` in :class:`GAConfig`) is when the task makes no choice of its own.
TASK_CHOICE_OFF: dict[str, object] = {"keep_evaluated": False, "best_candidates": 0, "split_rate": 0.0,
                                      "symmetric_rules": False, "max_rules": 48}


class Task(ABC):
    """A world with learning behaviours; see the module docstring."""

    name: ClassVar[str]
    behaviours: ClassVar[tuple[str, ...]]
    regimes: ClassVar[tuple[str, ...]] = ("independent",)
    world_settings: ClassVar[type[BaseModel]]
    #: Other names ``coevo show --task`` accepts for it (names of earlier versions).
    aliases: ClassVar[tuple[str, ...]] = ()
    #: Short names of its status measures for narrow displays (e.g. quality_tracking -> QT).
    measure_labels: ClassVar[dict[str, str]] = {}
    #: The world is its own mirror image, so a rule's mirror image (Sensor.mirrored, Action.mirrored) is as
    #: right on the other side as the rule on its own (GAConfig.symmetric_rules needs this).
    mirror_symmetric: ClassVar[bool] = False

    def schema(self, behaviour: str) -> Schema:
        self.check_behaviour(behaviour)
        return schema(behaviour)

    def check_behaviour(self, behaviour: str) -> str:
        if str(behaviour) not in self.behaviours:
            raise ConfigError(f"task {self.name!r} has no behaviour {str(behaviour)!r} (it has {', '.join(self.behaviours)})")
        return str(behaviour)

    def check_regime(self, regime: str) -> str:
        if regime not in self.regimes:
            raise ConfigError(f"unknown regime {regime!r} for task {self.name!r} (use {' or '.join(self.regimes)})")
        return regime

    def default_rules(self, behaviour: str) -> RuleSet | None:
        """The behaviour's shipped initial rules, or None where it starts random."""
        return None

    def initial_rules(self, behaviour: str, world: BaseModel) -> RuleSet | None:
        """The default rules a GA in ``world`` starts from (the shipped ones unless a world setting picks others)."""
        return self.default_rules(behaviour)

    def learnable_sensors(self, behaviour: str, world: BaseModel) -> np.ndarray | None:
        """(S,) bool: the sensors a GA in ``world`` may put conditions on (None: all of them)."""
        return None

    def ga_choices(self, behaviour: str) -> dict[str, object]:
        """The task's own values for the GA settings a :class:`GAConfig` leaves to it (``None``), for ``behaviour``.
        A setting the task does not choose falls back to :data:`TASK_CHOICE_OFF`."""
        return {}

    def ga_settings(self, behaviour: str, ga: GAConfig) -> GAConfig:
        """``ga`` with every setting it leaves to the task (``None``) filled in: the task's choice for
        ``behaviour`` (:meth:`ga_choices`), else off.  Settings given explicitly are kept.  A ConfigError if the
        filled-in settings cannot go together here (symmetric rules without a mirror world or room for them)."""
        behaviour = self.check_behaviour(behaviour)
        choices = {**TASK_CHOICE_OFF, **self.ga_choices(behaviour)}
        filled = ga.model_copy(update={k: v for k, v in choices.items() if getattr(ga, k) is None})
        if filled.symmetric_rules:  # each rule also stands for its mirror image (coevo.ga.symmetry)
            if not self.mirror_symmetric:
                raise ConfigError(f"symmetric_rules needs a world that is its own mirror image; task {self.name!r}'s "
                                  f"is not")
            if filled.max_rules is not None and filled.max_rules > MAX_SYMMETRIC_RULES:
                raise ConfigError(f"symmetric {behaviour} rules need max_rules <= {MAX_SYMMETRIC_RULES} (their mirror "
                                  f"images take the rest of the matcher's 64), got max_rules={filled.max_rules}; "
                                  f"symmetric_rules=false breeds up to 64")
        return filled

    def check_ga(self, ga: GAConfig) -> GAConfig:
        """``ga`` if every behaviour's filled-in settings (:meth:`ga_settings`) fit this task, else the ConfigError:
        for commands to call before they write or start anything."""
        for b in self.behaviours:
            self.ga_settings(b, ga)
        return ga

    def initial_model(self, behaviour: str, world: BaseModel, ga: GAConfig, rng: np.random.Generator) -> RuleSet:
        """How a partner that has not published yet is modelled: its initial behaviour."""
        default = self.initial_rules(behaviour, world) if ga.initial == "default" else None
        return default if default is not None else random_ruleset(behaviour, ga.initial_rules, rng)

    def partners_needed(self, behaviour: str, regime: str) -> tuple[str, ...]:
        """The behaviours whose policies ``behaviour`` learns against in ``regime``."""
        self.check_behaviour(behaviour)
        self.check_regime(regime)
        return ()

    @abstractmethod
    def evaluator(self, behaviour: str, world: BaseModel, ga: GAConfig) -> Evaluator:
        """An evaluator of ``behaviour`` in a world with these settings."""

    def status_measures(self, behaviour: str, measures: Mapping[str, float | None]) -> dict[str, float]:
        """The few measures (in %) that say how a behaviour is doing, for status displays."""
        return {}

    def final_measures(self, behaviour: str, best: RuleSet, *, world: BaseModel, partners: Partners,
                       epochs: int, seed: int) -> Mapping[str, float | int | None]:
        """The task's measures of a learned policy on fresh trials (``coevo learn``'s summary)."""
        return {}

    def picture(self, path: Path, behaviour: str, best: RuleSet, *, world: BaseModel, partners: Partners, seed: int,
                name: str) -> None:
        """Draw the learned policy at work into ``path`` (a PNG), where the task knows how; else nothing."""
        return None

    def run_measures(self, policies: Mapping[str, RuleSet], *, world: BaseModel, epochs: int,
                     seed: int) -> Mapping[str, float | int | None] | None:
        """The measures of a whole run's final policies together (``coevo run``), or None if incomplete."""
        return None

    # ------------------------------------------------------------------ coevo show
    def _cannot_show(self) -> ConfigError:
        return ConfigError(f"task {self.name!r} has no pictures: coevo show cannot draw it")

    def show_robot(self, name: str, world: BaseModel, rules: Mapping[str, RuleSet]) -> ShowRobot:
        """The robot these rule sets (behaviour -> rules) make, to play in ``world``; a ConfigError naming
        what is missing when they make none (e.g. an Executive without its partners)."""
        raise self._cannot_show()

    def show_episodes(self, robot: Any) -> int | None:
        """Episodes ``coevo show`` plays unless told (None: one epoch)."""
        return 3

    def show_play(self, robot: Any, *, seed: int, episodes: int | None) -> ShowPlay:
        """Play ``robot`` from ``seed`` with everything recorded: ``episodes`` in a row, or one epoch when None."""
        raise self._cannot_show()

    def show_scene(self, played: Any, *, title: str | None = None) -> Scene:
        """A recorded play as a :class:`~coevo.scene.Scene` (what ``coevo show`` draws and animates)."""
        raise self._cannot_show()

    def show_rules(self, played: Any) -> list[RuleTable]:
        """The robot's rule sets by strength, with how often each rule fired in ``played``."""
        raise self._cannot_show()

    def show_trace(self, played: Any) -> list[str]:
        """Per episode, one line: the rules that fired in turn and how it ended."""
        return []
