"""Playing door trials: the rule sets of a population, many trials each, in one batched world.

:func:`play` runs trials to their end with one compiled population, individual
``lane_policy[i]`` driving trial ``i``, and returns what happened and the decision
log.  :class:`DoorEvaluator` is what the GA calls: individual ``p`` owns trials
``[p*k, (p+1)*k)``; with ``GAConfig.common_scenarios`` every individual faces the
same ``k`` trials.  Payoff *(the numbers ours)*: reaching the goal pays
``1 - (1 - success_payoff_min) * time / time limit``, running out of time
``timeout_payoff``, a collision ``collision_payoff`` (report §7: "based on the time
it took ... a collision resulted in a very low payoff, and exceeding the time limit
resulted in a low payoff").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga.operators import Experience
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.tasks.base import ChildRng, Evaluation, Evaluator, Partners, Tick
from coevo.tasks.door.sensors import DOOR, action_values, sense
from coevo.tasks.door.settings import DoorConfig
from coevo.tasks.door.world import COLLISION, GOAL, TIMEOUT, DoorWorld, Trials, draw_trials

__all__ = ["Played", "play", "payoff", "measure", "outcome_rates", "DoorEvaluator"]


@dataclass
class Played:
    """What ``n`` trials did: ``outcome`` and ``time`` per trial, the rules that fired (uint64 bit masks)
    and the decision log (``bins`` (N, 9), ``rule``, ``full``, ``lane``, in time order)."""

    outcome: np.ndarray
    time: np.ndarray
    fired: np.ndarray
    bins: np.ndarray
    rule: np.ndarray
    full: np.ndarray
    lane: np.ndarray
    world: DoorWorld


def play(cfg: DoorConfig, compiled: CompiledPolicies, lane_policy: np.ndarray, trials: Trials, rng: np.random.Generator,
         *, conflict: str = "strongest", tick: Tick | None = None, record: bool = False) -> Played:
    """Run every trial to its end (goal, collision or time limit)."""
    world = DoorWorld(cfg, trials, rng=rng, record=record)
    fired = np.zeros(world.n, dtype=np.uint64)
    logs: tuple[list[np.ndarray], ...] = ([], [], [], [])
    lanes = np.arange(world.n)
    while lanes.size:
        if tick is not None:
            tick()
        bins = sense(world, lanes)
        pol = lane_policy[lanes]
        rank, full = compiled.decide(pol, bins, conflict=conflict, rng=rng)
        rule = compiled.rule_index(pol, rank)
        fired[lanes] |= np.left_shift(np.uint64(1), rule.astype(np.uint64))
        for log, v in zip(logs, (bins, rule, full, lanes)):
            log.append(v)
        speed, turn = action_values(compiled.action_values(pol, rank))
        world.act(lanes, speed, turn)
        lanes = lanes[world.outcome[lanes] == 0]
    bins, rule, full, lane = (np.concatenate(v) for v in logs)
    return Played(world.outcome.copy(), world.time.copy(), fired, bins, rule.astype(np.int64), full, lane, world)


def payoff(cfg: DoorConfig, outcome: np.ndarray, time: np.ndarray) -> np.ndarray:
    """The payoff of each trial (see the module docstring)."""
    limit = cfg.time_limit * cfg.decision_seconds
    won = 1.0 - (1.0 - cfg.success_payoff_min) * np.minimum(time / limit, 1.0)
    return np.where(outcome == GOAL, won, np.where(outcome == COLLISION, cfg.collision_payoff, cfg.timeout_payoff))


def outcome_rates(outcome: np.ndarray) -> dict[str, float]:
    """% of trials that reached the goal, collided, ran out of time."""
    n = max(len(outcome), 1)
    return {"success": 100.0 * float((outcome == GOAL).sum()) / n,
            "collision": 100.0 * float((outcome == COLLISION).sum()) / n,
            "timeout": 100.0 * float((outcome == TIMEOUT).sum()) / n}


class DoorEvaluator(Evaluator):
    """Plays populations of door rule sets; the ``details`` of an evaluation is its :class:`Played`."""

    def __init__(self, world: DoorConfig, ga: GAConfig) -> None:
        self.behaviour = DOOR
        self.world_cfg = world
        self.ga = ga

    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        if partners:
            raise ConfigError(f"the door task learns alone; got partners {', '.join(sorted(partners))}")
        for p in policies:
            if p.behaviour != DOOR:
                raise ConfigError(f"cannot evaluate a {p.behaviour} rule set in the door task")
        per, P = episodes or self.ga.episodes, len(policies)
        if self.ga.common_scenarios:
            trials = draw_trials(self.world_cfg, per, rng).tile(P)
        else:
            trials = draw_trials(self.world_cfg, P * per, rng)
        out = play(self.world_cfg, CompiledPolicies(policies), np.repeat(np.arange(P), per), trials, rng,
                   conflict=self.ga.conflict, tick=tick)
        pay = payoff(self.world_cfg, out.outcome, out.time)
        return Evaluation(pay.reshape(P, per).mean(axis=1), np.full(P, per), self._experience(out, pay, P, per), out)

    def _experience(self, out: Played, pay: np.ndarray, P: int, per: int) -> list[Experience]:
        """Each individual's trials and decisions (the log sorted by trial, time order kept)."""
        order = np.argsort(out.lane, kind="stable")
        lane = out.lane[order]
        bins, rule, full = out.bins[order], out.rule[order], out.full[order]
        cut = np.searchsorted(lane, np.arange(P + 1) * per)
        exps = []
        for i in range(P):
            s = slice(cut[i], cut[i + 1])
            exps.append(Experience(out.fired[i * per:(i + 1) * per], pay[i * per:(i + 1) * per], bins[s], rule[s],
                                   full[s], lane[s] - i * per, self.ga.high_payoff_quantile))
        return exps

    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        """% of the best's re-evaluation trials that reached the goal, collided or ran out of time."""
        return dict(outcome_rates(check.details.outcome))


def measure(rules: RuleSet, cfg: DoorConfig, *, trials: int, seed: int) -> dict[str, float | int | None]:
    """External performance (report §8.1): ``rules`` on ``trials`` fresh trials, % success and the rest
    (``mean_time_to_goal`` in seconds, None when no trial reached it)."""
    rng = np.random.default_rng(seed)
    out = play(cfg, CompiledPolicies([rules]), np.zeros(trials, dtype=np.int64), draw_trials(cfg, trials, rng), rng)
    pay = payoff(cfg, out.outcome, out.time)
    won = out.outcome == GOAL
    return {**outcome_rates(out.outcome), "payoff": float(pay.mean()), "trials": trials,
            "mean_time_to_goal": float(out.time[won].mean()) if won.any() else None}
