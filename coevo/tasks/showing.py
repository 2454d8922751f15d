"""What ``coevo show`` asks of a task (the hooks on :class:`~coevo.tasks.base.Task`), and the rule tables
it prints.

A task's *robot to show* is its own object (the policies it plays and the world they were learned
in), and so is a *recorded play* of it; ``coevo show`` needs only the few attributes of
:class:`ShowRobot` and :class:`ShowPlay`.  A task turns a play into a
:class:`~coevo.scene.Scene` and into :class:`RuleTable` s, rules sorted by strength with how often
each fired, numbered as in their file (1 = the first rule line), the numbers of the picture's trace.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from pydantic import BaseModel

from coevo.policy.rules import RuleSet
from coevo.policy.text import format_rule

__all__ = ["ShowRobot", "ShowPlay", "RuleRow", "RuleTable", "rule_rows", "run_lengths"]


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
