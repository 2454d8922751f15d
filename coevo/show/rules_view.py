"""Readable rule sets: sorted by strength, with how often each rule fired in the shown episodes.

Rules are numbered as in their file (1 = the first rule line), the numbers the
picture's trace panel and the animation's captions use.  On a terminal the tables
are rich tables; otherwise plain text, one rule a line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from coevo.policy.rules import RuleSet
from coevo.policy.text import format_rule
from coevo.show.play import Played
from coevo.show.tracking_fuel import CATEGORIES, episode_endings
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK, Behaviour

__all__ = ["RuleRow", "fire_counts", "rule_rows", "print_rules", "trace_lines"]

_TASK_OF = {Behaviour.TRACKING: TASK_TRACK, Behaviour.DOCKING: TASK_DOCK}


@dataclass(frozen=True)
class RuleRow:
    number: int  # 1-based, file order
    strength: float
    fired: int
    text: str  # the rule without its strength


def fire_counts(played: Played, behaviour: Behaviour, rules: int) -> np.ndarray:
    """How many times each rule of ``behaviour`` fired (steps for Tracking/Docking, episodes for the Executive)."""
    rec = played.record
    if behaviour == Behaviour.EXECUTIVE:
        fired = rec.executive_rule[:, 0]
    else:
        mine = rec.task[:, 0] == _TASK_OF[behaviour]
        fired = rec.rule[mine, :, 0].ravel()
    fired = fired[fired >= 0].astype(np.int64)
    return np.bincount(fired, minlength=rules)[:rules]


def rule_rows(rs: RuleSet, counts: np.ndarray) -> list[RuleRow]:
    """The rules sorted by strength (strongest first; ties in file order)."""
    order = sorted(range(len(rs)), key=lambda i: (-float(rs.strength[i]), i))
    rows = []
    for i in order:
        text = format_rule(rs, i)
        text = text[: text.rfind(" (strength")]
        rows.append(RuleRow(i + 1, float(rs.strength[i]), int(counts[i]), text))
    return rows


def _unit(b: Behaviour) -> str:
    return "episodes" if b == Behaviour.EXECUTIVE else "steps"


def print_rules(played: Played, *, console: Any | None = None, plain: bool | None = None) -> None:
    """Print each of the robot's rule sets, sorted by strength, with fire counts."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    plain = (not console.is_terminal) if plain is None else plain
    for b, rs in played.robot.rulesets().items():
        rows = rule_rows(rs, fire_counts(played, b, len(rs)))
        letter = b.value[0].upper()
        title = (f"{b.value}: {len(rs)} rules by strength; fired = {_unit(b)} it decided "
                 f"in {played.episodes} episodes")
        if plain:
            console.print(title, markup=False, highlight=False, soft_wrap=True)
            for r in rows:
                console.print(f"  {letter}{r.number:<3} {r.strength:6.3f} {r.fired:5d}  {r.text}",
                              markup=False, highlight=False, soft_wrap=True)
            continue
        t = Table(title=title, title_justify="left")
        t.add_column("#", justify="right")
        t.add_column("strength", justify="right")
        t.add_column("fired", justify="right")
        t.add_column("rule")
        for r in rows:
            t.add_row(f"{letter}{r.number}", f"{r.strength:.3f}", str(r.fired), r.text, style=None if r.fired else "dim")
        console.print(t)


def _runs(seq: np.ndarray, letter: str) -> str:
    """Run-length form of a rule sequence: 'T2x14 T4x3'."""
    out = []
    i = 0
    while i < len(seq):
        j = i
        while j < len(seq) and seq[j] == seq[i]:
            j += 1
        out.append(f"{letter}{int(seq[i]) + 1}x{j - i}")
        i = j
    return " ".join(out)


def trace_lines(played: Played) -> list[str]:
    """Per episode, the rules that fired step by step (run-length), and how it ended."""
    rec, out = played.record, played.outcome
    endings = episode_endings(played)
    lines = []
    for k in range(played.episodes):
        task = int(rec.task[k, 0])
        steps = int(out.steps[0, k])
        ex = int(rec.executive_rule[k, 0])
        who = CATEGORIES[task] + (f", picked by E{ex + 1}" if ex >= 0 else "")
        lines.append(f"episode {k + 1} ({who}): {_runs(rec.rule[k, :steps, 0], 'TD'[task])} -> {endings[k]}")
    return lines
