"""The fuel robot's rule sets as tables (sorted by strength, with how often each rule fired in the
shown episodes) and, per episode, the rules that fired step by step; ``coevo show --rules`` prints them.

Rules are numbered as in their file (1 = the first rule line), the numbers the
picture's trace panel and the animation's captions use.
"""

from __future__ import annotations

import numpy as np

from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK, Behaviour
from coevo.tasks.fuel.pictures.play import Played
from coevo.tasks.fuel.pictures.scene import CATEGORIES, episode_endings
from coevo.tasks.showing import RuleRow, RuleTable, rule_rows, run_lengths

__all__ = ["RuleRow", "fire_counts", "rule_rows", "rule_tables", "trace_lines"]

_TASK_OF = {Behaviour.TRACKING: TASK_TRACK, Behaviour.DOCKING: TASK_DOCK}


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


def _unit(b: Behaviour) -> str:
    return "episodes" if b == Behaviour.EXECUTIVE else "steps"


def rule_tables(played: Played) -> list[RuleTable]:
    """Each of the robot's rule sets, sorted by strength, with fire counts."""
    tables = []
    for b, rs in played.robot.rulesets().items():
        rows = rule_rows(rs, fire_counts(played, b, len(rs)))
        title = (f"{b.value}: {len(rs)} rules by strength; fired = {_unit(b)} it decided "
                 f"in {played.episodes} episodes")
        tables.append(RuleTable(title, b.value[0].upper(), tuple(rows)))
    return tables


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
        lines.append(f"episode {k + 1} ({who}): {run_lengths(rec.rule[k, :steps, 0], 'TD'[task])} -> {endings[k]}")
    return lines
