"""Initial behaviours and where Docking learns (SPEC §1, "Initial behaviours", "Where Docking learns")."""

from __future__ import annotations

import numpy as np
import pytest

from coevo.agents.models import PartnerModels
from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga import GA
from coevo.policy import parse_ruleset
from coevo.policy.rules import interval_width
from coevo.tasks import get_task
from coevo.tasks.fuel import default_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.evaluate import FuelEvaluator as Evaluator
from coevo.tasks.fuel.robot import docking_from_random_starts
from coevo.tasks.fuel.settings import WorldConfig

FUEL = get_task("fuel")

DOCK_SENSORS = {"dock_bearing"}
TRACK_SENSORS = {"target_range", "target_bearing"}


@pytest.mark.parametrize(("behaviour", "allowed"), [("tracking", TRACK_SENSORS), ("docking", DOCK_SENSORS)])
def test_defaults_are_small_and_sense_only_the_direction(behaviour: str, allowed: set[str]) -> None:
    rs = default_ruleset(behaviour)
    assert rs is not None and 3 <= len(rs) <= 8
    bins = np.array([s.bins for s in rs.schema.sensors])
    used = {rs.schema.sensors[j].name for j in np.flatnonzero((interval_width(rs) < bins).any(axis=0))}
    assert used <= allowed  # nothing about walls, the Target's motion, the approach angle or the dock's range


def test_the_executive_has_no_default() -> None:
    assert default_ruleset("executive") is None


def test_the_docking_default_leaves_docking_to_learning() -> None:
    """It drives at 8 ips, twice the fastest accepted docking speed: it cannot dock by itself."""
    rs = default_ruleset("docking")
    speeds = {rs.schema.actions[1].values[int(a)] for a in rs.action[:, 1]}
    assert speeds == {8}
    assert docking_from_random_starts(WorldConfig(), rs, episodes=200, seed=3) == 0.0


def test_the_ga_starts_from_the_default_unless_told_random(world_cfg: WorldConfig, small_ga: GAConfig) -> None:
    for b in ("tracking", "docking"):
        ga = GA(FUEL, b, world=world_cfg, ga=small_ga, seed=0)
        assert ga.population[0] == default_ruleset(b)
        rnd = GA(FUEL, b, world=world_cfg, ga=small_ga.model_copy(update={"initial": "random"}), seed=0)
        assert all(len(p) == small_ga.initial_rules for p in rnd.population)
        assert default_ruleset(b) not in rnd.population
    ex = GA(FUEL, "executive", world=world_cfg, ga=small_ga, seed=0)
    assert all(len(p) == small_ga.initial_rules for p in ex.population)  # random rule sets


def test_a_partner_that_has_not_published_is_modelled_by_its_initial_behaviour() -> None:
    m = PartnerModels(FUEL, Behaviour.EXECUTIVE, "independent", 0, ga=GAConfig(initial="default")).partners()
    assert m["tracking"] == default_ruleset("tracking") and m["docking"] == default_ruleset("docking")
    r = PartnerModels(FUEL, Behaviour.EXECUTIVE, "independent", 0, ga=GAConfig(initial="random")).partners()
    assert r["docking"] != default_ruleset("docking")
    mutual = PartnerModels(FUEL, Behaviour.DOCKING, "mutual", 0).partners()
    assert mutual["executive"] != default_ruleset("executive")


def test_a_bad_initial_setting_is_refused() -> None:
    from coevo.config import build

    with pytest.raises(ConfigError, match="initial='sometimes'"):
        build(GAConfig, initial="sometimes")


# ------------------------------------------------------------------ where Docking learns
def _docker() -> object:
    """A rule set that docks from just in front of the dock and nowhere else (the re-docking trap)."""
    return parse_ruleset(
        "IF dock_range = [0, 25] AND dock_orientation = [355, 5] THEN SET turn = 0 AND speed = 4 (strength 0.9)\n"
        "IF ANY THEN SET turn = 24 AND speed = 0 (strength 0.1)\n", "docking")


def test_docking_trains_on_fresh_starts_with_the_trivial_executive(world_cfg: WorldConfig) -> None:
    ga_cfg = GAConfig(population=4, episodes=40, best_episodes=40, lane_episodes=10)
    ev = Evaluator("docking", world_cfg, ga_cfg)
    assert ev.fresh_starts({})
    assert ev.layout(40, fresh_starts=True) == (40, 1, True)
    out = ev.evaluate([_docker()], {}, np.random.default_rng(0)).details
    assert out.played.shape == (40, 1)  # one episode per lane, each from its own random epoch start
    # With re-docking allowed, a docking is followed by an episode in front of the dock.
    carry = Evaluator("docking", world_cfg.model_copy(update={"docking_fresh_starts": False}), ga_cfg)
    assert not carry.fresh_starts({})
    assert carry.evaluate([_docker()], {}, np.random.default_rng(0)).details.played.shape == (4, 10)


def test_docking_inside_an_executives_epochs_is_unchanged(world_cfg: WorldConfig, small_ga: GAConfig) -> None:
    always_dock = parse_ruleset("IF ANY THEN SET task = dock (strength 0.5)", "executive")
    ev = Evaluator("docking", world_cfg, small_ga)
    partners = {"executive": always_dock, "tracking": default_ruleset("tracking")}
    assert not ev.fresh_starts(partners)  # Mutual: Docking learns in the epochs the Executive gives it


def test_docking_reports_its_rate_from_random_starts(world_cfg: WorldConfig, small_ga: GAConfig) -> None:
    rep = GA(FUEL, "docking", world=world_cfg, ga=small_ga, seed=0).generation({})
    assert rep.measures["docking_from_random"] is not None and 0.0 <= rep.measures["docking_from_random"] <= 100.0
    assert rep.measures["docking_from_random"] == rep.measures["docking_success_rate"]  # the re-evaluation already played fresh starts
    always_dock = parse_ruleset("IF ANY THEN SET task = dock (strength 0.5)", "executive")
    mutual = GA(FUEL, "docking", world=world_cfg, ga=small_ga, seed=0)
    rep = mutual.generation({"executive": always_dock, "tracking": default_ruleset("tracking")})
    assert rep.measures["docking_from_random"] is not None  # measured apart, on fresh starts
    assert GA(FUEL, "tracking", world=world_cfg, ga=small_ga, seed=0).generation({}).measures["docking_from_random"] is None
