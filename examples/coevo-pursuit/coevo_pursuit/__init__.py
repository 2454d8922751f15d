"""Pursuit and evasion, a coevo task from outside coevo: two robots in a square arena learn against each other.

The pursuer is paid for capturing the evader soon, the evader for staying free (:mod:`coevo_pursuit.world`); each
is a SAMUEL rule set learned by its own GA worker.  Regimes:

* ``mutual``: each learns against the other's best so far, published over the bus (competitive co-evolution);
* ``independent``: each learns against the other's hand-written rules (``pursuer.rules``: head for the evader;
  ``evader.rules``: head away from the pursuer), which are also where each GA starts.

Installed, it is the task ``pursuit`` of every coevo command (the entry point in pyproject.toml); nothing in
coevo names it.
"""

from __future__ import annotations

from collections.abc import Mapping
from importlib import resources

import numpy as np

from coevo.config import GAConfig
from coevo.ga.operators import Experience
from coevo.policy.rules import RuleSet
from coevo.policy.text import parse_ruleset
from coevo.tasks.base import ChildRng, Evaluation, Evaluator, Partners, Task, Tick, check_behaviour, check_regime

from coevo_pursuit.settings import PursuitConfig
from coevo_pursuit.world import BEHAVIOURS, EVADER, PURSUER, play

__all__ = ["PursuitTask", "PursuitConfig", "PursuitEvaluator", "hand_written", "PURSUER", "EVADER"]

#: Each side's measure, in % of episodes: the pursuer's captures, the evader's escapes.
MEASURE = {PURSUER: "captured", EVADER: "escaped"}


def hand_written(behaviour: str) -> RuleSet:
    """The shipped rules of ``behaviour``: the opponent of the independent regime, and where a GA starts."""
    return parse_ruleset(resources.files(__package__).joinpath(f"{behaviour}.rules").read_text(), behaviour)


def opponent_of(behaviour: str) -> str:
    return EVADER if behaviour == PURSUER else PURSUER


class PursuitEvaluator(Evaluator):
    """Plays a population of one side against the other side's model (or its hand-written rules)."""

    def __init__(self, behaviour: str, world: PursuitConfig, ga: GAConfig) -> None:
        self.behaviour, self.world, self.ga = behaviour, world, ga

    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        per = episodes or self.ga.episodes
        opponent = partners.get(opponent_of(self.behaviour)) or hand_written(opponent_of(self.behaviour))
        played = play(policies, self.behaviour, opponent, self.world, rng, episodes=per, conflict=self.ga.conflict)
        payoff = played.payoff[self.behaviour]
        bins, rule, full, lane = played.log
        exps = []
        for i in range(len(policies)):
            mine = (lane >= i * per) & (lane < (i + 1) * per)
            exps.append(Experience(played.fired[i * per:(i + 1) * per], payoff[i * per:(i + 1) * per], bins[mine],
                                   rule[mine].astype(np.int64), full[mine], lane[mine] - i * per,
                                   self.ga.high_payoff_quantile))
        fitness = payoff.reshape(len(policies), per).mean(axis=1)
        return Evaluation(fitness, np.full(len(policies), per), exps, played.captured.reshape(len(policies), per))

    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        captured = float(100.0 * check.details.mean())
        return {MEASURE[self.behaviour]: captured if self.behaviour == PURSUER else 100.0 - captured}


class PursuitTask(Task[PursuitConfig]):
    name = "pursuit"
    behaviours = BEHAVIOURS
    regimes = ("mutual", "independent")
    world_settings = PursuitConfig
    measure_labels = {"captured": "caught", "escaped": "free"}

    def initial_rules(self, behaviour: str, world: PursuitConfig) -> RuleSet:
        check_behaviour(self, behaviour)
        return hand_written(behaviour)

    def partners_needed(self, behaviour: str, regime: str) -> tuple[str, ...]:
        check_behaviour(self, behaviour)
        return (opponent_of(behaviour),) if check_regime(self, regime) == "mutual" else ()

    def evaluator(self, behaviour: str, world: PursuitConfig, ga: GAConfig) -> PursuitEvaluator:
        check_behaviour(self, behaviour)
        return PursuitEvaluator(behaviour, world, ga)

    def status_measures(self, behaviour: str, measures: Mapping[str, float | None]) -> dict[str, float]:
        key = MEASURE[behaviour]
        return {key: float(measures.get(key) or 0.0)}

    def final_measures(self, behaviour: str, best: RuleSet, *, world: PursuitConfig, partners: Partners,
                       epochs: int, seed: int) -> dict[str, float | int]:
        ev = self.evaluator(behaviour, world, GAConfig()).evaluate([best], partners, np.random.default_rng(seed),
                                                                   episodes=epochs)
        captured = float(100.0 * ev.details.mean())
        return {"captured": captured, "escaped": 100.0 - captured, "payoff": float(ev.fitness[0])}

    def run_measures(self, policies: Mapping[str, RuleSet], *, world: PursuitConfig, epochs: int,
                     seed: int) -> dict[str, float | int] | None:
        if not all(b in policies for b in BEHAVIOURS):
            return None
        return self.final_measures(PURSUER, policies[PURSUER], world=world, partners={EVADER: policies[EVADER]},
                                   epochs=epochs, seed=seed)

    def display(self):  # type: ignore[no-untyped-def]
        from coevo_pursuit.display import PursuitDisplay

        return PursuitDisplay()
