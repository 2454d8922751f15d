"""The world's rules: contacts, docking boundaries, fuel and towing, sensor bins."""

from __future__ import annotations

import numpy as np
import pytest

from coevo.policy.matcher import CompiledPolicies
from coevo.policy.schema import schema
from coevo.policy.text import parse_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.runner import ALWAYS_DOCK, ALWAYS_TRACK, Rules, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import DOCK_HEADING, BatchWorld

STILL = np.zeros(1)
QUIET = WorldConfig(target_speed=0.0, target_turn_sd=0.0)


def step(world: BatchWorld, turn: float, speed: float):
    return world.step(np.ones(world.n, bool), np.full(world.n, turn), np.full(world.n, speed), np.zeros(world.n))


def test_wall_contact_is_a_collision() -> None:
    w = BatchWorld(QUIET, 1)
    r = QUIET.robot_radius
    w.set_state([0], robot=(r + 3.0, 150.0), heading=180.0, target=(200.0, 200.0), fuel=1.0)
    ev = step(w, 0.0, 8.0)  # 4 inches west: into the wall
    assert ev.collided[0] and not ev.docked[0]


def test_target_contact_is_a_collision() -> None:
    w = BatchWorld(QUIET, 1)
    w.set_state([0], robot=(100.0, 100.0), heading=0.0, target=(100.0 + 2 * 9.0 + 3.0, 100.0), fuel=1.0)
    assert step(w, 0.0, 8.0).collided[0]


def test_moving_in_open_space_is_not_a_collision() -> None:
    w = BatchWorld(QUIET, 1)
    w.set_state([0], robot=(100.0, 100.0), heading=0.0, target=(200.0, 200.0), fuel=1.0)
    ev = step(w, 0.0, 16.0)
    assert not ev.collided[0]
    assert w.rx[0] == pytest.approx(108.0)


def _approach_dock(angle_off: float, speed: float, x_off: float = 0.0):
    cfg = QUIET
    w = BatchWorld(cfg, 1)
    heading = DOCK_HEADING + angle_off
    # Start so that one step of `speed` brings the robot's edge 0.5 in into the dock's front.
    travel = speed * cfg.step_seconds
    y = cfg.dock_depth + cfg.robot_radius - 0.5 + travel * abs(np.sin(np.radians(heading)))
    x = cfg.arena / 2 + x_off - travel * np.cos(np.radians(heading))
    w.set_state([0], robot=(x, y), heading=heading, target=(50.0, 250.0), fuel=0.3)
    return w, step(w, 0.0, speed)


@pytest.mark.parametrize("angle", [0.0, 14.9, -14.9, 15.0, -15.0])
def test_docking_accepted_head_on_within_15_degrees_at_4_ips(angle: float) -> None:
    w, ev = _approach_dock(angle, 4.0)
    assert ev.docked[0] and not ev.collided[0]


@pytest.mark.parametrize("angle,speed", [(15.5, 4.0), (-16.0, 4.0), (40.0, 4.0), (0.0, 8.0), (0.0, 16.0)])
def test_docking_refused_too_skew_or_too_fast_is_a_collision(angle: float, speed: float) -> None:
    w, ev = _approach_dock(angle, speed)
    assert ev.collided[0] and not ev.docked[0]


def test_docking_refills_the_tank_and_restarts_in_front_of_the_dock() -> None:
    w, ev = _approach_dock(0.0, 4.0)
    assert ev.docked[0]
    w.place_at_dock(np.array([0]))
    assert w.fuel[0] == 1.0
    assert w.ry[0] > QUIET.dock_depth + QUIET.robot_radius
    assert np.degrees(w.rh[0]) == pytest.approx(90.0)


def test_fuel_use_is_linear_in_speed_and_turn() -> None:
    cfg = QUIET
    w = BatchWorld(cfg, 3)
    for i in range(3):
        w.set_state([i], robot=(150.0, 150.0), heading=90.0, target=(60.0, 60.0), fuel=1.0)
    w.step(np.ones(3, bool), np.array([0.0, 0.0, 24.0]), np.array([0.0, 8.0, 0.0]), np.zeros(3))
    used = 1.0 - w.fuel
    assert used[0] == pytest.approx(cfg.fuel_idle)
    assert used[1] == pytest.approx(cfg.fuel_idle + 8 * cfg.fuel_per_ips)
    assert used[2] == pytest.approx(cfg.fuel_idle + 24 * cfg.fuel_per_dps)


