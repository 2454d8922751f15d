"""What a task is: the one interface the rules, GA, workers, broker and run tools are written against.

A task is a world with one or more *learning behaviours*.  For each behaviour it
declares the rule layout (sensors and actions, :class:`~coevo.policy.schema.Schema`,
registered under the behaviour's name when the task is imported), its initial rules,
the partners it learns against in each regime, and an
:class:`~coevo.ga.evaluator.Evaluator` (the GA's side of the contract, re-exported here) that plays a
population of rule sets in its batched world and returns a fitness, the experience the GA's
Lamarckian operators read, and the task's own measures.  The core never names a task or a
behaviour: the tracking-under-fuel task (:mod:`coevo.tasks.fuel`) is one implementation, the
corridor (:mod:`coevo.tasks.corridor`) a tiny second one that keeps the interface honest.

The shape, after Gymnasium's ``Env``: a small class of what a task must say, generic over its
world's settings, and functions for what follows from that.

* :class:`Task` ``[W]``: class attributes ``name``, ``behaviours``, ``regimes``, ``world_settings``
  (the model ``W``, a frozen pydantic model), ``aliases``, ``measure_labels``, ``measure_terms``,
  ``mirror_symmetric``; methods ``initial_rules``, ``learnable_sensors``, ``ga_choices``, ``partners_needed``,
  ``evaluator`` (the only abstract one), ``status_measures``, ``final_measures``, ``run_measures``,
  ``run_verdict`` and ``display``.  A measure is named to a reader by its :class:`Term` (readable name, unit,
  definition); :func:`measures_text` writes a run's measures with them.  Every method that takes a world takes
  a ``W``, so a task reads its own settings' fields and names no other model.
* Functions every task shares and none overrides: :func:`check_behaviour`, :func:`ga_settings`
  (the GA settings left to the task, filled in), :func:`check_ga` and :func:`initial_model` live
  with the GA (:mod:`coevo.ga.problem`, which needs them too) and are re-exported here;
  :func:`check_regime` is here.  The GA (:mod:`coevo.ga.problem`'s ``Problem``) needs only part
  of :class:`Task`.
* Its pictures are behind their own interface: ``display()`` gives a
  :class:`~coevo.tasks.showing.TaskDisplay` (``picture`` and the ``show_*`` hooks that ``coevo show``,
  ``coevo learn``'s best.png and the dashboard call; names no task), or None for a task without
  pictures.  A display draws with the task-agnostic :mod:`coevo.scene`.

Settings: a task's world settings are a frozen pydantic model (its ``world_settings``: the
physics and the task's own learning conditions, e.g. the fuel task's Docking sensors); the GA's
are :class:`~coevo.config.GAConfig`, shared by all.  :func:`coevo.tasks.checker.check_task` checks
a task against this interface.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Generic, TypeVar

import numpy as np
from pydantic import BaseModel

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga.evaluator import ChildRng, Evaluation, Evaluator, Partners, Tick
from coevo.ga.problem import TASK_CHOICE_OFF, check_behaviour, check_ga, ga_settings, initial_model
from coevo.policy.rules import RuleSet

if TYPE_CHECKING:
    from coevo.tasks.showing import TaskDisplay

__all__ = ["Task", "W", "Term", "measures_text", "Evaluator", "Evaluation", "Partners", "Tick", "ChildRng", "TASK_CHOICE_OFF",
           "check_behaviour", "check_regime", "ga_settings", "check_ga", "initial_model"]

#: The model of a task's world settings.
W = TypeVar("W", bound=BaseModel)


@dataclass(frozen=True)
class Term:
    """A measure's readable name, its unit (printed after a value: ' %', ' episodes'; '' for none) and what it is."""

    name: str
    unit: str
    definition: str
    #: Its possible range, (lowest, highest), or None when it has none to speak of: what a 95 % interval of its mean
    #: is cut at (a rate of episodes 0 to 100 %, a payoff 0 to 1).
    bounds: tuple[float, float] | None = None

    def text(self, value: float, digits: int = 1) -> str:
        """'Quality Tracking 72.2 %'; a value without a unit (a payoff, a fitness) to 3 places: 'Executive payoff
        0.660'."""
        places = 3 if self.unit == "" else digits
        return f"{self.name} {value:.{places}f}{self.unit}"


