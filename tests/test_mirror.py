"""A rule's mirror image (coevo.policy.rules.mirror_image) and symmetric rules (coevo.ga.symmetry)."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from coevo.config import GAConfig
from coevo.errors import ConfigError, RuleSetError
from coevo.experiments.compare.experiment import CompareSpec
from coevo.ga import GA
from coevo.ga.symmetry import MirroredEvaluator, fold, with_mirror_images
from coevo.policy.rules import mirror_image, random_ruleset
from coevo.policy.schema import Action, Sensor, schema
from coevo.rundir.settings import RunSettings
from coevo.tasks import get_task
from coevo.tasks.base import ga_settings
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld


@pytest.mark.parametrize("behaviour", ["tracking", "docking", "executive"])
def test_the_mirror_of_the_mirror_is_the_rule_itself(behaviour: str, rng) -> None:
    rs = random_ruleset(behaviour, 40, rng)
    assert mirror_image(mirror_image(rs)) == rs
    assert (mirror_image(rs).strength == rs.strength).all()


def test_a_mirrored_sensor_or_action_must_be_symmetric_about_zero() -> None:
    with pytest.raises(RuleSetError, match="'lean'"):
        Sensor("lean", 5.0, 30, False, "inches", origin=-70.0, mirrored=True)
    with pytest.raises(RuleSetError, match="'half'"):
        Sensor("half", 5.0, 36, True, "degrees", mirrored=True)
    with pytest.raises(RuleSetError, match="'veer'"):
        Action("veer", (-4, 0, 8), mirrored=True)
    assert Sensor("offset", 5.0, 30, False, "inches", origin=-75.0, mirrored=True).mirrored


def test_the_fuel_world_senses_its_mirror_image_in_mirrored_bins(rng) -> None:
    """A robot and a Target, and the same reflected about the dock's axis (x -> arena - x, heading -> 180 -
    heading): every Docking and Tracking sensor reads the mirrored bin there, so a mirrored rule fires in the
    mirrored state."""
    cfg = WorldConfig()
    n = 200
    w = BatchWorld(cfg, 2 * n)
    starts = w.random_starts(n, rng)
    mirrored = starts.copy()
    mirrored[:, [0, 3]] = cfg.arena - starts[:, [0, 3]]
    mirrored[:, [2, 5]] = np.pi - starts[:, [2, 5]]
    w.reset(np.arange(2 * n), starts=np.vstack([starts, mirrored]))
    for behaviour in ("docking", "tracking"):
        sch = schema(behaviour)
        raw = w.observe(sch.sensor_names)
        for s in sch.sensors:
            here = s.discretise(raw[s.name][:n]).astype(int)
            there = s.discretise(raw[s.name][n:]).astype(int)
            expect = s.bins - 1 - here if s.mirrored else here
            # a value on a bin edge may fall either side; random starts put (almost) none there
            assert np.mean(there == expect) > 0.98, (behaviour, s.name)


def test_a_policy_is_played_with_its_mirror_images_and_at_most_32_rules_are_bred(rng) -> None:
    rs = random_ruleset("docking", 5, rng)
    played = with_mirror_images(rs)
    assert len(played) == 10 and played.take(range(5)) == rs and played.take(range(5, 10)) == mirror_image(rs)
    with pytest.raises(RuleSetError, match="at most 32 rules"):
        with_mirror_images(random_ruleset("docking", 33, rng))


def test_an_images_decisions_are_folded_onto_its_rule_in_the_rules_own_frame(rng) -> None:
    """Play a policy with its images; every decision folded onto a rule lies inside that rule's conditions
    (seen in its own frame), and an image's firings count as its rule's."""
    rs = random_ruleset("docking", 12, rng)
    evaluator = get_task("fuel").evaluator("docking", WorldConfig(), GAConfig(episodes=30))
    played = evaluator.evaluate([with_mirror_images(rs)], {}, np.random.default_rng(4))
    exp = played.experience[0]
    sch = rs.schema
    assert (exp.rule >= 12).any() and (exp.rule < 12).any(), "no decision by a rule or none by an image"
    folded = fold(exp, 12, sch)
    assert folded.rule.max() < 12 and (folded.fired >> np.uint64(12) == 0).all()
    assert ((folded.fired != 0) == (exp.fired != 0)).all()
    full = folded.full
    lo, hi, k = rs.lo[folded.rule[full]], rs.hi[folded.rule[full]], folded.bins[full]
    inside = np.where(lo <= hi, (lo <= k) & (k <= hi), (k >= lo) | (k <= hi))
    assert inside.all()
    images = exp.rule >= 12
    assert not (folded.bins[images] == exp.bins[images]).all()  # the images' decisions were reflected


def test_a_symmetric_ga_evaluates_exactly_the_policy_it_publishes(rng) -> None:
    ga_cfg = GAConfig(population=4, episodes=12, best_episodes=12, generations=2)
    ga = GA(get_task("fuel"), "docking", world=WorldConfig(), ga=ga_cfg, seed=2)
    assert isinstance(ga.evaluator, MirroredEvaluator) and ga.cfg.max_rules == 32
    ga.generation({})
    plain = get_task("fuel").evaluator("docking", WorldConfig(), ga.cfg)
    for rs in ga.population[:2]:
        assert len(rs) <= 32
        mine = ga.evaluator.evaluate([rs], {}, np.random.default_rng(9)).fitness
        theirs = plain.evaluate([ga.played(rs)], {}, np.random.default_rng(9)).fitness
        assert mine == pytest.approx(theirs, abs=0)
    assert len(ga.played(ga.best)) == 2 * len(ga.best)


def test_symmetric_rules_need_a_mirror_world_and_room_for_the_images() -> None:
    with pytest.raises(ConfigError, match="max_rules <= 32.*got max_rules=48"):
        GA(get_task("fuel"), "docking", world=WorldConfig(), ga=GAConfig(max_rules=48, symmetric_rules=True), seed=0)
    with pytest.raises(ConfigError, match="symmetric docking rules need max_rules <= 32"):  # before any run starts
        RunSettings.make(run="r", regime="independent", ga=GAConfig(max_rules=64))
    with pytest.raises(ValidationError, match="symmetric docking rules need max_rules <= 32"):  # before OUT is written
        CompareSpec(ga=GAConfig(max_rules=64))
    door = get_task("door")
    with pytest.raises(ConfigError, match="mirror image.*'door'"):
        GA(door, "door", world=door.world_settings(), ga=GAConfig(symmetric_rules=True, max_rules=16), seed=0)


def test_docking_rules_are_symmetric_by_default_the_others_are_not() -> None:
    fuel = get_task("fuel")
    assert fuel.mirror_symmetric
    docking, tracking = ga_settings(fuel, "docking", GAConfig()), ga_settings(fuel, "tracking", GAConfig())
    assert (docking.symmetric_rules, docking.max_rules) == (True, 32)
    assert (tracking.symmetric_rules, tracking.max_rules) == (False, 48)
    told = ga_settings(fuel, "docking", GAConfig(symmetric_rules=False, max_rules=48))
    assert (told.symmetric_rules, told.max_rules) == (False, 48)
    tracker = GA(fuel, "tracking", world=WorldConfig(), ga=GAConfig(), seed=0)
    assert tracker.played(tracker.population[0]) is tracker.population[0]  # played as bred


def test_a_checkpoint_of_longer_policies_than_the_ga_breeds_is_refused_by_name() -> None:
    fuel, small = get_task("fuel"), dict(population=4, episodes=4, best_episodes=4, generations=2)
    old = GA(fuel, "docking", world=WorldConfig(), ga=GAConfig(symmetric_rules=False, max_rules=48, **small), seed=1)
    state = old.state_dict()
    state["population"][0] = random_ruleset("docking", 40, np.random.default_rng(0)).to_dict()
    new = GA(fuel, "docking", world=WorldConfig(), ga=GAConfig(**small), seed=1)
    with pytest.raises(ConfigError, match="up to 40 rules.*max_rules=32"):
        new.load_state(state)
