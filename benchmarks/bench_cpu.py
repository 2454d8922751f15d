"""``coevo bench``'s batched workload timed in CPU seconds: robot-steps per CPU-second, best of ``--repeats``.

    python benchmarks/bench_cpu.py [--behaviour tracking] [--policy RULES] [--repeats 3]

The same episodes as ``coevo bench`` (4,500 lanes, 50 random 32-rule policies from seed 0, or one rule file
for all), after one untimed warm-up episode (numba's loading, the world's first steps); ``time.process_time``
is steadier than the bench's wall clock on a machine shared with other jobs.  Prints one JSON line.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from coevo.errors import CoevoError
from coevo.policy.text import parse_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.bench import policies_for, workload
from coevo.tasks.fuel.runner import run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld

LANES, POLICIES, RULES = 4500, 50, 32  # coevo bench's defaults


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--behaviour", choices=["tracking", "docking"], default="tracking")
    p.add_argument("--policy", type=Path, help="a rule file driving every lane (default: random rule sets)")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    if a.repeats < 1:
        p.error(f"--repeats must be at least 1, got {a.repeats}")
    beh = Behaviour(a.behaviour)
    policy = None
    if a.policy is not None:
        try:
            policy = parse_ruleset(a.policy.read_text(encoding="utf-8"), beh)
        except (OSError, UnicodeDecodeError, CoevoError) as exc:
            p.error(f"--policy {a.policy}: not a readable {beh} rule file ({exc})")
    kw = workload(beh, policies_for(beh, POLICIES, RULES, np.random.default_rng(0), policy), LANES)
    world = BatchWorld(WorldConfig(), LANES)
    run_lanes(world, lane_episodes=1, restart_epochs=False, rng=np.random.default_rng(99), **kw)  # warm-up
    best = 0.0
    for r in range(a.repeats):
        t0 = time.process_time()
        out = run_lanes(world, lane_episodes=1, restart_epochs=False, rng=np.random.default_rng(r), **kw)
        best = max(best, int(out.steps.sum()) / (time.process_time() - t0))
    print(json.dumps({"behaviour": str(beh), "policy": str(a.policy) if a.policy else None,
                      "robot_steps_per_cpu_s": round(best)}))


if __name__ == "__main__":
    main()