def test_starting_supply_lasts_about_8_episodes_still_and_4_at_4_ips() -> None:
    """The report: 'if it were to remain motionless it could survive approximately eight episodes ...
    while it is moving slowly it can last up to four episodes' (SPEC §1, Fuel: the 50 % an epoch starts with)."""
    cfg = WorldConfig(target_speed=0.0, target_turn_sd=0.0)
    w = BatchWorld(cfg, 4)
    stand = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)", "tracking")
    out = run_lanes(w, lane_episodes=10, executive=ALWAYS_TRACK, tracking=Rules.single(CompiledPolicies([stand]), 4),
                    docking=None, restart_epochs=False, rng=np.random.default_rng(0))
    assert out.epoch_complete.all() and (out.epoch_penalty == cfg.towing_penalty).all()
    lasted = out.steps.sum(axis=1) / cfg.episode_steps  # episodes' worth of steps until dry
    assert lasted == pytest.approx(np.full(4, 8.0), abs=0.05)
    # At 4 ips, in an arena wide enough never to reach a wall.
    wide = WorldConfig(arena=2000.0, target_speed=0.0, target_turn_sd=0.0)
    w = BatchWorld(wide, 1)
    w.set_state([0], robot=(1000.0, 200.0), heading=90.0, target=(100.0, 100.0), fuel=wide.initial_fuel)
    steps = 0
    while True:
        steps += 1
        ev = w.step(np.ones(1, bool), np.zeros(1), np.full(1, 4.0), np.zeros(1))
        assert not ev.collided[0]
        if ev.dry[0]:
            break
    assert steps / wide.episode_steps == pytest.approx(4, abs=0.1)


def test_running_dry_ends_the_epoch_with_the_towing_penalty() -> None:
    cfg = WorldConfig(initial_fuel=0.051, target_speed=0.0, target_turn_sd=0.0)
    w = BatchWorld(cfg, 4)
    stand = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)", "tracking")
    out = run_lanes(w, lane_episodes=10, executive=ALWAYS_TRACK, tracking=Rules.single(CompiledPolicies([stand]), 4),
                    docking=None, restart_epochs=False, rng=np.random.default_rng(0))
    steps_to_dry = int(np.ceil(0.051 / cfg.fuel_idle))  # 24.48 -> 25
    assert out.dry[:, 0].all()
    assert (out.steps[:, 0] == steps_to_dry).all()
    assert (out.epoch_episodes == 1).all() and out.epoch_complete.all()
    assert (out.epoch_penalty == cfg.towing_penalty).all()
    expected = out.epoch_tracked / (cfg.episode_steps * cfg.epoch_episodes + cfg.towing_penalty)
    np.testing.assert_allclose(out.epoch_payoff, expected)


def test_collision_ends_the_epoch() -> None:
    cfg = QUIET
    w = BatchWorld(cfg, 2)
    rush = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 16 (strength 0.5)", "tracking")
    out = run_lanes(w, lane_episodes=10, executive=ALWAYS_TRACK, tracking=Rules.single(CompiledPolicies([rush]), 2),
                    docking=None, restart_epochs=False, rng=np.random.default_rng(3))
    assert out.collided[:, 0].all()
    assert not out.played[:, 1:].any()
    assert (out.payoff[:, 0] == 0).all()


def test_epoch_runs_ten_episodes_when_nothing_fails() -> None:
    cfg = WorldConfig(initial_fuel=1.0, fuel_idle=1e-5, fuel_per_ips=0.0, fuel_per_dps=0.0, target_speed=0.0, target_turn_sd=0.0)
    w = BatchWorld(cfg, 3)
    stand = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)", "tracking")
    out = run_lanes(w, lane_episodes=10, executive=ALWAYS_TRACK, tracking=Rules.single(CompiledPolicies([stand]), 3),
                    docking=None, restart_epochs=False, rng=np.random.default_rng(0))
    assert out.played.all() and (out.steps == cfg.episode_steps).all()
    assert (out.epoch_episodes == 10).all()


@pytest.mark.parametrize("value,expected", [(0.0, 0), (4.99, 0), (5.0, 1), (149.9, 29), (150.0, 30), (900.0, 30), (-3.0, 0)])
def test_range_bins_are_5_inches_with_a_last_bin_beyond_150(value: float, expected: int) -> None:
    s = schema(Behaviour.TRACKING).sensors[0]
    assert int(s.discretise(np.array([value]))[0]) == expected


