"""Measuring a policy (a TD table's greedy one, or rule sets) on fresh trials, the GA's measure of each task."""

from __future__ import annotations

from typing import Any

import numpy as np

from coevo.experiments.earl.td.envs import make_env
from coevo.experiments.earl.td.spec import Policy

__all__ = ["MEASURE_NAMES", "measure_policy", "rules_policy"]

MEASURE_NAMES = {"tracking": "quality_tracking", "docking": "docking_from_random", "door": "success"}


def measure_policy(task: str, policy: Policy, *, groups: int, trials: int, rng: np.random.Generator,
                   world: Any = None) -> np.ndarray:
    """The task's measure (in %) of ``groups`` policies at once on fresh trials, played greedily.

    Lanes ``[g*trials, (g+1)*trials)`` are group g's; ``policy`` gets the lane ids. ``trials`` is
    epochs for Tracking (Quality Tracking: % of their episodes with >= 80 % of the steps in range),
    random starts for Docking (% that dock), trials for the door (% that reach the goal).
    """
    env = make_env(task, groups * trials, rng, restart=False, world=world)
    while env.active.any():
        lanes = np.flatnonzero(env.active)
        actions = np.zeros(env.n, dtype=np.int64)
        actions[lanes] = policy(env.bins()[lanes], lanes, rng)
        env.step(actions, rng)
    ep = env.episodes()
    group = ep["lane"].astype(np.int64) // trials
    if task == "tracking":
        from coevo.tasks.fuel.measures import QUALITY_FRACTION
        from coevo.tasks.fuel.settings import WorldConfig

        cfg = env.cfg
        if not isinstance(cfg, WorldConfig):
            raise TypeError(f"Tracking plays in the fuel world, not in one of {type(cfg).__name__}")
        hit = ep["tracked"] >= QUALITY_FRACTION * cfg.episode_steps
    elif task == "docking":
        hit = ep["docked"].astype(bool)
    else:
        from coevo.tasks.door.world import GOAL

        hit = ep["outcome"] == GOAL
    n = np.bincount(group, minlength=groups)
    return 100.0 * np.bincount(group, weights=hit.astype(float), minlength=groups) / np.maximum(n, 1)


def rules_policy(rulesets: list[Any], trials: int, *, conflict: str = "strongest") -> Policy:
    """A measurement policy from rule sets (group g plays ``rulesets[g]``), as the GA's rules act."""
    from coevo.policy.matcher import CompiledPolicies

    compiled = CompiledPolicies(rulesets)
    n_speed = len(compiled.schema.actions[1].values)

    def policy(bins: np.ndarray, lanes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        pol = lanes // trials
        rank, _ = compiled.decide(pol, bins, conflict=conflict, rng=rng)
        act = compiled.action_values(pol, rank)
        return act[:, 0].astype(np.int64) * n_speed + act[:, 1]

    return policy
