"""The generational GA of one behaviour: evaluate, learn strengths, select, recombine, mutate.

One :meth:`GA.generation` call is one generation of the report's GA (Appendix A
§6.2): every individual is evaluated on ``episodes`` episodes against the current
partner models; rule strengths are updated from the payoffs (Lamarckian: offspring
inherit them); the generation's best is re-evaluated on ``best_episodes`` episodes
for the learning curve; the best so far is kept; the next population is bred.

The GA names no task: its problem (:class:`~coevo.ga.problem.Problem`, a task) gives it the
behaviour's initial rules and an evaluator.  The partner models are an argument of
every generation, so an asynchronous worker can swap in new partner policies
between generations without the GA knowing; so is the tick a worker's heartbeat
hangs on.

The mutation model (``GAConfig.mutation_model``, see :mod:`coevo.ga.mutation`) may
give every individual a 3-bit control gene: ``GA.genes[i]`` (uint8, 0..7) belongs to
``GA.population[i]`` and travels with it through breeding (all zeros under FM and FH).
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, TypeVar

import numpy as np
from pydantic import BaseModel

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga.evaluator import Evaluation, Mixture, Partners, Tick, pooled
from coevo.ga.mutation import CONTROL_LEVELS, MutationModel, model_from_config
from coevo.ga.operators import Experience, cover, crossover, delete, generalise, select_parents, specialise, split, trim
from coevo.ga.problem import Problem, check_behaviour, ga_settings
from coevo.ga.symmetry import MirroredEvaluator, with_mirror_images
from coevo.policy.rules import RuleSet, random_ruleset
from coevo.policy.schema import schema
from coevo.policy.strength import update_strengths

__all__ = ["GA", "GenerationReport"]

W = TypeVar("W", bound=BaseModel)  # the world settings of the GA's problem


@dataclass(frozen=True)
class GenerationReport:
    """One point of the learning curve."""

    generation: int  # 1-based
    best_fitness: float  # this generation's best, re-evaluated on best_episodes
    population_best: float  # its fitness in the population evaluation
    population_mean: float
    best_so_far: float  # the best re-evaluated fitness so far
    improved: bool  # the best so far changed this generation
    starved: int  # individuals that controlled no episode at all
    measures: dict[str, float | None]  # the task's measures of the generation's best (its re-evaluation)
    seconds: float

    def as_dict(self) -> dict[str, float | int | bool | None]:
        """One row of the learning curve: the GA's columns, the task's measures, the time."""
        d = asdict(self)
        return {**{k: v for k, v in d.items() if k not in ("measures", "seconds")}, **self.measures,
                "seconds": self.seconds}


class GA:
    """A population of rule sets for one behaviour and its generational loop."""

    def __init__(
        self,
        task: Problem[W],
        behaviour: str,
        *,
        world: W,
        ga: GAConfig,
        seed: int,
        mutation: MutationModel | None = None,
        seed_policy: RuleSet | None = None,
    ) -> None:
        self.task: Problem[Any] = task
        self.behaviour = check_behaviour(task, behaviour)
        self.world_cfg: BaseModel = world
        self.cfg = ga = ga_settings(task, self.behaviour, ga)  # the settings left to the task, filled in
        if ga.max_rules is None:
            raise ConfigError(f"the task left max_rules unset for {self.behaviour}: its ga_choices must not set it to None")
        self.max_rules: int = ga.max_rules
        self.rng = np.random.default_rng(seed)
        self.mutation = mutation or model_from_config(ga)
        self.evaluator = task.evaluator(self.behaviour, world, ga)
        if ga.symmetric_rules:  # each rule also stands for its mirror image (coevo.ga.symmetry)
            self.evaluator = MirroredEvaluator(self.evaluator)
        learnable = task.learnable_sensors(self.behaviour, world)
        self._unusable = None if learnable is None or learnable.all() else ~learnable
        self._use = None if self._unusable is None else ~self._unusable  # operators draw only over these sensors
        self._full_hi = np.array([s.bins - 1 for s in schema(self.behaviour).sensors])
        if seed_policy is None and ga.initial == "default":
            seed_policy = task.initial_rules(self.behaviour, world)  # None where the behaviour starts random
        if seed_policy is not None:
            if seed_policy.behaviour != self.behaviour:
                raise ConfigError(f"seed policy is a {seed_policy.behaviour} rule set, not {self.behaviour}")
            self.population = self._seeded(trim(seed_policy, self.max_rules))
        else:
            self.population = [self._usable(random_ruleset(self.behaviour, ga.initial_rules, self.rng, self._use))
                               for _ in range(ga.population)]
        self.genes = self._random_genes(ga.population)  # control gene of population[i]; zeros if the model has none
        self.generation_no = 0
        self.best: RuleSet | None = None
        self.current: RuleSet | None = None  # the last generation's best individual (strengths learned)
        self.current_fitness = 0.0
        self.best_fitness = -np.inf
        self.candidates: list[tuple[RuleSet, float, int]] = []  # (policy, sum of its re-evaluations, how many)
        # The candidates' re-evaluations draw from a stream of their own: the run's learning is the same with or without.
        self.evidence_rng = np.random.default_rng([seed, 1])
        self.last: Evaluation | None = None

    def played(self, rs: RuleSet) -> RuleSet:
        """``rs`` (one of this GA's individuals, its ``best`` or ``current``) as it is played: what to publish and
        write for everyone else to read as a plain rule set (with its mirror images if the rules are symmetric)."""
        return with_mirror_images(rs) if self.cfg.symmetric_rules else rs

    def best_rules(self) -> RuleSet:
        """``best`` once a generation has run; before, a RuntimeError (a caller's bug: GAConfig allows no fewer than
        one generation)."""
        if self.best is None:
            raise RuntimeError("no generation ran: the GA has no best rules yet")
        return self.best

    # ------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, Any]:
        """Everything the next generation depends on, as plain data (msgpack/JSON-able).

        A GA loaded from it with :meth:`load_state` breeds, evaluates and reports
        exactly as this one would have: the population with its learned strengths,
        the control genes, the best and current policies and the generator's state.
        """
        return {
            "generation": self.generation_no,
            "population": [p.to_dict() for p in self.population],
            "genes": self.genes.tolist(),
            "rng": json.dumps(self.rng.bit_generator.state),  # 128-bit integers: JSON keeps them exact
            "best": None if self.best is None else self.best.to_dict(),
            "best_fitness": float(self.best_fitness),
            "current": None if self.current is None else self.current.to_dict(),
            "current_fitness": float(self.current_fitness),
            "candidates": [[rs.to_dict(), total, n] for rs, total, n in self.candidates],
            "evidence_rng": json.dumps(self.evidence_rng.bit_generator.state),
        }

    def load_state(self, state: dict[str, Any]) -> None:
        """Continue from :meth:`state_dict` of a GA with the same behaviour and settings."""
        population = [RuleSet.from_dict(d) for d in state["population"]]
        if len(population) != self.cfg.population or any(p.behaviour != self.behaviour for p in population):
            raise ConfigError(f"checkpointed population ({len(population)} rule sets) does not fit a "
                              f"{self.behaviour} GA of population {self.cfg.population}")
        longest = max(len(p) for p in population)
        if longest > self.max_rules:  # e.g. a Docking run checkpointed before its rules became symmetric
            raise ConfigError(f"checkpointed {self.behaviour} policies hold up to {longest} rules, more than this GA's "
                              f"max_rules={self.max_rules}; resume it with the settings it was started with")
        self.population = population
        self.genes = np.asarray(state["genes"], dtype=np.uint8)
        self.rng.bit_generator.state = json.loads(state["rng"])
        self.generation_no = int(state["generation"])
        self.best = None if state["best"] is None else RuleSet.from_dict(state["best"])
        self.best_fitness = float(state["best_fitness"])
        self.current = None if state["current"] is None else RuleSet.from_dict(state["current"])
        self.current_fitness = float(state["current_fitness"])
        self.candidates = [(RuleSet.from_dict(d), float(t), int(n)) for d, t, n in state.get("candidates", [])]
        if "evidence_rng" in state:
            self.evidence_rng.bit_generator.state = json.loads(state["evidence_rng"])

    def replace(self, indices: Sequence[int], policies: Sequence[RuleSet]) -> None:
        """Put ``policies[k]`` in place of individual ``indices[k]`` (e.g. a restart on a changed world,
        :mod:`coevo.cel.learning`); each newcomer gets a fresh control gene (zero under FM and FH)."""
        idx = [int(i) for i in indices]
        n = len(self.population)
        if len(idx) != len(policies):
            raise ConfigError(f"replace: {len(idx)} indices for {len(policies)} policies")
        if len(set(idx)) != len(idx) or any(not 0 <= i < n for i in idx):
            raise ConfigError(f"replace: indices must be distinct and in [0, {n}), got {idx}")
        for p in policies:
            if p.behaviour != self.behaviour:
                raise ConfigError(f"replace: a {p.behaviour} rule set cannot join a {self.behaviour} population")
        for i, p in zip(idx, policies):
            self.population[i] = trim(p, self.max_rules)
        self.genes[idx] = self._random_genes(len(idx))

    def _seeded(self, seed_policy: RuleSet) -> list[RuleSet]:
        """The initial population from a seed policy: the policy itself, then mutated copies (each with
        ``seed_random_rules`` random rules in front) and a ``seed_random_share`` of random rule sets."""
        cfg, rng = self.cfg, self.rng
        n_random = int(round(cfg.seed_random_share * (cfg.population - 1)))
        out = [self._usable(seed_policy)]
        for _ in range(cfg.population - 1 - n_random):
            child = self._mutate(seed_policy, 0)
            if cfg.seed_random_rules:
                extra = random_ruleset(self.behaviour, cfg.seed_random_rules, rng, self._use)
                child = trim(RuleSet.concat(self.behaviour, [extra, child]), self.max_rules)
            out.append(self._usable(child))
        out += [self._usable(random_ruleset(self.behaviour, cfg.initial_rules, rng, self._use)) for _ in range(n_random)]
        return out

    def _mutate(self, rs: RuleSet, generation: int, gene: int = 0) -> RuleSet:
        if self._use is None:  # any mutation model; with a sensor set, the built-in ones (coevo.ga.mutation)
            return self.mutation.mutate(rs, self.rng, generation=generation, gene=gene)
        return self.mutation.mutate(rs, self.rng, generation=generation, gene=gene, usable=self._use)  # type: ignore[call-arg]

    def _usable(self, rs: RuleSet) -> RuleSet:
        """``rs`` with every condition on a sensor the task does not let this GA use widened to ANY."""
        if self._unusable is None:
            return rs
        u = self._unusable
        if not ((rs.lo[:, u] != 0) | (rs.hi[:, u] != self._full_hi[u])).any():
            return rs
        return rs.replace(lo=np.where(u, 0, rs.lo), hi=np.where(u, self._full_hi, rs.hi))

    def _random_genes(self, n: int) -> np.ndarray:
        if not self.mutation.controlled:
            return np.zeros(n, dtype=np.uint8)
        return self.rng.integers(CONTROL_LEVELS, size=n).astype(np.uint8)

    def _child_rng(self) -> np.random.Generator:
        return np.random.default_rng(int(self.rng.integers(2**63)))

    def generation(self, partners: Partners, *, tick: Tick | None = None, mixture: Mixture | None = None) -> GenerationReport:
        """Run one generation against ``partners`` and breed the next population; ``tick`` is
        called between episode rounds of the population's evaluation (a worker's heartbeat).  With ``mixture``
        the population plays each of its partner sets for its episodes instead (:func:`~coevo.ga.evaluator.pooled`);
        the best's re-evaluation and measures are still against ``partners``."""
        t0 = time.perf_counter()
        cfg = self.cfg
        if mixture is None:
            ev = self.evaluator.evaluate(self.population, partners, self._child_rng(), tick=tick)
        else:
            ev = pooled([self.evaluator.evaluate(self.population, p, self._child_rng(), episodes=n, tick=tick)
                         for p, n in mixture])
        self.last = ev
        learned = [
            update_strengths(p, e.fired, e.payoff, cfg.strength_rate) for p, e in zip(self.population, ev.experience)
        ]
        top = int(np.argmax(ev.fitness))
        # keep_evaluated: the policy selected is the one whose fitness was measured, strengths and all.
        chosen = self.population[top] if self.cfg.keep_evaluated else learned[top]
        self.current, self.current_fitness = chosen, float(ev.fitness[top])
        check = self.evaluator.evaluate([chosen], partners, self._child_rng(), episodes=cfg.best_episodes)
        best_fit = float(check.fitness[0])
        if self.cfg.best_candidates:
            improved = self._pool_evidence(chosen, best_fit, partners)
        else:
            improved = best_fit > self.best_fitness
            if improved:
                self.best, self.best_fitness = chosen, best_fit
        measures = self.evaluator.measures(chosen, partners, check, self._child_rng)
        self.generation_no += 1
        elite_pool = self.population if self.cfg.keep_evaluated else learned
        self.population, self.genes = self._breed(learned, ev.fitness, ev.experience, elite_pool)
        return GenerationReport(
            generation=self.generation_no,
            best_fitness=best_fit,
            population_best=float(ev.fitness[top]),
            population_mean=float(ev.fitness.mean()),
            best_so_far=float(self.best_fitness),
            improved=improved,
            starved=int((ev.episodes == 0).sum()),
            measures=measures,
            seconds=time.perf_counter() - t0,
        )

    def _pool_evidence(self, chosen: RuleSet, fit: float, partners: Partners) -> bool:
        """Best so far by all the evidence (``best_candidates`` > 0, see :func:`~coevo.ga.problem.ga_settings`): the candidates (the best
        few policies chosen so far) are re-evaluated every generation and judged by the mean of all their
        re-evaluations, so one lucky re-evaluation of ``best_episodes`` no longer makes a policy the best for good.
        True if the best changed."""
        cfg = self.cfg
        pool = {rs: [total, n] for rs, total, n in self.candidates}
        record = pool.setdefault(chosen, [0.0, 0])
        record[0] += fit
        record[1] += 1
        for rs, rec in pool.items():
            if rs is not chosen and rs != chosen:
                rng = np.random.default_rng(int(self.evidence_rng.integers(2**63)))
                again = self.evaluator.evaluate([rs], partners, rng, episodes=cfg.best_episodes)
                rec[0] += float(again.fitness[0])
                rec[1] += 1
        ranked = sorted(pool.items(), key=lambda kv: -kv[1][0] / kv[1][1])[: self.cfg.best_candidates]
        self.candidates = [(rs, total, int(n)) for rs, (total, n) in ranked]
        top, (total, n) = ranked[0]
        changed = self.best is None or top != self.best
        self.best, self.best_fitness = top, total / n
        return changed

    def _breed(
        self, pop: list[RuleSet], fitness: np.ndarray, exps: list[Experience], elite_pool: list[RuleSet] | None = None,
    ) -> tuple[list[RuleSet], np.ndarray]:
        cfg, rng = self.cfg, self.rng
        order = np.argsort(-fitness, kind="stable")
        children: list[RuleSet] = [(elite_pool or pop)[i] for i in order[: cfg.elite]]
        genes: list[int] = [int(self.genes[i]) for i in order[: cfg.elite]]
        inherited = list(genes)  # before mutation: what GH's hypermutation chance is read from
        parents = select_parents(fitness, cfg.parents_fraction, rng)
        while len(children) < cfg.population:
            for i in parents:
                others = parents[parents != i]
                j = int(rng.choice(others)) if others.size else int(i)
                if rng.random() < cfg.crossover_rate:
                    pair: tuple[tuple[RuleSet, np.ndarray], ...] = crossover(pop[i], exps[i], pop[j], exps[j], rng)
                else:
                    pair = tuple((pop[x], ~exps[x].fired_rules(len(pop[x]))) for x in (i, j))
                for (child, idle), src in zip(pair, (i, j)):
                    gene = int(self.genes[src])
                    children.append(self._vary(child, idle, pop[src], exps[src], gene))
                    inherited.append(gene)
                    genes.append(self.mutation.mutate_gene(gene, rng))
                if len(children) >= cfg.population:
                    break
        children, gene_arr = children[: cfg.population], np.array(genes[: cfg.population], dtype=np.uint8)
        hyper = self.mutation.hypermutants(np.array(inherited[cfg.elite : cfg.population], dtype=np.uint8), rng)
        if hyper is not None:
            for k in np.flatnonzero(hyper) + cfg.elite:
                children[k] = self._usable(random_ruleset(self.behaviour, cfg.initial_rules, rng, self._use))
            gene_arr[cfg.elite :][hyper] = self._random_genes(int(hyper.sum()))
        return children, gene_arr

    def _vary(self, child: RuleSet, idle: np.ndarray, parent: RuleSet, exp: Experience, gene: int = 0) -> RuleSet:
        """Lamarckian operators from the parent's experience, then mutation, then the size cap."""
        cfg, rng = self.cfg, self.rng
        extra: list[RuleSet] = []
        if rng.random() < cfg.delete_rate:
            child, idle = delete(child, idle)
        if rng.random() < cfg.specialise_rate:
            r = specialise(parent, exp, rng, low_strength=cfg.low_strength, fraction=cfg.specialise_fraction,
                           recency=cfg.specialise_recency, usable=self._use)
            if r is not None:
                extra.append(r)
        if rng.random() < cfg.generalise_rate:
            extra.append(generalise(parent, exp, rng, self._use))
        if rng.random() < cfg.cover_rate:
            r = cover(parent, exp, rng, partial=cfg.cover_partial)
            if r is not None:
                extra.append(r)
        if cfg.split_rate and rng.random() < cfg.split_rate:
            got = split(parent, exp, rng, self._use)
            if got is not None:
                child, narrowed = _narrow_in(child, parent, *got)
                extra += narrowed
        if extra:
            child = RuleSet.concat(child.behaviour, [child, *extra])
        child = self._mutate(child, self.generation_no, gene)
        return self._usable(trim(child, self.max_rules))


def _narrow_in(child: RuleSet, parent: RuleSet, r: int, narrowed: RuleSet) -> tuple[RuleSet, list[RuleSet]]:
    """``child`` with its copies of ``parent``'s rule ``r`` narrowed (:func:`~coevo.ga.operators.split`) in place,
    or unchanged with ``[narrowed]`` to add where crossover left it none."""
    same = ((child.lo == parent.lo[r]).all(axis=1) & (child.hi == parent.hi[r]).all(axis=1)
            & (child.action == parent.action[r]).all(axis=1))
    if not same.any():
        return child, [narrowed]
    lo, hi, strength = child.lo.copy(), child.hi.copy(), child.strength.copy()
    lo[same], hi[same], strength[same] = narrowed.lo[0], narrowed.hi[0], narrowed.strength[0]
    return child.replace(lo=lo, hi=hi, strength=strength), []
