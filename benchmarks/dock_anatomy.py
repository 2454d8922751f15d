"""How learned Docking policies fail from random starts, and how they learned: the record of docs/docking-learning.md.

    python benchmarks/dock_anatomy.py RUN_DIR [RUN_DIR ...] [--starts 1000] [--seed 7] [--target-range LO,HI]

For each ``coevo learn --behaviour docking`` run directory (its ``best.rules``) it plays
``--starts`` fresh single episodes from random starts (as ``docking_from_random_starts``
does) and prints how they ended: docked; collided, split by what was hit (the dock's
front too fast, the dock's front at more than the accepted angle, the dock's side or
corner, a wall, the Target); ran dry; timed out.  For the collisions at the dock it gives
where they happened in the dock's frame (median distance along the axis and |lateral
offset| one step before, median |angle off head-on|).  Then the run's learning curve:
docking from random starts of each generation's best at generations 10, 20, 30, 40, 50
(``curve.csv``).  The last line sums every run given.

``--target-range 40,60`` places the Target that far from the robot, at a random bearing, instead of anywhere:
where tracking leaves the robot when an Executive calls Docking (the tracking range), so that what Docking meets
inside the combined robot can be told from what it meets from random starts.  A RUN_DIR may also be a
``best.rules`` file of any run (a worker's ``workers/docking/best.rules``); it then has no curve.
"""

from __future__ import annotations

import argparse
import csv
from collections import Counter
from pathlib import Path

import numpy as np

from coevo.errors import CoevoError
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.text import parse_ruleset
from coevo.tasks.fuel.behaviours import SPEED, TURN, Behaviour
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import DOCK_HEADING, BatchWorld, signed_deg

KINDS = ("docked", "dock-fast", "dock-angle", "dock-side", "wall", "target", "dry", "time-up")


def target_near(w: BatchWorld, rng: np.random.Generator, lo: float, hi: float) -> None:
    """Move each lane's Target to ``lo``-``hi`` in from its robot at a random bearing, inside the arena and clear of the
    dock (a lane with no such place in 100 draws keeps its Target)."""
    c = w.cfg
    edge = c.spawn_margin + c.target_radius
    tx, ty = w.tx.copy(), w.ty.copy()
    for i in range(w.n):
        for _ in range(100):
            d, a = rng.uniform(lo, hi), rng.uniform(-np.pi, np.pi)
            x, y = w.rx[i] + d * np.cos(a), w.ry[i] + d * np.sin(a)
            if edge < x < c.arena - edge and edge + c.dock_depth + 2 * c.robot_radius < y < c.arena - edge:
                tx[i], ty[i] = x, y
                break
    w.set_state(np.arange(w.n), target=(tx, ty))  # once: each call re-places every lane's bodies


def play(rules_path: Path, world_cfg: WorldConfig, starts: int, seed: int,
         target_range: tuple[float, float] | None = None) -> tuple[Counter[str], np.ndarray]:
    """End kinds of ``starts`` fresh episodes, and (axis, |offset|, |angle|) rows one step before each dock collision."""
    rs = parse_ruleset(rules_path.read_text(), Behaviour.DOCKING)
    comp = CompiledPolicies([rs])
    sch = comp.schema
    rng = np.random.default_rng(seed)
    w = BatchWorld(world_cfg, starts)
    w.reset(np.arange(starts), rng)
    if target_range is not None:
        target_near(w, rng, *target_range)
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
    if not (run / "curve.csv").is_file():
        return ["-"] * 5
    rows = list(csv.DictReader((run / "curve.csv").open()))
    return [f"{float(rows[g - 1]['docking_from_random']):.0f}" if g <= len(rows) and rows[g - 1]["docking_from_random"] else "-"
            for g in (10, 20, 30, 40, 50)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--starts", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--target-range", metavar="LO,HI", help="the Target LO-HI in from the robot at the start (e.g. 40,60)")
    args = ap.parse_args()
    missing = [str(r) for r in args.runs if not r.is_file() and not ((r / "best.rules").is_file() and (r / "curve.csv").is_file())]
    if missing:
        ap.error(f"neither a rule file nor a finished coevo learn run directory (best.rules, curve.csv): {', '.join(missing)}")
    if args.starts < 1:
        ap.error(f"--starts must be at least 1, got {args.starts}")
    near = None
    if args.target_range is not None:
        try:
            lo, hi = (float(v) for v in args.target_range.split(","))
        except ValueError:
            ap.error(f"--target-range must be LO,HI in inches, got {args.target_range!r}")
        if not 0 <= lo <= hi <= 150:  # also refuses nan
            ap.error(f"--target-range needs 0 <= LO <= HI <= 150, got {args.target_range!r}")
        near = (lo, hi)
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
        rules = run if run.is_file() else run / "best.rules"
        try:
            kinds, where = play(rules, cfg, args.starts, args.seed, near)
        except CoevoError as exc:  # not a Docking rule set
            ap.error(f"{rules}: {exc}")
        total.update(kinds)
        spots.append(where)
        med = "–" if not len(where) else ", ".join(f"{v:.0f}" for v in np.median(where, axis=0))
        print(f"| {run.name if run.is_dir() else run} | " + " | ".join(f"{100 * kinds[k] / args.starts:.1f}" for k in KINDS)
              + f" | {med} | {' '.join(curve(run))} |")
    n = args.starts * len(args.runs)
    allw = np.concatenate(spots)
    med = "–" if not len(allw) else ", ".join(f"{v:.0f}" for v in np.median(allw, axis=0))
    print("| all | " + " | ".join(f"{100 * total[k] / n:.1f}" for k in KINDS) + f" | {med} | |")


if __name__ == "__main__":
    main()
