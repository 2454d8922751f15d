"""The fuel task's evaluator: a population of one behaviour against models of the other two.

The models of the partners are fixed rule sets for the duration of one evaluation
(best so far, in the report's regimes) or the trivial Executive that always picks
the learner.  All individuals of a population run in one batched world: individual
``i`` owns lanes ``[i*l, (i+1)*l)``.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga.operators import Experience
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.tasks.base import ChildRng, Evaluation, Evaluator, Partners, Tick
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK, Behaviour
from coevo.tasks.fuel.measures import measure
from coevo.tasks.fuel.runner import Outcome, Rules, Trace, Trivial, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld, compiled_loops

__all__ = ["FuelEvaluator"]


class FuelEvaluator(Evaluator):
    """Runs populations of ``behaviour`` in batched worlds (kept and reused per batch size).

    Partners: ``executive`` absent means the trivial Executive that always picks the
    learner; a Tracking or Docking learner's sibling absent means none (the trivial
    Executive never calls it).
    """

    def __init__(self, behaviour: Behaviour | str, world: WorldConfig, ga: GAConfig) -> None:
        self.behaviour = Behaviour(behaviour)
        self.world_cfg = world
        self.ga = ga
        self._worlds: dict[int, BatchWorld] = {}

    def _world(self, lanes: int) -> BatchWorld:
        """The batched world of ``lanes`` lanes: kept for this evaluator's later evaluations, and shared
        with the other evaluators of this thread (a worker's GA, a replay's, an experiment's many)."""
        if lanes not in self._worlds:
            self._worlds[lanes] = _shared_world(self.world_cfg, lanes)
        return self._worlds[lanes]


    def fresh_starts(self, partners: Partners) -> bool:
        """Does every episode start from a fresh random placement? Docking with the trivial
        Executive does (``WorldConfig.docking_fresh_starts``): that is where an Executive calls it."""
        return (self.behaviour == Behaviour.DOCKING and partners.get("executive") is None
                and self.world_cfg.docking_fresh_starts)

    def layout(self, episodes: int, *, fresh_starts: bool = False) -> tuple[int, int, bool]:
        """(lanes per individual, episodes per lane, restart epochs) for an evaluation of ``episodes``."""
        if self.behaviour == Behaviour.EXECUTIVE:
            k = self.world_cfg.epoch_episodes  # one epoch per lane: the Executive is paid per epoch
            return -(-episodes // k), k, False
        k = 1 if fresh_starts else self.ga.lane_episodes
        return -(-episodes // k), k, True

    def evaluate(
        self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *, episodes: int | None = None,
        tick: Tick | None = None, fresh_starts: bool | None = None,
    ) -> Evaluation:
        """Play ``policies`` against ``partners``; ``fresh_starts`` forces (or forbids) a fresh random
        placement for every episode, by default :meth:`fresh_starts` decides."""
        beh = self.behaviour
        for p in policies:
            if p.behaviour != beh:
                raise ConfigError(f"cannot evaluate a {p.behaviour} rule set as {beh}")
        fresh = self.fresh_starts(partners) if fresh_starts is None else fresh_starts
        per, k, restart = self.layout(episodes or self.ga.episodes, fresh_starts=fresh)
        P = len(policies)
        L = P * per
        world = self._world(L)
        own = Rules(CompiledPolicies(policies), np.repeat(np.arange(P), per))
        tracking: Rules | None
        docking: Rules | None
        if beh == Behaviour.EXECUTIVE:
            if partners.get("tracking") is None or partners.get("docking") is None:
                raise ConfigError("the Executive learns against Tracking and Docking rule sets; give both")
            executive: Trivial | Rules = own
            tracking = Rules.single(CompiledPolicies([partners["tracking"]]), L)
            docking = Rules.single(CompiledPolicies([partners["docking"]]), L)
        else:
            me = TASK_TRACK if beh == Behaviour.TRACKING else TASK_DOCK
            ex_rules = partners.get("executive")
            executive = Trivial(me) if ex_rules is None else Rules.single(CompiledPolicies([ex_rules]), L)
            sibling = partners.get("docking") if beh == Behaviour.TRACKING else partners.get("tracking")
            sib = Rules.single(CompiledPolicies([sibling]), L) if sibling is not None else None
            tracking, docking = (own, sib) if beh == Behaviour.TRACKING else (sib, own)
        out = run_lanes(
            world, lane_episodes=k, executive=executive, tracking=tracking, docking=docking,
            restart_epochs=restart, rng=rng, learner=beh, conflict=self.ga.conflict,
            scenarios=per if self.ga.common_scenarios else None, tick=tick,
        )
        fitness = np.zeros(P)
        count = np.zeros(P, dtype=np.int64)
        exps = self._experiences(out, P, per, k)
        for i, exp in enumerate(exps):
            lanes = slice(i * per, (i + 1) * per)
            if beh == Behaviour.EXECUTIVE:
                sel = (out.epoch_lane >= i * per) & (out.epoch_lane < (i + 1) * per) & out.epoch_complete
                fitness[i] = out.epoch_payoff[sel].mean() if sel.any() else 0.0
                count[i] = out.played[lanes].sum()
            else:
                count[i] = exp.payoff.size
                fitness[i] = exp.payoff.mean() if exp.payoff.size else 0.0
        return Evaluation(fitness, count, exps, out)

    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        """The report's measures of the best's re-evaluation, and Docking's own (docs/spec.md §1, "Where Docking
        learns"): % of fresh random starts it docks from (None for the other behaviours).

        Where the re-evaluation already played fresh starts (the trivial Executive) that is
        its docking rate; inside a learning Executive's epochs (Mutual) the best is played
        once more, alone, on ``best_episodes`` fresh starts.
        """
        m = measure(check.details, self.world_cfg.episode_steps)
        from_random = None
        if self.behaviour == Behaviour.DOCKING:
            if not self.fresh_starts(partners):
                check = self.evaluate([best], {}, child_rng(), episodes=self.ga.best_episodes, fresh_starts=True)
            from_random = measure(check.details, self.world_cfg.episode_steps).docking_success_rate
        return {
            "quality_tracking": m.quality_tracking, "successful_docking": m.successful_docking,
            "dock_choice": m.dock_choice, "docking_success_rate": m.docking_success_rate,
            "average_epoch_length": m.average_epoch_length, "docking_from_random": from_random,
        }

    def _experiences(self, out: Outcome, P: int, per: int, k: int) -> list[Experience]:
        """:meth:`_experience` of every individual: for a Tracking or Docking learner once numba is loaded, in
        one compiled pass over the whole run (:func:`.kernels.experiences`: the same arrays; its decision logs
        hold a row per step, ~230,000 at the report's size), not ~20 numpy calls per individual."""
        kernels = None if self.behaviour == Behaviour.EXECUTIVE else compiled_loops(out.played.shape[0])
        if kernels is None:
            return [self._experience(out, slice(i * per, (i + 1) * per), k) for i in range(P)]
        mine = out.played & (out.task == (TASK_TRACK if self.behaviour == Behaviour.TRACKING else TASK_DOCK))
        tr = _trace(out)
        e, fired, payoff, d, bins, rule, full, episode = kernels.experiences(per, mine, out.fired, out.payoff, tr.rule,
                                                                             tr.bins, tr.full)
        q = self.ga.high_payoff_quantile
        return [Experience(fired=fired[e[i]:e[i + 1]], payoff=payoff[e[i]:e[i + 1]], bins=bins[d[i]:d[i + 1]],
                           rule=rule[d[i]:d[i + 1]], full=full[d[i]:d[i + 1]], episode=episode[d[i]:d[i + 1]],
                           high_quantile=q) for i in range(P)]

    def _experience(self, out: Outcome, lanes: slice, k: int) -> Experience:
        """The per-episode record and decision log of the individual owning ``lanes``."""
        beh = self.behaviour
        if beh == Behaviour.EXECUTIVE:
            mine = out.played[lanes]
            e_id = out.epoch_of[lanes]
            payoff = np.where(mine, out.epoch_payoff[np.maximum(e_id, 0)], 0.0)
        else:
            role = TASK_TRACK if beh == Behaviour.TRACKING else TASK_DOCK
            mine = out.played[lanes] & (out.task[lanes] == role)
            payoff = out.payoff[lanes]
        epmap = np.full(mine.shape, -1, dtype=np.int64)  # (l, K) -> episode index
        epmap[mine] = np.arange(int(mine.sum()))
        tr = _trace(out)
        if beh == Behaviour.EXECUTIVE:
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


def _trace(out: Outcome) -> Trace:
    """The learner's decisions in ``out``: a run without a learner has none to learn from."""
    if out.trace is None:
        raise ConfigError("this outcome holds no learner's decisions: run_lanes was given no learner")
    return out.trace


# Worlds by (thread, settings, lanes), the most recently used last.  A world carries nothing from one
# run_lanes to the next (every run places every lane afresh), so any evaluator of the same thread may
# reuse it; building one costs ~0.15 s per 4500 lanes (22 500 pymunk shapes), keeping one ~26 MB.
_SHARED: OrderedDict[tuple[int, str, int], BatchWorld] = OrderedDict()
_SHARED_MAX = 4  # a GA uses two or three sizes: its population's, the best's, a fresh-start probe's


def _shared_world(cfg: WorldConfig, lanes: int) -> BatchWorld:
    key = (threading.get_ident(), cfg.model_dump_json(), lanes)
    world = _SHARED.pop(key, None)
    if world is None:
        world = BatchWorld(cfg, lanes)
    _SHARED[key] = world
    while len(_SHARED) > _SHARED_MAX:
        _SHARED.popitem(last=False)
    return world
