"""A task's pictures, behind their own interface: :class:`TaskDisplay`, and the rule tables ``coevo show`` prints.

The learning contract (:class:`~coevo.tasks.base.Task`) holds one accessor for them,
``Task.display()``: a :class:`TaskDisplay` over the task's world settings, or None for a task
without pictures (:func:`display_of` turns None into the one-line error every caller gives).
``coevo show`` and the dashboard's robot panel play and draw through it, ``coevo learn`` draws its
best.png with :meth:`TaskDisplay.picture`, and the task checker plays it once.  The fuel task's
display is :class:`coevo.tasks.fuel.pictures.FuelDisplay`, the door task's
:class:`coevo.tasks.door.pictures.DoorDisplay`, the corridor's (the smallest)
:class:`coevo.tasks.corridor.CorridorDisplay`.

A task's *robot to show* is its own object (the policies it plays and the world they were learned
in), and so is a *recorded play* of it; ``coevo show`` needs only the few attributes of
:class:`ShowRobot` and :class:`ShowPlay`.  A display turns a play into a
:class:`~coevo.scene.Scene` and into :class:`RuleTable` s, rules sorted by strength with how often
each fired, numbered as in their file (1 = the first rule line), the numbers of the picture's trace.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

import numpy as np
from pydantic import BaseModel

from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_rule

if TYPE_CHECKING:
    from coevo.ga.evaluator import Partners
    from coevo.scene import Scene
    from coevo.tasks.base import Task

__all__ = ["TaskDisplay", "display_of", "ShowRobot", "ShowPlay", "RuleRow", "RuleTable", "rule_rows", "run_lengths"]

#: The model of the task's world settings.
W = TypeVar("W", bound=BaseModel)


class ShowRobot(Protocol):
    """A robot to show: a name (for file names and titles) and its world's settings."""

    @property
    def name(self) -> str: ...

    @property
    def world(self) -> BaseModel: ...


class ShowPlay(Protocol):
    """A recorded play of a robot: how many episodes (or trials) it holds."""

    @property
    def episodes(self) -> int: ...


class TaskDisplay(ABC, Generic[W]):
    """A task's pictures: a learned policy's best.png, and the robot ``coevo show`` plays, draws and lists.

    A robot and a play are the display's own objects (:class:`ShowRobot`, :class:`ShowPlay` say what
    ``coevo show`` reads of them); the hooks take back what they gave.
    """

    def picture(self, path: Path, behaviour: str, best: RuleSet, *, world: W, partners: Partners, seed: int,
                name: str) -> None:
        """Draw the learned policy ``best`` at work into ``path`` (a PNG: ``coevo learn``'s best.png), with the
        partners it learned against; by default nothing."""
        return None

    @abstractmethod
    def show_robot(self, name: str, world: W, rules: Mapping[str, RuleSet]) -> ShowRobot:
        """The robot these rule sets (behaviour -> rules) make, to play in ``world``; a ConfigError naming
        what is missing when they make none (e.g. an Executive without its partners)."""

    def show_episodes(self, robot: Any) -> int | None:
        """Episodes ``coevo show`` plays unless told (None: one epoch)."""
        return 3

    @abstractmethod
    def show_play(self, robot: Any, *, seed: int, episodes: int | None) -> ShowPlay:
        """Play ``robot`` from ``seed`` with everything recorded: ``episodes`` in a row, or one epoch when None."""

    @abstractmethod
    def show_scene(self, played: Any, *, title: str | None = None) -> Scene:
        """A recorded play as a :class:`~coevo.scene.Scene` (what ``coevo show`` draws and animates)."""

    @abstractmethod
    def show_rules(self, played: Any) -> list[RuleTable]:
        """The robot's rule sets by strength, with how often each rule fired in ``played``."""

    def show_trace(self, played: Any) -> list[str]:
        """Per episode, one line: the rules that fired in turn and how it ended."""
        return []

    def show_score(self, played: Any) -> tuple[str, float] | None:
        """What a play of one epoch scored, and the score's name (the fuel task: ``("Executive payoff", 0.65)``), by
        which ``coevo show`` picks a typical epoch to draw when no ``--seed`` is given; None (the default): no score,
        and it draws seed 0."""
        return None


def display_of(task: Task[Any]) -> TaskDisplay[Any]:
    """``task``'s pictures, or a ConfigError saying it has none (what ``coevo show`` and the dashboard say)."""
    display = task.display()
    if display is None:
        raise ConfigError(f"task {task.name!r} has no pictures: coevo show cannot draw it")
    return display


@dataclass(frozen=True)
class RuleRow:
    number: int  # 1-based, file order
    strength: float
    fired: int
    text: str  # the rule without its strength


@dataclass(frozen=True)
class RuleTable:
    """One rule set to print: its title, the letter before rule numbers, its rows by strength."""

    title: str
    letter: str
    rows: tuple[RuleRow, ...]


def rule_rows(rs: RuleSet, counts: np.ndarray) -> list[RuleRow]:
    """The rules sorted by strength (strongest first; ties in file order)."""
    order = sorted(range(len(rs)), key=lambda i: (-float(rs.strength[i]), i))
    rows = []
    for i in order:
        text = format_rule(rs, i)
        text = text[: text.rfind(" (strength")]
        rows.append(RuleRow(i + 1, float(rs.strength[i]), int(counts[i]), text))
    return rows


def run_lengths(seq: Sequence[int] | np.ndarray, letter: str) -> str:
    """Run-length form of a 0-based rule sequence: 'T2x14 T4x3'."""
    out = []
    i = 0
    while i < len(seq):
        j = i
        while j < len(seq) and seq[j] == seq[i]:
            j += 1
        out.append(f"{letter}{int(seq[i]) + 1}x{j - i}")
        i = j
    return " ".join(out)
