"""Docking's sensors in the dock's frame and the choice of sensor set (coevo/tasks/fuel/dock_frame.py)."""

from __future__ import annotations

import numpy as np
import pytest

from coevo.config import GAConfig
from coevo.ga import GA
from coevo.policy.schema import schema
from coevo.tasks import get_task
from coevo.tasks.base import ga_settings
from coevo.tasks.fuel import default_ruleset
from coevo.tasks.fuel.behaviours import TARGET_SENSORS
from coevo.tasks.fuel.dock_frame import SENSOR_SETS
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld


def test_frame_sensors_give_the_place_in_the_dock_frame() -> None:
    cfg = WorldConfig()
    w = BatchWorld(cfg, 2)
    w.set_state([0], robot=(170.0, 40.0), heading=-80.0)
    w.set_state([1], robot=(100.0, 200.0), heading=0.0)
    o = w.observe(("dock_axis", "dock_offset", "dock_orientation"))
    assert o["dock_axis"] == pytest.approx([40.0 - cfg.dock_depth - cfg.robot_radius, 200.0 - cfg.dock_depth - cfg.robot_radius])
    assert o["dock_offset"] == pytest.approx([20.0, -50.0])  # east of the axis is positive
    assert o["dock_orientation"] == pytest.approx([10.0, 90.0])
    sch = schema("docking")
    j = sch.sensor_index("dock_offset")
    off = sch.sensors[j]
    assert off.label(0) == -75 and off.label(15) == 0
    assert off.discretise(np.array([-200.0, -0.1, 0.0, 4.9, 500.0])).tolist() == [0, 14, 15, 15, off.bins - 1]
    assert off.bin_of_label(-5) == 14


@pytest.mark.parametrize("sensors", sorted(SENSOR_SETS))
def test_each_set_starts_from_a_direction_only_default_over_its_own_sensors(sensors: str) -> None:
    rs = default_ruleset("docking", sensors)
    sch = rs.schema
    full = np.array([s.bins - 1 for s in sch.sensors])
    used = {sch.sensor_names[j] for j in range(sch.n_sensors) if ((rs.lo[:, j] != 0) | (rs.hi[:, j] != full[j])).any()}
    assert used <= set(SENSOR_SETS[sensors])
    assert set(np.asarray(sch.actions[1].values)[rs.action[:, 1]]) == {8}  # 8 ips everywhere: nothing about slowing


@pytest.mark.parametrize(("sensors", "target"), [("polar", False), ("dock-frame", False), ("both", False), ("both", True)])
def test_a_docking_ga_conditions_only_on_its_sensor_set(sensors: str, target: bool) -> None:
    ga_cfg = GAConfig(population=6, episodes=4, best_episodes=4, generations=2)
    world = WorldConfig(docking_sensors=sensors, docking_target_sensors=target)
    ga = GA(get_task("fuel"), "docking", world=world, ga=ga_cfg, seed=3)
    ga.generation({})
    ga.generation({})
    sch = schema("docking")
    full = np.array([s.bins - 1 for s in sch.sensors])
    other = [sch.sensor_index(n) for n in SENSOR_SETS["both"] if n not in SENSOR_SETS[sensors]]
    on_target = [sch.sensor_index(n) for n in sorted(TARGET_SENSORS)]
    for rs in ga.population:
        assert (rs.lo[:, other] == 0).all() and (rs.hi[:, other] == full[other]).all()
    conditioned = [((rs.lo[:, on_target] != 0) | (rs.hi[:, on_target] != full[on_target])).any() for rs in ga.population]
    assert any(conditioned) == target  # left out by default; with the setting the seeded random rules use them


def _ga(**kw: object) -> GA:
    cfg = GAConfig(population=6, episodes=6, best_episodes=6, generations=3, **kw)
    return GA(get_task("fuel"), "docking", world=WorldConfig(docking_sensors="both"), ga=cfg, seed=5)


def test_docking_keeps_the_policy_as_it_was_evaluated_by_default_the_others_do_not() -> None:
    fuel = get_task("fuel")
    docking, tracking = ga_settings(fuel, "docking", GAConfig()), ga_settings(fuel, "tracking", GAConfig())
    assert (docking.keep_evaluated, docking.best_candidates) == (True, 3)
    assert (tracking.keep_evaluated, tracking.best_candidates) == (False, 0)
    told = ga_settings(fuel, "docking", GAConfig(keep_evaluated=False, best_candidates=0))
    assert (told.keep_evaluated, told.best_candidates) == (False, 0)
    ga = _ga()
    before = list(ga.population)
    ga.generation({})
    assert any(ga.current == p for p in before)  # strengths as evaluated, not updated
    assert ga.population[0] == ga.current  # the elite too


def test_best_candidates_judge_the_best_by_all_its_reevaluations_and_leave_the_learning_alone() -> None:
    plain, pooled = _ga(keep_evaluated=True, best_candidates=0), _ga(keep_evaluated=True, best_candidates=3)
    for _ in range(3):
        plain.generation({})
        pooled.generation({})
    assert all(a == b for a, b in zip(plain.population, pooled.population))  # own random stream
    assert 1 <= len(pooled.candidates) <= 3
    rs, total, n = pooled.candidates[0]
    assert pooled.best == rs and pooled.best_fitness == pytest.approx(total / n)
    assert all(t / k <= total / n for _, t, k in pooled.candidates)
    again = _ga(keep_evaluated=True, best_candidates=3)
    again.load_state(pooled.state_dict())
    again.generation({})
    pooled.generation({})
    assert again.best == pooled.best and again.best_fitness == pooled.best_fitness
    assert [c[1:] for c in again.candidates] == [c[1:] for c in pooled.candidates]



def test_operators_draw_only_over_the_usable_sensors() -> None:
    from coevo.ga.mutation import mutate_rules
    from coevo.ga.operators import generalise
    from coevo.policy.rules import random_ruleset

    sch = schema("docking")
    usable = np.array([n not in ("dock_axis", "dock_offset") for n in sch.sensor_names])
    full = np.array([s.bins - 1 for s in sch.sensors])
    rng = np.random.default_rng(0)
    rs = random_ruleset("docking", 20, rng, usable)
    assert (rs.lo[:, ~usable] == 0).all() and (rs.hi[:, ~usable] == full[~usable]).all()
    assert ((rs.lo[:, usable] != 0) | (rs.hi[:, usable] != full[usable])).any()
    m = mutate_rules(rs, np.ones(20, bool), rng, usable)
    g = generalise(rs, None, rng, usable)  # type: ignore[arg-type]
    for out in (m, g):
        assert (out.lo[:, ~usable] == 0).all() and (out.hi[:, ~usable] == full[~usable]).all()
