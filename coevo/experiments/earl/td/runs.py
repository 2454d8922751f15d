"""The runs: Q-learning on a task's lanes, the GA with its experience counted, and one task's comparison."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np
from pydantic import BaseModel

from coevo.errors import ConfigError
from coevo.experiments.earl.td.encoders import ENCODERS, Encoder
from coevo.experiments.earl.td.envs import make_env
from coevo.experiments.earl.td.measures import (
    MEASURE_NAMES,
    measure_policy,
    rules_policy,
)
from coevo.experiments.earl.td.qtable import HashedQ
from coevo.experiments.earl.td.spec import (
    VARIANTS,
    Curve,
    Policy,
    Progress,
    TDSpec,
    no_progress,
)
from coevo.ga.evaluator import ChildRng, Evaluation, Evaluator, Partners, Tick
from coevo.policy.rules import RuleSet

__all__ = ["run_td", "CountingEvaluator", "robot_steps_of", "run_ga", "variant_specs", "checkpoint_marks", "task_results", "run_task"]


def _prior(task: str, prior: str) -> Policy | None:
    """The default rules as a policy on any lanes (``prior='default'``), else None."""
    if prior == "none":
        return None
    if task == "door":
        from coevo.tasks.door import default_ruleset as door_default

        rules: RuleSet | None = door_default()
    else:
        from coevo.tasks.fuel import default_ruleset

        rules = default_ruleset(task)
    if rules is None:
        raise ConfigError(f"prior='default': the {task} task has no default rules")
    one = rules_policy([rules], 1)
    return lambda bins, lanes, rng: one(bins, np.zeros(len(bins), dtype=np.int64), rng)


def _td_policy(learner: HashedQ, encoder: Encoder, trials: int, prior: Policy | None) -> Policy:
    def policy(bins: np.ndarray, lanes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        rows = learner.rows(lanes // trials, encoder.code(bins), allocate=False)
        fallback = None if prior is None else prior(bins, lanes, rng)
        return learner.act(rows, rng, explore=False, fallback=fallback)

    return policy


class _Distinct:
    """Distinct observation codes met per run: buffered, merged (sorted, unique) when counted."""

    def __init__(self, runs: int) -> None:
        self.known = [np.zeros(0, dtype=np.int64) for _ in range(runs)]
        self.buffer: list[tuple[np.ndarray, np.ndarray]] = []

    def add(self, run: np.ndarray, codes: np.ndarray) -> None:
        self.buffer.append((run.astype(np.int16), codes))

    def counts(self) -> list[int]:
        if self.buffer:
            run = np.concatenate([b[0] for b in self.buffer])
            codes = np.concatenate([b[1] for b in self.buffer])
            self.buffer = []
            for r in range(len(self.known)):
                self.known[r] = np.union1d(self.known[r], codes[run == r])
        return [int(k.size) for k in self.known]


def run_td(spec: TDSpec, checkpoint_steps: list[int], *, progress: Progress = no_progress) -> list[Curve]:
    """``spec.seeds`` TD runs on one batched world, measured when their robot-steps pass each checkpoint."""
    enc = ENCODERS[(spec.task, spec.encoder)]
    R, M = spec.seeds, spec.lanes
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, 19, 3]))
    measure_rng = np.random.default_rng(np.random.SeedSequence([spec.seed, 19, 4]))
    env = make_env(spec.task, R * M, rng, reward=spec.reward)
    learner = HashedQ(R, env.n_actions, spec.q_config, max_rows=spec.max_rows)
    run_of_lane = np.arange(R * M) // M
    curves = [Curve("td", spec.seed + r, extra={"table": []}) for r in range(R)]
    steps = np.zeros(R, dtype=np.int64)
    budget = checkpoint_steps[-1]
    todo = list(checkpoint_steps)
    t0 = time.perf_counter()
    full = ENCODERS[(spec.task, "full")]
    seen = _Distinct(R)  # what a table over every sensor at the schema's bins would have grown to
    bins = env.bins()
    rows = learner.rows(run_of_lane, enc.code(bins))
    prior = _prior(spec.task, spec.prior)
    lanes = np.arange(R * M)
    while todo:
        act = learner.act(rows, rng, fallback=None if prior is None else prior(bins, lanes, rng))
        was = env.active.copy()
        seen.add(run_of_lane[was], full.code(bins[was]))
        reward, done = env.step(act, rng)
        bins = env.bins()
        nxt = learner.rows(run_of_lane, enc.code(bins))
        learner.update(rows[was], act[was], reward[was], nxt[was], done[was])
        steps += np.bincount(run_of_lane[was], minlength=R)
        rows = nxt
        if steps.min() >= todo[0]:
            todo.pop(0)
            full_sizes = seen.counts()
            got = measure_policy(spec.task, _td_policy(learner, enc, spec.measure_trials, prior), groups=R,
                                 trials=spec.measure_trials, rng=measure_rng)
            sizes = learner.table_sizes()
            for r, c in enumerate(curves):
                c.robot_steps.append(int(steps[r]))
                c.measure.append(float(got[r]))
                c.extra["table"].append({**sizes[r], "full_observations": full_sizes[r]})
            progress(f"{spec.task}: TD", int(steps.min()), budget)
    seconds = time.perf_counter() - t0
    for c in curves:
        c.seconds = seconds / R  # one batched world for all runs: each run's share
        c.extra["overflow"] = learner.overflow
    return curves


class CountingEvaluator(Evaluator):
    """Wraps a task's evaluator and counts the robot-steps of every evaluation the GA asks for."""

    def __init__(self, inner: Evaluator) -> None:
        self.inner = inner
        self.behaviour = inner.behaviour
        self.robot_steps = 0

    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        ev = self.inner.evaluate(policies, partners, rng, episodes=episodes, tick=tick)
        self.robot_steps += robot_steps_of(ev.details)
        return ev

    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        return self.inner.measures(best, partners, check, child_rng)


