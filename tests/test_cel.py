"""Continuous and Embedded Learning, in process: the monitor, the case base, the execution and learning
modules, and the lockstep run's determinism."""

from __future__ import annotations

import numpy as np
import pytest

from coevo.cel import CaseBase, ExecutionModule, FailureSchedule, LearningModule, Monitor, distance
from coevo.cel.experiment import recovery, run_cel
from coevo.cel.monitor import REPAIR_RUN, ZERO_RUN
from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.policy.rules import random_ruleset
from coevo.tasks.door import DOOR, DoorConfig, default_ruleset
from coevo.tasks.door.settings import SONARS

TINY_GA = GAConfig(population=10, episodes=12, best_episodes=20)
FAILED = ("front", "front_right", "right")
FRONT = SONARS.index("front")


def without(*failed: str) -> tuple[str, ...]:
    return tuple(s for s in SONARS if s not in failed)


# ------------------------------------------------------------------ the monitor
def test_monitor_flags_a_failed_front_sonar_after_n_forward_zeros_and_not_before() -> None:
    mon = Monitor()
    reading = np.full(7, 50.0)
    reading[FRONT] = 0.0
    for _ in range(ZERO_RUN - 1):
        assert mon.observe(reading, forward=True) is None
        assert mon.observe(reading, forward=False) is None  # standing still neither counts nor resets
    assert mon.observe(reading, forward=True) == without("front")
    assert mon.observe(reading, forward=True) is None  # reported once


def test_monitor_a_non_zero_reading_resets_the_count() -> None:
    mon = Monitor(zero_run=3)
    zero, ok = np.full(7, 50.0), np.full(7, 50.0)
    zero[FRONT] = 0.0
    for r in (zero, zero, ok, zero, zero):
        assert mon.observe(r, forward=True) is None
    assert mon.observe(zero, forward=True) == without("front")


def test_monitor_detects_a_failed_front_sonar_within_n_decisions_of_a_real_trial() -> None:
    ex = ExecutionModule(DoorConfig(), default_ruleset(), seed=0, schedule=FailureSchedule(((0, ("front",)),)))
    st = ex.run(1)  # the default rules always drive forward
    assert [(c.trial, c.decision, c.capabilities) for c in st.changes] == [(0, ZERO_RUN - 1, without("front"))]
    assert ex.capabilities == without("front")


def test_monitor_gives_no_false_alarm_with_every_sonar_working() -> None:
    ex = ExecutionModule(DoorConfig(), default_ruleset(), seed=1)
    st = ex.run(200)
    assert st.changes == [] and ex.capabilities == SONARS
    assert st.decisions > 2000  # it did watch


def test_monitor_sees_a_repair_and_the_same_failure_again() -> None:
    sched = FailureSchedule(((0, FAILED), (3, ()), (6, FAILED)))
    ex = ExecutionModule(DoorConfig(), default_ruleset(), seed=2, schedule=sched)
    changes = ex.run(9).changes
    assert [c.capabilities for c in changes] == [without(*FAILED), SONARS, without(*FAILED)]
    assert [c.trial for c in changes] == [0, 3, 6]
    assert changes[1].decision == REPAIR_RUN - 1


def test_monitor_refuses_bad_input() -> None:
    with pytest.raises(ConfigError, match="zero_run"):
        Monitor(zero_run=0)
    with pytest.raises(ConfigError, match="unknown sonar 'rear'"):
        Monitor(capabilities=("front", "rear"))
    with pytest.raises(ConfigError, match="7 sonar readings"):
        Monitor().observe(np.zeros(6), forward=True)


def test_monitor_batch_agrees_with_one_decision_at_a_time() -> None:
    rng = np.random.default_rng(0)
    a, b = Monitor(zero_run=3, repair_run=2), Monitor(zero_run=3, repair_run=2)
    for _ in range(200):
        m = int(rng.integers(1, 10))
        r = np.where(rng.random((m, 7)) < rng.random() * 0.6, 0.0, 30.0)
        if rng.random() < 0.5:
            r[:, :3] = 0.0
        f = rng.random(m) < 0.8
        one = [(i, c) for i in range(m) if (c := b.observe(r[i], bool(f[i]))) is not None]
        assert a.observe_decisions(r, f) == one
        assert a.capabilities == b.capabilities


