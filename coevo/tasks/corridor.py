"""The corridor: the smallest task, for tests that the core names no task.

A walker stands in a corridor of ``length`` cells and must reach the last one
within ``steps`` steps; it senses its cell and sets ``move`` to -1, 0 or +1.  Its
payoff is 0 if it does not arrive, else ``1 - steps used / (steps + 1)``; its
measure ``arrived`` is the share of episodes that reach the end.  Every episode
starts on a random cell before the last.  Many lanes play at once on numpy arrays.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from pydantic import BaseModel, Field

from coevo.config import GAConfig, Settings
from coevo.errors import ConfigError
from coevo.ga.operators import Experience
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.policy.schema import Action, Schema, Sensor, register
from coevo.tasks.base import ChildRng, Evaluation, Evaluator, Partners, Task, Tick

__all__ = ["CorridorTask", "CorridorConfig", "CORRIDOR"]

CORRIDOR = "corridor"
_MAX_CELLS = 16  # the cell sensor's bins: the longest corridor


class CorridorConfig(Settings):
    length: int = Field(12, ge=2, le=_MAX_CELLS, description="cells in the corridor")
    steps: int = Field(24, ge=1, le=10_000, description="steps an episode may take")


_MOVE = Action("move", (-1, 0, 1))
register(Schema(CORRIDOR, (Sensor("cell", 1.0, _MAX_CELLS, False, "cells"),), (_MOVE,)))


class CorridorEvaluator(Evaluator):
    def __init__(self, world: CorridorConfig, ga: GAConfig) -> None:
        self.behaviour = CORRIDOR
        self.world, self.ga = world, ga

    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        per = episodes or self.ga.episodes
        P, T, goal = len(policies), self.world.steps, self.world.length - 1
        L = P * per
        compiled = CompiledPolicies(policies)
        lane_policy = np.repeat(np.arange(P), per)
        pos = np.tile(rng.integers(0, goal, per), P)  # common random starts for every individual
        used = np.full(L, T)
        active = np.ones(L, dtype=bool)
        fired = np.zeros(L, dtype=np.uint64)
        log_bins, log_rule, log_full, log_lane = [], [], [], []
        moves = np.array(_MOVE.values, dtype=np.int64)
        for t in range(T):
            lanes = np.flatnonzero(active)
            if lanes.size == 0:
                break
            if tick is not None:
                tick()
            bins = pos[lanes].astype(np.uint8)[:, None]
            rank, full = compiled.decide(lane_policy[lanes], bins, conflict=self.ga.conflict, rng=rng)
            rule = compiled.rule_index(lane_policy[lanes], rank)
            fired[lanes] |= np.uint64(1) << rule.astype(np.uint64)
            log_bins.append(bins), log_rule.append(rule), log_full.append(full), log_lane.append(lanes)
            pos[lanes] = np.clip(pos[lanes] + moves[compiled.action_values(lane_policy[lanes], rank)[:, 0]], 0, goal)
            arrived = lanes[pos[lanes] == goal]
            used[arrived] = t + 1
            active[arrived] = False
        reached = ~active
        payoff = np.where(reached, 1.0 - used / (T + 1), 0.0)
        bins, rule = np.concatenate(log_bins), np.concatenate(log_rule).astype(np.int64)
        full, lane = np.concatenate(log_full), np.concatenate(log_lane)
        exps = []
        for i in range(P):
            mine = (lane >= i * per) & (lane < (i + 1) * per)
            exps.append(Experience(fired[i * per:(i + 1) * per], payoff[i * per:(i + 1) * per], bins[mine], rule[mine],
                                   full[mine], lane[mine] - i * per, self.ga.high_payoff_quantile))
        fitness = payoff.reshape(P, per).mean(axis=1)
        return Evaluation(fitness, np.full(P, per), exps, reached.reshape(P, per))

    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        return {"arrived": float(100.0 * check.details.mean())}


class CorridorTask(Task):
    name = "corridor"
    behaviours = (CORRIDOR,)
    world_settings = CorridorConfig

    def evaluator(self, behaviour: str, world: BaseModel, ga: GAConfig) -> CorridorEvaluator:
        self.check_behaviour(behaviour)
        if not isinstance(world, CorridorConfig):
            raise ConfigError(f"the corridor task needs CorridorConfig settings, got {type(world).__name__}")
        return CorridorEvaluator(world, ga)

    def status_measures(self, behaviour: str, measures: Mapping[str, float | None]) -> dict[str, float]:
        return {"arrived": float(measures["arrived"] or 0.0)}

    def final_measures(self, behaviour: str, best: RuleSet, *, world: BaseModel, partners: Partners,
                       epochs: int, seed: int) -> dict[str, float | int]:
        ev = self.evaluator(behaviour, world, GAConfig()).evaluate([best], {}, np.random.default_rng(seed), episodes=epochs)
        return {"arrived": float(100.0 * ev.details.mean()), "payoff": float(ev.fitness[0])}

    def run_measures(self, policies: Mapping[str, RuleSet], *, world: BaseModel, epochs: int,
                     seed: int) -> dict[str, float | int] | None:
        best = policies.get(CORRIDOR)
        return None if best is None else self.final_measures(CORRIDOR, best, world=world, partners={}, epochs=epochs, seed=seed)
