"""How the combined robot's episodes end, per task: the diagnosis behind docs/compare.md's Table 1 findings.

    python benchmarks/epoch_anatomy.py RUN_DIR [RUN_DIR ...] [--epochs 300] [--seed 5]

For each ``coevo run`` directory (its workers' final ``best.rules``) it plays
``--epochs`` fresh epochs and prints, per run: the average epoch length, how the
Executive's Tracking and Docking episodes ended (collided, ran dry, docked, time
up), the mean speed and turn rate the robot used while tracking (what sets how
long the fuel lasts), and then the same summed over all runs given.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np

from coevo.errors import CoevoError
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.text import parse_ruleset
from coevo.rundir.settings import RunSettings
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK, Behaviour
from coevo.tasks.fuel.recorder import Recorder
from coevo.tasks.fuel.runner import Rules, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld


def anatomy(run_dir: Path, epochs: int, seed: int) -> tuple[Counter[str], float, float, float]:
    world = RunSettings.load(run_dir / "run.json").world_config()
    if not isinstance(world, WorldConfig):
        raise SystemExit(f"{run_dir} is not a run of the fuel task")
    rules = {b: parse_ruleset((run_dir / "workers" / b.value / "best.rules").read_text(), b) for b in Behaviour}
    ctrl = {b: Rules.single(CompiledPolicies([rules[b]]), epochs) for b in Behaviour}
    rec = Recorder()
    out = run_lanes(BatchWorld(world, epochs), lane_episodes=world.epoch_episodes, executive=ctrl[Behaviour.EXECUTIVE],
                    tracking=ctrl[Behaviour.TRACKING], docking=ctrl[Behaviour.DOCKING], restart_epochs=False,
                    rng=np.random.default_rng(seed), record=rec)
    p = out.played
    c: Counter[str] = Counter()
    for name, task in (("track", TASK_TRACK), ("dock", TASK_DOCK)):
        mine = p & (out.task == task)
        c[f"{name} episodes"] += int(mine.sum())
        c[f"{name}: collided"] += int((mine & out.collided).sum())
        c[f"{name}: ran dry"] += int((mine & out.dry).sum())
        c[f"{name}: docked"] += int((mine & out.docked).sum())
        c[f"{name}: time up"] += int((mine & ~out.collided & ~out.dry & ~out.docked).sum())
    speed, turn = _tracking_controls(rec, world.step_seconds)
    return c, float(out.epoch_episodes.mean()), speed, turn


def _tracking_controls(rec: Recorder, dt: float) -> tuple[float, float]:
    """Mean |speed| (ips) and |turn rate| (deg/s) over the steps of Tracking episodes, from the recorded path."""
    track = (rec.task == TASK_TRACK)[:, None, :]
    ok = track & np.isfinite(rec.rx[:, 1:]) & np.isfinite(rec.rx[:, :-1])
    dist = np.hypot(np.diff(rec.rx, axis=1), np.diff(rec.ry, axis=1))
    dh = np.degrees(np.diff(rec.rh, axis=1))
    dh = (dh + 180.0) % 360.0 - 180.0
    return float(np.mean(dist[ok]) / dt), float(np.mean(np.abs(dh[ok])) / dt)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--epochs", type=int, default=300)
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args()
    if args.epochs < 1:
        ap.error(f"--epochs must be at least 1, got {args.epochs}")
    total: Counter[str] = Counter()
    for d in args.runs:
        try:
            c, length, speed, turn = anatomy(d, args.epochs, args.seed)
        except (CoevoError, OSError) as exc:
            raise SystemExit(f"{d}: {type(exc).__name__}: {exc}") from None
        total += c
        print(f"{d.name}: epoch length {length:.2f}; tracking at {speed:.1f} ips, {turn:.1f} deg/s on average; "
              + ", ".join(f"{k} {v}" for k, v in c.items()))
    for task in ("track", "dock"):
        n = total[f"{task} episodes"]
        if n:
            shares = ", ".join(f"{k.split(': ')[1]} {100 * v / n:.1f} %" for k, v in total.items()
                               if k.startswith(f"{task}:"))
            print(f"all runs, {task} episodes ({n}): {shares}")


if __name__ == "__main__":
    main()
