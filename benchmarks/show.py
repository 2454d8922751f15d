"""How long `coevo show` takes to draw one epoch: PNG (target < 2 s) and GIF (target < 20 s).

Baseline, measured in the same run: the bare simulation of the same epoch (one lane,
no recorder).  Then the recorded play, the PNG (scene + drawing + atomic write) and the
GIF (at most 150 frames).  matplotlib's import is timed apart: a fresh `coevo show`
pays it once (~0.4-0.7 s here).  Best of --repeats for the fast steps.

    python benchmarks/show.py [--source RULES_OR_RUN_DIR] [--seed 3] [--repeats 3] [--out DIR]

Without --source the robot is the default Tracking and Docking rules under a simple
Executive (dock below 20 % fuel), whose epoch of seed 3 runs 4 episodes (181 steps).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from coevo.policy.matcher import CompiledPolicies
from coevo.policy.text import parse_ruleset
from coevo.scene import animate, draw_png
from coevo.show.source import from_path
from coevo.tasks.fuel.pictures import Robot, play, robot_from_rules, scene_for
from coevo.tasks.fuel import default_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.runner import ALWAYS_DOCK, ALWAYS_TRACK, Rules, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld

EXEC = "# behaviour: executive\nIF fuel = [0, 20] THEN SET task = dock (strength 0.9)\nIF ANY THEN SET task = track (strength 0.5)\n"


def bare_epoch(robot: Robot, seed: int) -> int:
    """The same epoch without a recorder; returns its steps."""
    def rules(rs):  # type: ignore[no-untyped-def]
        return None if rs is None else Rules.single(CompiledPolicies([rs]), 1)
    ex = rules(robot.executive) or (ALWAYS_TRACK if robot.tracking is not None else ALWAYS_DOCK)
    out = run_lanes(BatchWorld(robot.world, 1), lane_episodes=robot.world.epoch_episodes, executive=ex,
                    tracking=rules(robot.tracking), docking=rules(robot.docking), restart_epochs=False,
                    rng=np.random.default_rng(seed))
    return int(out.steps.sum())


def best_of(n: int, fn) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", help="a rule file or run directory (default: default rules + a simple Executive)")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", help="keep the pictures here (default: a temporary directory)")
    args = ap.parse_args()
    if args.source:
        robot = from_path(Path(args.source), world_over={}, partners={}, wanted=None).robot
    else:
        robot = robot_from_rules("bench", WorldConfig(), {Behaviour.EXECUTIVE: parse_ruleset(EXEC),
                                                          Behaviour.TRACKING: default_ruleset("tracking"),
                                                          Behaviour.DOCKING: default_ruleset("docking")})
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="coevo-show-bench-"))
    out.mkdir(parents=True, exist_ok=True)

    t0 = time.perf_counter()
    import matplotlib.animation  # noqa: F401
    import matplotlib.pyplot  # noqa: F401
    mpl = time.perf_counter() - t0

    steps = bare_epoch(robot, args.seed)
    bare = best_of(args.repeats, lambda: bare_epoch(robot, args.seed))
    played = play(robot, seed=args.seed)
    rec = best_of(args.repeats, lambda: play(robot, seed=args.seed))
    png = best_of(args.repeats, lambda: draw_png(scene_for(play(robot, seed=args.seed)), out / "epoch.png", trace=True))
    frames = 0

    def gif() -> None:
        nonlocal frames
        frames = animate(scene_for(play(robot, seed=args.seed)), out / "epoch.gif")

    gif_s = best_of(1, gif)
    print(f"robot {robot.name}, seed {args.seed}: one epoch of {played.episodes} episodes, {steps} steps")
    print(f"  matplotlib import (once per process)  {mpl:7.3f} s")
    print(f"  bare simulation (baseline)            {bare:7.3f} s")
    print(f"  recorded play                         {rec:7.3f} s  ({rec / bare:.2f}x the baseline)")
    print(f"  PNG with trace panel (play + draw)    {png:7.3f} s  ({png / bare:.0f}x the baseline; target < 2 s)"
          f"  {(out / 'epoch.png').stat().st_size / 1024:.0f} kB")
    print(f"  GIF, {frames:3d} frames (play + draw)      {gif_s:7.3f} s  ({gif_s / bare:.0f}x the baseline; target < 20 s)"
          f"  {(out / 'epoch.gif').stat().st_size / 1024:.0f} kB")
    print(f"  pictures in {out}")


if __name__ == "__main__":
    main()
