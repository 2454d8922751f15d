"""A deterministic lockstep run of the CEL architecture, and the experiments built on it.

:func:`run_cel` steps the architecture in lockstep *(ours; the live service runs the
two modules asynchronously)*: before any learning the execution module plays ``K``
trials with the initial rules (generation 0); then, per generation, the learning
module runs one GA generation on its model and hands over a new best if it found one,
the execution module plays ``K`` trials with the newest rules it has, and every
capability change its monitor reported is given to the learner, which restarts
before its next generation.  ``K`` = 100 *(ours)*: the external performance after
generation g (successes out of the last 100 trials) is then exactly generation g's
rules on 100 trials of the world, Figure 3's y-axis ("the number of times out of 100
that the robot succeeded").

Generation g's trials are trials ``[g K, (g + 1) K)``.  A schedule event at generation e
changes the world from trial ``e K`` on: generation e's point is the first after it (the
report: "at the beginning of generation 50, the three sonars fail.  The performance
then drops to 37 %"), played with rules learned on 50 generations of the old model,
and e - 1's the last before it.  A change the monitor reports during generation e's
trials reaches the learner before its generation e + 1.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from coevo.cel.casebase import CaseBase
from coevo.cel.execution import ExecutionModule, FailureSchedule, Stretch
from coevo.cel.learning import LearningModule
from coevo.cel.monitor import REPAIR_RUN, ZERO_RUN, Monitor
from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.tasks.door import default_ruleset, door_ga
from coevo.tasks.door.settings import SONARS, DoorConfig

__all__ = ["TRIALS_PER_GENERATION", "FIGURE3", "CYCLIC", "run_cel", "detection_delays", "recovery", "summarise",
           "zero_runs", "detection_decisions"]

TRIALS_PER_GENERATION = 100  # K (ours): see the module docstring
FAILED: tuple[str, ...] = ("front", "front_right", "right")  # report §7
#: Figure 3: all sonars for 50 generations, then front, front-right and right fail; 50 more.
FIGURE3: dict[str, Any] = {"generations": 100, "events": ((50, FAILED),)}
#: The cyclic schedule (ours): all sonars, failure, repair, the same failure again, 25 generations each.
CYCLIC: dict[str, Any] = {"generations": 100, "events": ((25, FAILED), (50, ()), (75, FAILED))}


def _row(g: int, ex: ExecutionModule, st: Stretch, learner: LearningModule, sim: float | None) -> dict[str, Any]:
    return {"generation": g, "external": st.performance, "simulated": sim, "rules_version": ex.version,
            "world_failed": list(ex.schedule.failed_at(st.first, ex.world.failed)),
            "learner_capabilities": list(learner.capabilities), **{k: round(v, 2) for k, v in st.rates().items()}}


def run_cel(seed: int, *, generations: int, events: Sequence[tuple[int, Sequence[str]]] = (),
            trials_per_generation: int = TRIALS_PER_GENERATION, world: DoorConfig | None = None,
            ga: GAConfig | None = None, case_base: bool | CaseBase = False, zero_run: int = ZERO_RUN,
            repair_run: int = REPAIR_RUN) -> dict[str, Any]:
    """One lockstep run (see the module docstring); the same arguments give the same numbers.

    Returns ``rows`` (one per generation 0..G: external performance, the learner's simulated success,
    the stretch's outcome rates and share of decisions not moving forward), ``changes`` (the monitor's
    verdicts, with the generation during whose trials each came and the first learner generation on the
    new model), ``detections`` (:func:`detection_delays`), the rules in use at each schedule event, and
    the seconds spent learning and executing.
    """
    if generations < 1:
        raise ConfigError(f"generations must be at least 1, got {generations}")
    world = world or DoorConfig()
    K = trials_per_generation
    schedule = FailureSchedule.at_generations(events, K)
    cases = case_base if isinstance(case_base, CaseBase) else (CaseBase() if case_base else None)
    learner = LearningModule(world, ga or door_ga(), seed=seed, case_base=cases)
    ex = ExecutionModule(world, default_ruleset(), seed=seed + 1_000_003, schedule=schedule,
                         monitor=Monitor(zero_run=zero_run, repair_run=repair_run, capabilities=world.capabilities))
    event_gens = {g for g, _ in events}
    rows: list[dict[str, Any]] = []
    changes: list[dict[str, Any]] = []
    at_event: dict[str, str] = {}
    t_learn = t_exec = 0.0
    stretches: list[Stretch] = []
    for g in range(generations + 1):
        sim = None
        if g > 0:
            t0 = time.perf_counter()
            step = learner.generation()
            t_learn += time.perf_counter() - t0
            sim = step.report.measures.get("success")
            if step.new_best is not None:
                ex.receive(step.new_best)
        if g in event_gens:
            at_event[str(g)] = format_ruleset(ex.rules)  # the rules that meet the change
        t0 = time.perf_counter()
        st = ex.run(K)
        t_exec += time.perf_counter() - t0
        stretches.append(st)
        rows.append(_row(g, ex, st, learner, sim))
        for c in st.changes:
            restarted = learner.set_capabilities(c.capabilities)
            changes.append({"trial": c.trial, "decision": c.decision, "generation": g, "capabilities": list(c.capabilities),
                            "learner_from": g + 1, "restarted": restarted})
    return {"seed": seed, "generations": generations, "trials_per_generation": K, "case_base": cases is not None,
            "events": [[g, list(f)] for g, f in events], "zero_run": zero_run, "repair_run": repair_run,
            "rows": rows, "changes": changes, "detections": detection_delays(schedule, stretches, changes, world),
            "rules_at_event": at_event, "final_rules": format_ruleset(ex.rules), "cases": len(cases) if cases is not None else 0,
            "seconds": {"learning": t_learn, "execution": t_exec}}


def detection_delays(schedule: FailureSchedule, stretches: list[Stretch], changes: list[dict[str, Any]],
                     world: DoorConfig) -> list[dict[str, Any]]:
    """For each schedule event: how long until the monitor's list matched the world's working sonars:
    trials (1 = during the first trial after the event), decisions, and generations (learner generations
    run on the wrong model after the event: 0 when the first generation after it already ran on the
    right one)."""
    per_trial = np.concatenate([s.trial_decisions for s in stretches])
    K = len(stretches[0].outcome) if stretches else 1
    out = []
    for start, failed in schedule.events:
        truth = [s for s in SONARS if s not in failed and s not in world.failed] if failed else list(world.capabilities)
        hit = next((c for c in changes if c["trial"] >= start and c["capabilities"] == truth), None)
        row: dict[str, Any] = {"trial": start, "generation": start // K, "failed": list(failed), "detected": hit is not None}
        if hit is not None:
            row.update(trials=hit["trial"] - start + 1,
                       decisions=int(per_trial[start:hit["trial"]].sum()) + hit["decision"] + 1,
                       generations=hit["learner_from"] - (start // K + 1))
        out.append(row)
    return out


def recovery(external: Sequence[float], event_generation: int, threshold: float) -> int | None:
    """Generations from a failure at ``event_generation`` until the external performance is back at
    ``threshold`` % or more: 0 when the failure's own generation (the old rules blinded) is already there,
    k when generation ``event_generation + k`` is the first; None if it never is."""
    return next((g - event_generation for g in range(event_generation, len(external)) if external[g] >= threshold),
                None)


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean and s.d. over runs of the external performance per generation, and the runs' detection delays."""
    ext = np.array([[r["external"] for r in run["rows"]] for run in runs])
    det = [d for run in runs for d in run["detections"]]
    found = [d for d in det if d["detected"]]
    return {"runs": len(runs), "external_mean": ext.mean(axis=0).round(2).tolist(),
            "external_sd": ext.std(axis=0, ddof=1 if len(runs) > 1 else 0).round(2).tolist(),
            "detected": f"{len(found)}/{len(det)}",
            "delay_trials": [d["trials"] for d in found], "delay_decisions": [d["decisions"] for d in found],
            "delay_generations": [d["generations"] for d in found]}