# ------------------------------------------------------------------ the case base
def _rules(seed: int):
    return random_ruleset(DOOR, 4, np.random.default_rng(seed))


def test_case_base_finds_the_nearest_capability_list_newest_first() -> None:
    cb = CaseBase()
    all_old = cb.add(SONARS, _rules(0), fitness=0.9, generation=50)
    blind = cb.add(without(*FAILED), _rules(1), fitness=0.8, generation=100)
    all_new = cb.add(SONARS, _rules(2), fitness=0.95, generation=150)
    assert distance(SONARS, without(*FAILED)) == 3
    assert cb.nearest(without(*FAILED), 3) == [blind, all_new, all_old]
    assert cb.nearest(SONARS) == [all_new]
    assert cb.nearest(without("front")) == [all_new]  # distance 1 to all sonars, 2 to the blind case
    assert CaseBase().nearest(SONARS, 2) == []


def test_case_base_json_lines_round_trip_and_bad_lines(tmp_path) -> None:
    cb = CaseBase()
    cb.add(SONARS, _rules(0), fitness=0.5, generation=3)
    cb.add(without("front"), _rules(1), fitness=0.25, generation=7)
    back = CaseBase.from_jsonl(cb.to_jsonl())
    assert [(c.capabilities, c.fitness, c.generation, c.seq) for c in back] == \
           [(c.capabilities, c.fitness, c.generation, c.seq) for c in cb]
    assert all(a.rules == b.rules for a, b in zip(back, cb))
    cb.save(tmp_path / "cases.jsonl")
    assert CaseBase.load(tmp_path / "cases.jsonl").to_jsonl() == cb.to_jsonl()
    with pytest.raises(ConfigError, match="case base line 2"):
        CaseBase.from_jsonl(cb.to_jsonl().splitlines()[0] + "\n{not json\n")
    with pytest.raises(ConfigError, match="schema version"):
        CaseBase.from_jsonl('{"schema_version": 99}\n')


# ------------------------------------------------------------------ the modules
def test_execution_module_keeps_the_last_100_trials_and_uses_the_newest_rules() -> None:
    ex = ExecutionModule(DoorConfig(), default_ruleset(), seed=3)
    first = ex.run(60)
    second = ex.run(60)
    outcomes = np.concatenate([first.outcome, second.outcome])[-100:]
    assert second.performance == pytest.approx(float((outcomes == 1).sum()))
    other = _rules(5)
    ex.receive(other)
    assert ex.rules is other and ex.version == 1
    with pytest.raises(ConfigError, match="at least 1"):
        ex.run(0)


def test_failure_schedule_checks_names_and_order() -> None:
    s = FailureSchedule.at_generations([(2, "front-right,front"), (4, ())], trials_per_generation=10)
    assert s.events == ((20, ("front", "front_right")), (40, ()))
    assert s.failed_at(19) == () and s.failed_at(20) == ("front", "front_right") and s.failed_at(45) == ()
    with pytest.raises(ConfigError, match="unknown sonar"):
        FailureSchedule(((0, ("rear",)),))
    with pytest.raises(ConfigError, match="increase"):
        FailureSchedule(((5, ()), (5, ("front",))))


def test_learning_restart_keeps_half_and_fills_the_rest_with_the_initial_rules() -> None:
    lm = LearningModule(DoorConfig(), TINY_GA, seed=0)
    lm.generation()
    before = list(lm.ga.population)
    assert lm.best is not None
    assert lm.set_capabilities(without(*FAILED)) is True
    pop = lm.ga.population
    kept = [i for i in range(10) if pop[i] is before[i]]
    assert len(kept) == 5 and 0 in kept  # the elite stays
    assert all(pop[i] is default_ruleset() for i in range(10) if i not in kept)
    assert lm.model.failed == FAILED and lm.best is None
    assert lm.set_capabilities(without(*FAILED)) is False  # no change, no restart
    assert lm.generation().capabilities == without(*FAILED)