class Task(ABC, Generic[W]):
    """A world with learning behaviours, its settings a ``W``; see the module docstring."""

    name: ClassVar[str]
    behaviours: ClassVar[tuple[str, ...]]
    regimes: ClassVar[tuple[str, ...]] = ("independent",)
    #: The model of its world's settings, set on the class (not a ClassVar only because a ClassVar cannot hold W).
    world_settings: type[W]
    #: Other names ``coevo show --task`` accepts for it (names of earlier versions).
    aliases: ClassVar[tuple[str, ...]] = ()
    #: Short names of its status measures for narrow displays (e.g. quality_tracking -> QT).
    measure_labels: ClassVar[dict[str, str]] = {}
    #: Each measure's readable name, unit and definition, by field name: how a reader sees the fields of
    #: ``run_measures`` and ``final_measures`` (``coevo run``'s last lines); a field without one shows its own name.
    measure_terms: ClassVar[Mapping[str, Term]] = {}
    #: Command-line flags of its own, each a world setting by another name (the door task's ``--fail front`` is
    #: ``--world failed=front``), taken by ``coevo learn``, ``show``, ``run`` and ``worker`` once the task is known;
    #: every behaviour of a task is a flag too there, giving a partner's rule file (``--tracking FILE``).
    flags: ClassVar[dict[str, str]] = {}
    #: The world is its own mirror image, so a rule's mirror image (Sensor.mirrored, Action.mirrored) is as
    #: right on the other side as the rule on its own (GAConfig.symmetric_rules needs this).
    mirror_symmetric: ClassVar[bool] = False
    #: The behaviour that can learn offline on the partner histories an Independent run recorded (``coevo learn
    #: --history``; a comparison's pseudo-regime ``independent-offline``), or None.
    offline_learner: ClassVar[str | None] = None
    #: How a comparison of it is read (``coevo compare``): "module:NAME" of a
    #: :class:`~coevo.experiments.compare.reading.Reading`, imported when a comparison is read; None: the generic
    #: reading (every measure of its ``run_measures`` and each behaviour's curve, compared between the regimes).
    comparison: ClassVar[str | None] = None

    def initial_rules(self, behaviour: str, world: W) -> RuleSet | None:
        """The rules a GA of ``behaviour`` in ``world`` starts from (its shipped default rules, which a world
        setting may choose among), or None where it starts random."""
        return None

    def learnable_sensors(self, behaviour: str, world: W) -> np.ndarray | None:
        """(S,) bool: the sensors a GA in ``world`` may put conditions on (None: all of them)."""
        return None

    def ga_choices(self, behaviour: str) -> dict[str, object]:
        """The task's own values for the GA settings a :class:`GAConfig` leaves to it (``None``), for ``behaviour``.
        A setting the task does not choose falls back to :data:`TASK_CHOICE_OFF` (:func:`ga_settings`)."""
        return {}

    def partners_needed(self, behaviour: str, regime: str) -> tuple[str, ...]:
        """The behaviours whose policies ``behaviour`` learns against in ``regime``."""
        check_behaviour(self, behaviour)
        check_regime(self, regime)
        return ()

    @abstractmethod
    def evaluator(self, behaviour: str, world: W, ga: GAConfig) -> Evaluator:
        """An evaluator of ``behaviour`` in a world with these settings."""

    def status_measures(self, behaviour: str, measures: Mapping[str, float | None]) -> dict[str, float]:
        """The few measures (in %) that say how a behaviour is doing, for status displays."""
        return {}

    def final_measures(self, behaviour: str, best: RuleSet, *, world: W, partners: Partners,
                       epochs: int, seed: int) -> Mapping[str, float | int | None]:
        """The task's measures of a learned policy on fresh trials (``coevo learn``'s summary)."""
        return {}

    def run_measures(self, policies: Mapping[str, RuleSet], *, world: W, epochs: int,
                     seed: int) -> Mapping[str, float | int | None] | None:
        """The measures of a whole run's final policies together (``coevo run``), or None if incomplete."""
        return None

    def run_verdict(self, measures: Mapping[str, float | int | None]) -> str | None:
        """What a run's final measures (``run_measures``'s) say, in words, for ``coevo run``'s last lines (the fuel
        task: the run's class in the report's Table 1, and why), or None: nothing beyond the numbers."""
        return None

    def display(self) -> TaskDisplay[W] | None:
        """Its pictures (:class:`~coevo.tasks.showing.TaskDisplay`: ``coevo show``, ``coevo learn``'s best.png, the
        dashboard's robot), or None: it has none."""
        return None


def measures_text(task: Task[Any], measures: Mapping[str, float | int | None]) -> list[str]:
    """A run's measures as a reader reads them, each by its task's :class:`Term`: ['Quality Tracking 72.2 %', ...,
    'Executive payoff 0.660'], in the order of the task's terms; a field the task names no term for by its own name,
    to 3 significant digits, after them.  Counts (ints) and missing values are left out."""
    terms = task.measure_terms
    fields = [k for k in terms if k in measures] + [k for k in measures if k not in terms]
    return [terms[k].text(v) if k in terms else f"{k} {v:.3g}" for k in fields if isinstance(v := measures[k], float)]


def check_regime(task: Task[Any], regime: str) -> str:
    """``regime`` if ``task`` learns in it, else a ConfigError naming the ones it has."""
    if regime not in task.regimes:
        raise ConfigError(f"unknown regime {regime!r} for task {task.name!r} (use {' or '.join(task.regimes)})")
    return regime