# ---------------------------------------------------------------- choosing the monitor's N
def _log(rules: RuleSet, world: DoorConfig, trials: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Readings ``(m, 7)``, forward flags and trial index of every decision of ``trials`` trials, in order."""
    log: list[tuple[np.ndarray, np.ndarray]] = []

    class _Recorder(Monitor):
        def observe_decisions(self, readings: np.ndarray, forward: np.ndarray) -> list[tuple[int, tuple[str, ...]]]:
            log.append((np.asarray(readings), np.asarray(forward)))
            return []

    ex = ExecutionModule(world, rules, seed=seed, monitor=_Recorder())
    st = ex.run(trials)
    return log[0][0], log[0][1], np.repeat(np.arange(trials), st.trial_decisions)


def zero_runs(rules: RuleSet, world: DoorConfig, *, trials: int, seed: int, zero: float = 0.0) -> np.ndarray:
    """For each trial and sonar, the longest run of zero readings while moving forward (a decision not
    moving forward pauses a run, a non-zero reading ends it: the monitor's count), as ``(trials, 7)``.
    Runs are counted within a trial here, to attribute them; the monitor's run on across trials."""
    reading, forward, trial = _log(rules, world, trials, seed)
    zero_m = reading <= zero
    best = np.zeros((trials, len(SONARS)), dtype=np.int64)
    run = np.zeros(len(SONARS), dtype=np.int64)
    prev = -1
    for i in range(len(reading)):
        if trial[i] != prev:
            run[:] = 0
            prev = trial[i]
        if forward[i]:
            run = np.where(zero_m[i], run + 1, 0)
        else:
            run[~zero_m[i]] = 0
        np.maximum(best[trial[i]], run, out=best[trial[i]])
    return best


def detection_decisions(rules: RuleSet, world: DoorConfig, *, zero_run: int, trials: int, seed: int
                        ) -> tuple[int | None, int | None]:
    """(trials, decisions) until a monitor with ``zero_run`` flags a sonar failed in ``world`` when
    ``rules`` drive from the first trial after the failure; (None, None) if it never does in ``trials``."""
    reading, forward, trial = _log(rules, world, trials, seed)
    mon = Monitor(zero_run=zero_run)
    for i in range(len(reading)):
        if mon.observe(reading[i], bool(forward[i])) is not None:
            return int(trial[i]) + 1, i + 1
    return None, None