def test_learning_restart_with_a_case_base_seeds_from_the_nearest_cases() -> None:
    cb = CaseBase()
    lm = LearningModule(DoorConfig(), TINY_GA, seed=0, case_base=cb)
    lm.generation()
    lm.set_capabilities(without(*FAILED))  # stores the all-sonar best, then seeds with it
    assert [c.capabilities for c in cb] == [SONARS]
    assert sum(p is cb.nearest(SONARS)[0].rules for p in lm.ga.population) >= 5
    blind_case = cb.add(without(*FAILED), _rules(9), fitness=0.7, generation=1)
    lm.generation()
    lm.set_capabilities(SONARS)
    lm.generation()
    lm.set_capabilities(without(*FAILED))
    # stored meanwhile: the blind best at the repair and the all-sonar best now; the two blind cases are nearest
    learned, manual, newest_all = cb.nearest(without(*FAILED), 3)
    assert (learned.capabilities, manual) == (without(*FAILED), blind_case) and newest_all.capabilities == SONARS
    assert {id(p) for p in lm.ga.population} >= {id(learned.rules), id(manual.rules), id(newest_all.rules)}


def test_learning_module_refuses_bad_settings() -> None:
    with pytest.raises(ConfigError, match="keep"):
        LearningModule(DoorConfig(), TINY_GA, seed=0, keep=1.5)
    with pytest.raises(ConfigError, match="unknown sonar"):
        LearningModule(DoorConfig(), TINY_GA, seed=0).set_capabilities(("front", "rear"))


# ------------------------------------------------------------------ the lockstep run
def test_a_short_lockstep_run_is_deterministic_and_detects_the_failure() -> None:
    kw = dict(generations=4, events=((2, FAILED),), trials_per_generation=20, ga=TINY_GA, case_base=True)
    a, b = run_cel(5, **kw), run_cel(5, **kw)
    for r in (a, b):
        del r["seconds"]
    assert a == b
    assert [row["world_failed"] for row in a["rows"]] == [[], [], list(FAILED), list(FAILED), list(FAILED)]
    det = a["detections"][0]
    assert det["detected"] and det["trials"] == 1 and det["generations"] == 0
    assert a["rows"][3]["learner_capabilities"] == list(without(*FAILED))
    assert run_cel(6, **kw)["rows"] != a["rows"]


def test_recovery_counts_generations_back_over_a_threshold() -> None:
    assert recovery([10, 90, 20, 40, 95, 96], 2, 90) == 2
    assert recovery([10, 90, 95, 40], 2, 90) == 0
    assert recovery([10, 90, 20, 40], 2, 90) is None


# ------------------------------------------------------------------ checkpoints (for a service's --resume)
def test_modules_restored_from_their_state_go_on_exactly_as_the_originals() -> None:
    import json

    sched = FailureSchedule(((30, FAILED),))
    lm = LearningModule(DoorConfig(), TINY_GA, seed=1)
    ex = ExecutionModule(DoorConfig(), default_ruleset(), seed=2, schedule=sched)
    for _ in range(2):
        step = lm.generation()
        if step.new_best is not None:
            ex.receive(step.new_best)
        for c in ex.run(20).changes:
            lm.set_capabilities(c.capabilities)
    assert lm.capabilities == without(*FAILED)
    lm_state, ex_state = json.loads(json.dumps(lm.state_dict())), json.loads(json.dumps(ex.state_dict()))
    lm2 = LearningModule(DoorConfig(), TINY_GA, seed=99)
    ex2 = ExecutionModule(DoorConfig(), default_ruleset(), seed=99, schedule=sched)
    lm2.load_state(lm_state)
    ex2.load_state(ex_state)
    for a, b in ((lm, ex), (lm2, ex2)):
        b.receive(a.generation().new_best or b.rules)
    st, st2 = ex.run(20), ex2.run(20)
    assert lm2.capabilities == lm.capabilities and lm2.best_fitness == lm.best_fitness
    assert st.outcome.tolist() == st2.outcome.tolist() and st.performance == st2.performance
    assert ex2.monitor.state_dict() == ex.monitor.state_dict()
    with pytest.raises(ConfigError, match="not a learning module state"):
        lm2.load_state({"failed": ["rear"]})
