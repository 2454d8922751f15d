"""Where a combined robot loses: its learned agents swapped for hand-written ones, the record of docs/docking-learning.md.

    python benchmarks/partner_swaps.py RUN_DIR [RUN_DIR ...] [--epochs 300] [--seed 5] [--diagnostics DIR]

For each finished ``coevo compare`` run (its ``workers/*/best.rules``) it measures the robot on ``--epochs`` fresh
epochs under six line-ups: the hand-written "dock below 40 % fuel" Executive of ``--diagnostics`` with every mix of
hand-written (h) and learned (l) Tracking and Docking, and the run's own Executive with learned Tracking and learned
or hand-written Docking.  It prints the medians over the runs of the Executive's payoff, the epochs' length, the
share of picked dockings that dock, how often Docking is picked, how the picked dockings fail (a collision, which
ends the epoch, or the time running out), the episodes that end in a collision while tracking, running dry, and
Quality Tracking.  The hand-written rule sets are a yardstick (diagnostics/README.md), never a start.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np

from coevo.errors import CoevoError
from coevo.policy.rules import RuleSet
from coevo.policy.text import parse_ruleset
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK
from coevo.tasks.fuel.measures import measure
from coevo.tasks.fuel.robot import controllers
from coevo.tasks.fuel.runner import run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld

COLUMNS = ("payoff", "AEL", "picked dockings docked %", "picks Docking %", "picked dockings collide %",
           "picked dockings time out %", "tracking collisions % of episodes", "dry %", "QT %")
LINEUPS = ("hand hand hand", "hand learned hand", "hand hand learned", "hand learned learned",
           "own learned learned", "own learned hand")  # Executive, Tracking, Docking


def robot(executive: RuleSet, tracking: RuleSet, docking: RuleSet, *, epochs: int, seed: int) -> tuple[float, ...]:
    """The :data:`COLUMNS` of one line-up over ``epochs`` fresh epochs."""
    cfg = WorldConfig()
    ex, tr, dk = controllers(executive, tracking, docking, epochs)
    out = run_lanes(BatchWorld(cfg, epochs), lane_episodes=cfg.epoch_episodes, executive=ex, tracking=tr, docking=dk,
                    restart_epochs=False, rng=np.random.default_rng(seed))
    m = measure(out, cfg.episode_steps)
    picked = out.played & (out.task == TASK_DOCK)
    n = max(1, int(picked.sum()))
    collide = 100 * (picked & out.collided).sum() / n
    time_out = 100 * (picked & ~out.collided & ~out.docked & ~out.dry).sum() / n
    tracking_hits = 100 * (out.played & (out.task == TASK_TRACK) & out.collided).sum() / max(1, int(out.played.sum()))
    return (m.executive_payoff, m.average_epoch_length, m.docking_success_rate, m.dock_choice, collide, time_out,
            tracking_hits, m.dry_rate, m.quality_tracking)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--epochs", type=int, default=300)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--diagnostics", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "diagnostics",
                    help="the folder of the hand-written rule sets (default ../shared/diagnostics)")
    a = ap.parse_args()
    if a.epochs < 1:
        ap.error(f"--epochs must be at least 1, got {a.epochs}")
    names = {"executive": "executive-dock-below-40.rules", "tracking": "tracking-handwritten.rules",
             "docking": "docking-handwritten.rules"}
    try:
        hand = {b: parse_ruleset((a.diagnostics / f).read_text(), b) for b, f in names.items()}
    except (OSError, CoevoError) as exc:
        ap.error(f"--diagnostics {a.diagnostics}: {exc}")
    rows: dict[str, list[tuple[float, ...]]] = {k: [] for k in LINEUPS}
    for run in a.runs:
        try:
            own = {b: parse_ruleset((run / "workers" / b / "best.rules").read_text(), b) for b in names}
        except (OSError, CoevoError) as exc:
            ap.error(f"{run} is not a finished coevo compare run with workers/*/best.rules ({exc})")
        for lineup in LINEUPS:
            e, t, d = lineup.split()
            pick = {"hand": hand, "learned": own, "own": own}
            rows[lineup].append(robot(pick[e]["executive"], pick[t]["tracking"], pick[d]["docking"],
                                      epochs=a.epochs, seed=a.seed))
    print("| Executive, Tracking, Docking | " + " | ".join(COLUMNS) + " |")
    print("|---|" + "---|" * len(COLUMNS))
    for lineup, vals in rows.items():
        med = [statistics.median(v[j] for v in vals) for j in range(len(COLUMNS))]
        print(f"| {lineup.replace(' ', ', ')} | " + " | ".join(f"{x:.2f}" for x in med) + " |")


if __name__ == "__main__":
    main()
