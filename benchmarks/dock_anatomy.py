"""How learned Docking policies fail from random starts, and how they learned: the record of docs/docking-learning.md.

    python benchmarks/dock_anatomy.py RUN_DIR [RUN_DIR ...] [--starts 1000] [--seed 7]

For each ``coevo learn --behaviour docking`` run directory (its ``best.rules``) it plays
``--starts`` fresh single episodes from random starts (as ``docking_from_random_starts``
does) and prints how they ended: docked; collided, split by what was hit (the dock's
front too fast, the dock's front at more than the accepted angle, the dock's side or
corner, a wall, the Target); ran dry; timed out.  For the collisions at the dock it gives
where they happened in the dock's frame (median distance along the axis and |lateral
offset| one step before, median |angle off head-on|).  Then the run's learning curve:
docking from random starts of each generation's best at generations 10, 20, 30, 40, 50
(``curve.csv``).  The last line sums every run given.
"""

from __future__ import annotations

import argparse
import csv
from collections import Counter
from pathlib import Path

import numpy as np

from coevo.policy.matcher import CompiledPolicies
from coevo.policy.text import parse_ruleset
from coevo.tasks.fuel.behaviours import SPEED, TURN, Behaviour
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import DOCK_HEADING, BatchWorld, signed_deg

KINDS = ("docked", "dock-fast", "dock-angle", "dock-side", "wall", "target", "dry", "time-up")


def play(rules_path: Path, world_cfg: WorldConfig, starts: int, seed: int) -> tuple[Counter[str], np.ndarray]:
    """End kinds of ``starts`` fresh episodes, and (axis, |offset|, |angle|) rows one step before each dock collision."""
    rs = parse_ruleset(rules_path.read_text(), Behaviour.DOCKING)
    comp = CompiledPolicies([rs])
    sch = comp.schema
    rng = np.random.default_rng(seed)
    w = BatchWorld(world_cfg, starts)
    w.reset(np.arange(starts), rng)
    turn_v, speed_v = np.array(TURN.values, float), np.array(SPEED.values, float)
    active = np.ones(starts, bool)
    kind = np.full(starts, "time-up", dtype=object)
    where = np.zeros((starts, 3))
    pol = np.zeros(starts, np.int64)
    c = world_cfg
    for _ in range(c.episode_steps):
        if not active.any():
            break
        bins = sch.discretise(w.observe(sch.sensor_names))
        rank, _ = comp.decide(pol, bins)
        act = comp.action_values(pol, rank)
        turn, speed = turn_v[act[:, 0]], speed_v[act[:, 1]]
        before = np.column_stack([w.ry - c.dock_depth - c.robot_radius, np.abs(w.rx - w.dock_point[0]),
                                  np.abs(signed_deg(np.degrees(w.rh) - DOCK_HEADING))])
        ev = w.step(active, turn, speed, rng.normal(0.0, c.target_turn_sd, starts))
        ended = active & (ev.collided | ev.docked | ev.dry)
        for i in np.flatnonzero(ended):
            where[i] = before[i]
            if ev.docked[i]:
                kind[i] = "docked"
            elif ev.dry[i]:
                kind[i] = "dry"
            elif np.hypot(w.tx[i] - w.rx[i], w.ty[i] - w.ry[i]) < c.robot_radius + c.target_radius:
                kind[i] = "target"
            else:
                x, y = w.rx[i], w.ry[i]
                near_dock = (y < c.dock_depth + c.robot_radius + 2) and (w.dock_x0 - c.robot_radius - 2 < x < w.dock_x1 + c.robot_radius + 2)
                if not near_dock:
                    kind[i] = "wall"
                elif not (c.dock_depth <= y and w.dock_x0 <= x <= w.dock_x1):
                    kind[i] = "dock-side"
                elif speed[i] > c.dock_max_speed or speed[i] <= 0:
                    kind[i] = "dock-fast"
                else:
                    kind[i] = "dock-angle"
        active &= ~ended
    at_dock = np.isin(kind, ["dock-fast", "dock-angle", "dock-side"])
    return Counter(kind.tolist()), where[at_dock]


def curve(run: Path) -> list[str]:
    rows = list(csv.DictReader((run / "curve.csv").open()))
    return [f"{float(rows[g - 1]['docking_from_random']):.0f}" if g <= len(rows) and rows[g - 1]["docking_from_random"] else "-"
            for g in (10, 20, 30, 40, 50)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--starts", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    missing = [str(r) for r in args.runs if not (r / "best.rules").is_file() or not (r / "curve.csv").is_file()]
    if missing:
        ap.error(f"not a finished coevo learn run directory (no best.rules or curve.csv): {', '.join(missing)}")
    if args.starts < 1:
        ap.error(f"--starts must be at least 1, got {args.starts}")
    total: Counter[str] = Counter()
    spots = []
    print("| run | " + " | ".join(KINDS) + " | dock hits: axis, |offset|, |angle| | curve g10/20/30/40/50 |")
    print("|---|" + "---|" * (len(KINDS) + 2))
    for run in args.runs:
        cfg = WorldConfig()
        settings = run / "config.json"
        if settings.exists():
            import json

            cfg = WorldConfig(**json.loads(settings.read_text()).get("world", {}))
        kinds, where = play(run / "best.rules", cfg, args.starts, args.seed)
        total.update(kinds)
        spots.append(where)
        med = "–" if not len(where) else ", ".join(f"{v:.0f}" for v in np.median(where, axis=0))
        print(f"| {run.name} | " + " | ".join(f"{100 * kinds[k] / args.starts:.1f}" for k in KINDS)
              + f" | {med} | {' '.join(curve(run))} |")
    n = args.starts * len(args.runs)
    allw = np.concatenate(spots)
    med = "–" if not len(allw) else ", ".join(f"{v:.0f}" for v in np.median(allw, axis=0))
    print("| all | " + " | ".join(f"{100 * total[k] / n:.1f}" for k in KINDS) + f" | {med} | |")


if __name__ == "__main__":
    main()
