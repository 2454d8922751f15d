"""Evaluating a population of one behaviour against models of the other two.

The models of the partners are fixed rule sets for the duration of one evaluation
(best so far, in the report's regimes) or the trivial Executive that always picks
the learner.  All individuals of a population run in one batched world: individual
``i`` owns lanes ``[i*l, (i+1)*l)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coevo.behaviours import TASK_DOCK, TASK_TRACK, Behaviour
from coevo.config import GAConfig, WorldConfig
from coevo.errors import ConfigError
from coevo.ga.operators import Experience
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.sim.measures import Measures, measure
from coevo.sim.runner import Outcome, Rules, Trivial, run_lanes
from coevo.sim.world import BatchWorld

__all__ = ["Partners", "Evaluation", "Evaluator"]


@dataclass(frozen=True)
class Partners:
    """The learner's models of the other agents; ``executive=None`` means "always picks me"."""

    executive: RuleSet | None = None
    tracking: RuleSet | None = None
    docking: RuleSet | None = None


@dataclass
class Evaluation:
    """Fitness of each individual, with what each did (for the Lamarckian operators)."""

    fitness: np.ndarray
    episodes: np.ndarray  # episodes each individual controlled (0: starved of experience)
    experience: list[Experience]
    outcome: Outcome

    def measures(self, episode_steps: int) -> Measures:
        return measure(self.outcome, episode_steps)


class Evaluator:
    """Runs populations of ``behaviour`` in batched worlds (kept and reused per batch size)."""

    def __init__(self, behaviour: Behaviour | str, world: WorldConfig, ga: GAConfig) -> None:
        self.behaviour = Behaviour(behaviour)
        self.world_cfg = world
        self.ga = ga
        self._worlds: dict[int, BatchWorld] = {}
        self.tick: Callable[[], None] | None = None  # called between episode rounds (a worker's heartbeat)

    def _world(self, lanes: int) -> BatchWorld:
        if lanes not in self._worlds:
            self._worlds[lanes] = BatchWorld(self.world_cfg, lanes)
        return self._worlds[lanes]

    def fresh_starts(self, partners: Partners) -> bool:
        """Does every episode start from a fresh random placement? Docking with the trivial
        Executive does (``GAConfig.docking_fresh_starts``): that is where an Executive calls it."""
        return self.behaviour is Behaviour.DOCKING and partners.executive is None and self.ga.docking_fresh_starts

    def layout(self, episodes: int, *, fresh_starts: bool = False) -> tuple[int, int, bool]:
        """(lanes per individual, episodes per lane, restart epochs) for an evaluation of ``episodes``."""
        if self.behaviour is Behaviour.EXECUTIVE:
            k = self.world_cfg.epoch_episodes  # one epoch per lane: the Executive is paid per epoch
            return -(-episodes // k), k, False
        k = 1 if fresh_starts else self.ga.lane_episodes
        return -(-episodes // k), k, True

    def evaluate(
        self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *, episodes: int | None = None,
        fresh_starts: bool | None = None,
    ) -> Evaluation:
        """Play ``policies`` against ``partners``; ``fresh_starts`` forces (or forbids) a fresh random
        placement for every episode, by default :meth:`fresh_starts` decides."""
        beh = self.behaviour
        for p in policies:
            if p.behaviour is not beh:
                raise ConfigError(f"cannot evaluate a {p.behaviour} rule set as {beh}")
        fresh = self.fresh_starts(partners) if fresh_starts is None else fresh_starts
        per, k, restart = self.layout(episodes or self.ga.episodes, fresh_starts=fresh)
        P = len(policies)
        L = P * per
        world = self._world(L)
        own = Rules(CompiledPolicies(policies), np.repeat(np.arange(P), per))
        if beh is Behaviour.EXECUTIVE:
            if partners.tracking is None or partners.docking is None:
                raise ConfigError("the Executive learns against Tracking and Docking rule sets; give both")
            executive: Trivial | Rules = own
            tracking = Rules.single(CompiledPolicies([partners.tracking]), L)
            docking = Rules.single(CompiledPolicies([partners.docking]), L)
        else:
            me = TASK_TRACK if beh is Behaviour.TRACKING else TASK_DOCK
            executive = Trivial(me) if partners.executive is None else Rules.single(CompiledPolicies([partners.executive]), L)
            sibling = partners.docking if beh is Behaviour.TRACKING else partners.tracking
            sib = Rules.single(CompiledPolicies([sibling]), L) if sibling is not None else None
            tracking, docking = (own, sib) if beh is Behaviour.TRACKING else (sib, own)
        out = run_lanes(
            world, lane_episodes=k, executive=executive, tracking=tracking, docking=docking,
            restart_epochs=restart, rng=rng, learner=beh, conflict=self.ga.conflict,
            scenarios=per if self.ga.common_scenarios else None, tick=self.tick,
        )
        fitness = np.zeros(P)
        count = np.zeros(P, dtype=np.int64)
        exps: list[Experience] = []
        for i in range(P):
            lanes = slice(i * per, (i + 1) * per)
            exp = self._experience(out, lanes, k)
            exps.append(exp)
            if beh is Behaviour.EXECUTIVE:
                sel = (out.epoch_lane >= i * per) & (out.epoch_lane < (i + 1) * per) & out.epoch_complete
                fitness[i] = out.epoch_payoff[sel].mean() if sel.any() else 0.0
                count[i] = out.played[lanes].sum()
            else:
                count[i] = exp.payoff.size
                fitness[i] = exp.payoff.mean() if exp.payoff.size else 0.0
        return Evaluation(fitness, count, exps, out)

    def _experience(self, out: Outcome, lanes: slice, k: int) -> Experience:
        """The per-episode record and decision log of the individual owning ``lanes``."""
        beh = self.behaviour
        if beh is Behaviour.EXECUTIVE:
            mine = out.played[lanes]
            e_id = out.epoch_of[lanes]
            payoff = np.where(mine, out.epoch_payoff[np.maximum(e_id, 0)], 0.0)
        else:
            role = TASK_TRACK if beh is Behaviour.TRACKING else TASK_DOCK
            mine = out.played[lanes] & (out.task[lanes] == role)
            payoff = out.payoff[lanes]
        epmap = np.full(mine.shape, -1, dtype=np.int64)  # (l, K) -> episode index
        epmap[mine] = np.arange(int(mine.sum()))
        tr = out.trace
        if beh is Behaviour.EXECUTIVE:
            rule = tr.rule[:, lanes]  # (K, l)
            ep = epmap.T
            bins, full = tr.bins[:, lanes], tr.full[:, lanes]
        else:
            rule = tr.rule[:, :, lanes]  # (K, T, l)
            ep = np.broadcast_to(epmap.T[:, None, :], rule.shape)
            bins, full = tr.bins[:, :, lanes], tr.full[:, :, lanes]
        sel = (rule >= 0) & (ep >= 0)
        return Experience(
            fired=out.fired[lanes][mine],
            payoff=payoff[mine],
            bins=bins[sel],
            rule=rule[sel].astype(np.int64),
            full=full[sel],
            episode=ep[sel],
            high_quantile=self.ga.high_payoff_quantile,
        )