def robot_steps_of(details: Any) -> int:
    """Robot-steps an evaluation played: the fuel runner's per-episode steps, or the door's decisions."""
    if hasattr(details, "steps") and hasattr(details, "played"):  # coevo.tasks.fuel.runner.Outcome
        return int(np.asarray(details.steps).sum())
    if hasattr(details, "lane") and hasattr(details, "outcome"):  # coevo.tasks.door.evaluate.Played
        return int(len(details.lane))
    raise ConfigError(f"cannot count the robot-steps of a {type(details).__name__} evaluation")


def run_ga(spec: TDSpec, seed: int, *, progress: Progress = no_progress) -> Curve:
    """The GA on the task (report settings; ``coevo learn``'s), its best so far measured at the checkpoints."""
    from coevo.config import GAConfig, build
    from coevo.ga import GA
    from coevo.tasks import get_task

    if spec.task == "door":
        from coevo.tasks.door import DoorConfig, door_ga

        world: BaseModel = DoorConfig()
        task, behaviour = get_task("door"), "door"
        ga_cfg = door_ga(generations=spec.generations, population=spec.population, episodes=spec.episodes)
    else:
        from coevo.tasks.fuel.settings import WorldConfig

        task, behaviour, world = get_task("fuel"), spec.task, WorldConfig()
        ga_cfg = build(GAConfig, generations=spec.generations, population=spec.population, episodes=spec.episodes)
    ga = GA(task, behaviour, world=world, ga=ga_cfg, seed=seed)
    counter = CountingEvaluator(ga.evaluator)
    ga.evaluator = counter
    measure_rng = np.random.default_rng(np.random.SeedSequence([seed, 19, 5]))
    curve = Curve("ga", seed, extra={"rules": []})
    learn_seconds = 0.0
    for g in range(1, spec.generations + 1):
        t0 = time.perf_counter()
        ga.generation({})
        learn_seconds += time.perf_counter() - t0
        if g in spec.marks:
            trials, best = spec.measure_trials, ga.played(ga.best_rules())
            got = measure_policy(spec.task, rules_policy([best], trials, conflict=ga_cfg.conflict), groups=1,
                                 trials=trials, rng=measure_rng)
            curve.robot_steps.append(counter.robot_steps)
            curve.measure.append(float(got[0]))
            curve.extra["rules"].append(len(best))
        progress(f"{spec.task}: GA seed {seed}", g, spec.generations)
    curve.seconds = learn_seconds
    return curve




def variant_specs(spec: TDSpec, variants: tuple[str, ...]) -> dict[str, TDSpec]:
    """The TD spec of each extra run in ``variants`` (a ConfigError naming one the task does not have)."""
    specs = {}
    for v in variants:
        if v not in VARIANTS:
            raise ConfigError(f"variant {v!r}: choose from {', '.join(VARIANTS)}")
        specs[v] = replace(spec, **VARIANTS[v])  # raises where the task has no such setting
    return specs


def checkpoint_marks(spec: TDSpec, ga_steps: list[list[int]]) -> list[int]:
    """The TD runs' checkpoints: the GA runs' mean robot-steps at each (scaled to ``td_steps`` if given)."""
    marks = np.mean(ga_steps, axis=0)
    if spec.td_steps is not None:
        marks = marks * (spec.td_steps / marks[-1])
    return [max(1, int(round(m))) for m in marks]


def task_results(spec: TDSpec, marks: list[int], ga: list[dict[str, Any]], td: list[dict[str, Any]],
                 variants: dict[str, list[dict[str, Any]]], seconds: dict[str, float]) -> dict[str, Any]:
    """One task's results as plain data (what the report reads), from its runs' curves."""
    enc = ENCODERS[(spec.task, spec.encoder)]
    return {
        "task": spec.task, "measure": MEASURE_NAMES[spec.task], "spec": spec.as_dict(),
        "encoder": {"name": enc.name, "sensors": enc.describe(), "dense_observations": float(enc.n_states),
                    "actions": 56 if spec.task == "door" else 78},
        "checkpoint_steps": marks, "ga": ga, "td": td, "variants": variants, "seconds": seconds,
    }


def run_task(spec: TDSpec, *, variants: tuple[str, ...] = (), progress: Progress = no_progress) -> dict[str, Any]:
    """The GA's runs, then the TD runs at the GA's mean robot-steps per checkpoint, then a TD run per
    extra reward in ``variants`` (e.g. Tracking's ``shaped``); results as plain data, in this process
    (``coevo td-baseline`` runs the same pieces as replicates: :mod:`.replicates`)."""
    specs = variant_specs(spec, variants)
    t0 = time.perf_counter()
    ga = [run_ga(spec, spec.seed + i, progress=progress) for i in range(spec.seeds)]
    t1 = time.perf_counter()
    marks = checkpoint_marks(spec, [c.robot_steps for c in ga])
    td = run_td(spec, marks, progress=progress)
    t2 = time.perf_counter()
    extra = {v: [c.as_dict() for c in run_td(vs, marks, progress=progress)] for v, vs in specs.items()}
    t3 = time.perf_counter()
    return task_results(spec, marks, [c.as_dict() for c in ga], [c.as_dict() for c in td], extra,
                        {"ga": t1 - t0, "td": t2 - t1, "variants": t3 - t2})
