"""``coevo bench``: robot-steps per second, batched world vs a plain one-episode loop, same run.

Both sides drive robots with the same rule sets (evolved-size: ``rules`` rules
each, random unless a rule file is given) and count only the robot-steps actually
simulated (an episode that ends early stops counting).  The batched side runs
``lanes`` episodes at once (the GA's 50 x 90 by default); the plain side runs
episodes one after another until ``baseline_seconds`` have passed.
"""

from __future__ import annotations

import resource
import time
import tracemalloc
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet, random_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.runner import ALWAYS_DOCK, ALWAYS_TRACK, Rules, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.single import run_episode
from coevo.tasks.fuel.world import BatchWorld

__all__ = ["BenchResult", "bench", "policies_for", "workload"]


@dataclass(frozen=True)
class BenchResult:
    behaviour: str
    lanes: int
    rules_per_policy: int
    batched_steps_per_s: float
    baseline_steps_per_s: float
    ratio: float
    batched_robot_steps: int
    baseline_robot_steps: int
    batch_peak_mb: float  # tracemalloc peak of the batched episode (numpy and Python objects)
    max_rss_mb: float  # the process's peak resident set, everything included

    def as_dict(self) -> dict[str, float | int | str]:
        return asdict(self)


def workload(behaviour: Behaviour, pols: list[RuleSet], lanes: int) -> dict[str, Any]:
    """The batched side's controllers, as :func:`.runner.run_lanes`' keyword arguments: ``pols`` spread over
    ``lanes`` lanes, under the trivial Executive."""
    ctrl = Rules(CompiledPolicies(pols), np.arange(lanes) % len(pols))
    if behaviour == Behaviour.DOCKING:
        return dict(tracking=None, docking=ctrl, executive=ALWAYS_DOCK)
    return dict(tracking=ctrl, docking=None, executive=ALWAYS_TRACK)


def policies_for(behaviour: Behaviour, policies: int, rules: int, rng: np.random.Generator,
                 policy: RuleSet | None = None) -> list[RuleSet]:
    """``policies`` random rule sets of ``rules`` rules, or ``policy`` as many times."""
    return [policy] * policies if policy is not None else [random_ruleset(behaviour, rules, rng) for _ in range(policies)]


def bench(
    *,
    world: WorldConfig,
    behaviour: Behaviour = Behaviour.TRACKING,
    lanes: int = 4500,
    policies: int = 50,
    rules: int = 32,
    repeats: int = 3,
    baseline_seconds: float = 3.0,
    seed: int = 0,
    policy: RuleSet | None = None,
) -> BenchResult:
    rng = np.random.default_rng(seed)
    pols = policies_for(behaviour, policies, rules, rng, policy)
    kw = workload(behaviour, pols, lanes)
    w = BatchWorld(world, lanes)
    best = 0.0
    steps_total = 0
    for r in range(repeats):
        t0 = time.perf_counter()
        out = run_lanes(w, lane_episodes=1, restart_epochs=False, rng=np.random.default_rng(seed + r), **kw)
        dt = time.perf_counter() - t0
        steps = int(out.steps.sum())
        steps_total += steps
        best = max(best, steps / dt)
    # Memory in a separate, untimed run: tracemalloc slows numpy allocation down.
    tracemalloc.start()
    run_lanes(w, lane_episodes=1, restart_epochs=False, rng=np.random.default_rng(seed), **kw)
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    base_steps = 0
    t0 = time.perf_counter()
    i = 0
    while i == 0 or time.perf_counter() - t0 < baseline_seconds:  # at least one episode, however busy the machine
        base_steps += run_episode(world, pols[i % policies], rng)
        i += 1
    base = base_steps / (time.perf_counter() - t0)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return BenchResult(
        behaviour=str(behaviour), lanes=lanes, rules_per_policy=len(pols[0]),
        batched_steps_per_s=best, baseline_steps_per_s=base, ratio=best / base,
        batched_robot_steps=steps_total, baseline_robot_steps=base_steps,
        batch_peak_mb=peak, max_rss_mb=rss,
    )