@pytest.mark.parametrize("value,expected", [(0.0, 0), (4.99, 0), (5.0, 1), (359.99, 71), (360.0, 0), (-1.0, 71), (725.0, 1)])
def test_bearing_bins_are_5_degrees_and_wrap(value: float, expected: int) -> None:
    s = schema(Behaviour.TRACKING).sensors[1]
    assert int(s.discretise(np.array([value]))[0]) == expected


def test_heading_bins_are_45_degrees() -> None:
    s = schema(Behaviour.TRACKING).sensors[2]
    assert s.bins == 8
    assert s.discretise(np.array([0.0, 44.9, 45.0, 359.0])).tolist() == [0, 0, 1, 7]


def test_sensors_see_target_and_dock_where_they_are() -> None:
    w = BatchWorld(QUIET, 1)
    w.set_state([0], robot=(150.0, 100.0), heading=90.0, target=(150.0, 150.0), target_heading=90.0, fuel=0.42)
    obs = w.observe()
    assert obs["target_range"][0] == pytest.approx(50.0)
    assert obs["target_bearing"][0] == pytest.approx(0.0, abs=1e-9)
    assert obs["heading"][0] == pytest.approx(0.0, abs=1e-9)  # Target moving straight away
    assert obs["dock_range"][0] == pytest.approx(100.0 - QUIET.dock_depth)
    assert obs["dock_bearing"][0] == pytest.approx(180.0)
    assert obs["dock_orientation"][0] == pytest.approx(180.0)
    assert obs["fuel"][0] == pytest.approx(42.0)
    assert obs["range"][0] == pytest.approx(50.0 - 2 * 9.0)  # the Target is the nearest object
    assert obs["bearing"][0] == pytest.approx(0.0, abs=1e-9)


def test_tracking_counts_steps_in_40_to_60_inches() -> None:
    w = BatchWorld(QUIET, 2)
    w.set_state([0], robot=(150.0, 100.0), heading=0.0, target=(150.0, 150.0), fuel=1.0)
    w.set_state([1], robot=(150.0, 100.0), heading=0.0, target=(150.0, 170.0), fuel=1.0)
    ev = step(w, 0.0, 0.0)
    assert ev.tracking.tolist() == [True, False]


def test_lanes_do_not_touch_each_other() -> None:
    w = BatchWorld(QUIET, 9)
    for i in range(9):
        w.set_state([i], robot=(QUIET.arena - 9.5, QUIET.arena - 9.5), heading=45.0, target=(50.0, 50.0), fuel=1.0)
    ev = step(w, 0.0, 0.0)
    assert not ev.collided.any()


def test_always_dock_executive_only_runs_docking() -> None:
    w = BatchWorld(QUIET, 3)
    rs = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 4 (strength 0.5)", "docking")
    out = run_lanes(w, lane_episodes=2, executive=ALWAYS_DOCK, tracking=None, docking=Rules.single(CompiledPolicies([rs]), 3),
                    restart_epochs=True, rng=np.random.default_rng(0))
    assert (out.task[out.played] == 1).all()


def test_common_scenarios_give_every_group_the_same_situations() -> None:
    cfg = WorldConfig()
    w = BatchWorld(cfg, 6)
    stand = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)", "tracking")
    out = run_lanes(w, lane_episodes=3, executive=ALWAYS_TRACK, tracking=Rules.single(CompiledPolicies([stand]), 6),
                    docking=None, restart_epochs=True, rng=np.random.default_rng(0), scenarios=3)
    # Lanes 0 and 3, 1 and 4, 2 and 5 share a scenario and run the same policy: identical lives.
    assert np.array_equal(out.tracked[:3], out.tracked[3:])
    assert np.array_equal(out.steps[:3], out.steps[3:])
    assert not np.array_equal(out.tracked[0], out.tracked[1]) or not np.array_equal(out.steps[0], out.steps[1])


def test_scenarios_must_divide_the_lanes() -> None:
    from coevo.errors import ConfigError

    w = BatchWorld(QUIET, 4)
    stand = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)", "tracking")
    with pytest.raises(ConfigError, match="scenarios=3"):
        run_lanes(w, lane_episodes=1, executive=ALWAYS_TRACK, tracking=Rules.single(CompiledPolicies([stand]), 4),
                  docking=None, restart_epochs=True, rng=np.random.default_rng(0), scenarios=3)
