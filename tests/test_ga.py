"""GA operators, the generational loop, and determinism."""

from __future__ import annotations

import numpy as np
import pytest

from coevo.config import GAConfig
from coevo.errors import ConfigError
from coevo.ga import GA, FixedRate
from coevo.ga.engine import _narrow_in
from coevo.ga.operators import Experience, cover, crossover, delete, generalise, select_parents, specialise, split
from coevo.policy import RuleSet, parse_ruleset, random_ruleset
from coevo.policy.rules import interval_width
from coevo.policy.strength import update_strengths
from coevo.tasks import get_task
from coevo.tasks.base import ga_settings
from coevo.tasks.fuel.evaluate import FuelEvaluator as Evaluator
from coevo.tasks.fuel.settings import WorldConfig

FUEL = get_task("fuel")


def _exp(fired: list[int], payoff: list[float], states: list[tuple[list[int], int, bool, int]], s: int) -> Experience:
    return Experience(
        fired=np.array(fired, dtype=np.uint64),
        payoff=np.array(payoff, dtype=float),
        bins=np.array([x[0] for x in states], dtype=np.uint8).reshape(-1, s),
        rule=np.array([x[1] for x in states], dtype=np.int64),
        full=np.array([x[2] for x in states], dtype=bool),
        episode=np.array([x[3] for x in states], dtype=np.int64),
    )


def test_selection_takes_the_top_half(rng) -> None:
    fit = np.array([0.1, 0.9, 0.5, 0.3, 0.8, 0.2])
    assert sorted(select_parents(fit, 0.5, rng).tolist()) == [1, 2, 4]


def test_crossover_keeps_rules_that_fired_together_in_a_high_payoff_episode(rng) -> None:
    a = random_ruleset("tracking", 8, rng)
    b = random_ruleset("tracking", 8, rng)
    # Rules 1, 3 and 6 of a fired together in a's best episode; rules 0 and 2 of b in b's.
    ea = _exp([(1 << 1) | (1 << 3) | (1 << 6), 1 << 0], [0.9, 0.1], [], 5)
    eb = _exp([(1 << 0) | (1 << 2), 1 << 5], [0.8, 0.0], [], 5)
    for _ in range(30):
        (c1, _), (c2, _) = crossover(a, ea, b, eb, rng)
        assert len(c1) + len(c2) == 16
        for group, parent in (([1, 3, 6], a), ([0, 2], b)):
            homes = set()
            for idx, child in enumerate((c1, c2)):
                for r in group:
                    if any(np.array_equal(child.lo[i], parent.lo[r]) and np.array_equal(child.hi[i], parent.hi[r])
                           and child.strength[i] == parent.strength[r] for i in range(len(child))):
                        homes.add(idx)
            assert len(homes) == 1  # the cluster travelled as one


def test_specialise_narrows_a_weak_general_rule_around_what_it_saw(rng) -> None:
    rs = parse_ruleset("IF range = [25, 55] AND bearing = [0, 180] THEN SET turn = 24 AND speed = 4 (strength 0.1)", "tracking")
    seen = [8, 20, 0, 10, 0]  # range 40, bearing 100
    exp = _exp([1], [0.8], [(seen, 0, True, 0)], 5)
    new = specialise(rs, exp, rng, low_strength=0.3)
    assert new is not None
    assert new.lo[0, 0] == 7 and new.hi[0, 0] == 9  # range [35, 45]
    assert new.lo[0, 1] == 11 and new.hi[0, 1] == 29  # bearing [55, 145] around 100
    assert new.strength[0] == pytest.approx(0.8)
    assert (interval_width(new) <= interval_width(rs)).all()


def test_specialise_with_a_fraction_keeps_the_other_conditions(rng) -> None:
    rs = parse_ruleset("IF range = [25, 55] AND bearing = [0, 180] THEN SET turn = 24 AND speed = 4 (strength 0.1)", "tracking")
    exp = _exp([1], [0.8], [([8, 20, 0, 10, 0], 0, True, 0)], 5)
    for _ in range(20):
        new = specialise(rs, exp, rng, low_strength=0.3, fraction=0.01)
        assert new is not None
        changed = (new.lo[0] != rs.lo[0]) | (new.hi[0] != rs.hi[0])
        assert changed.sum() <= 1 and new.matches(np.array([[8, 20, 0, 10, 0]]))[0, 0]


def test_specialise_with_recency_centres_on_late_decisions(rng) -> None:
    rs = parse_ruleset("IF range = [0, 150] THEN SET turn = 0 AND speed = 4 (strength 0.1)", "tracking")
    states = [([r, 0, 0, 0, 0], 0, True, 0) for r in range(30, 0, -1)]  # one episode closing in: range bin 30 .. 1
    exp = _exp([1], [0.9], states, 5)
    centres = []
    for _ in range(50):
        new = specialise(rs, exp, rng, low_strength=0.3, recency=0.5)
        assert new is not None
        centres.append((int(new.lo[0, 0]) + int(new.hi[0, 0])) / 2)
    assert np.mean(centres) < 8  # the last decisions (small range bins) dominate


def test_split_narrows_a_rule_to_where_it_paid(rng) -> None:
    rs = parse_ruleset("IF bearing = [340, 20] THEN SET turn = 0 AND speed = 16 (strength 0.4)", "tracking")
    far = [([r, 0, 0, 0, 0], 0, True, 0) for r in (20, 15, 10)]  # episode 0 pays 0.9: fired far out
    crash = [([r, 0, 0, 0, 0], 0, True, 1) for r in (20, 3, 1)]  # episode 1 pays 0: still fired close in
    got = split(rs, _exp([1, 1], [0.9, 0.0], far + crash, 5), rng)
    assert got is not None
    r, new = got
    assert r == 0 and new.lo[0, 0] == 4 and new.hi[0, 0] == rs.hi[0, 0]  # range cut after bin 3: [20, 150] inches
    assert (new.lo[0, 1:] == rs.lo[0, 1:]).all() and (new.hi[0, 1:] == rs.hi[0, 1:]).all()
    assert (new.action == rs.action).all()
    assert new.strength[0] == pytest.approx(0.45)  # both episodes fired on the kept side (bin 20)


def test_split_needs_a_rule_that_fired_where_it_paid_and_where_it_failed(rng) -> None:
    rs = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 16 (strength 0.4)\nIF ANY THEN SET turn = 8 AND speed = 4 (strength 0.4)", "tracking")
    paid = [([r, 0, 0, 0, 0], 0, True, 0) for r in (20, 15)]
    failed = [([r, 0, 0, 0, 0], 1, True, 1) for r in (3, 1)]
    assert split(rs, _exp([1, 2], [0.9, 0.0], paid + failed, 5), rng) is None  # each rule fired in one kind only
    assert split(rs, _exp([1, 1], [0.9, 0.5], paid + [(s, 0, f, e) for s, _, f, e in failed], 5), rng) is None  # no failure
    same = [([20, 0, 0, 0, 0], 0, True, e) for e in (0, 1)]
    assert split(rs, _exp([1, 1], [0.9, 0.0], same, 5), rng) is None  # nothing tells the two apart


def test_a_split_rule_is_narrowed_in_place_in_the_child() -> None:
    parent = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 16 (strength 0.4)\nIF ANY THEN SET turn = 8 AND speed = 4 (strength 0.3)", "tracking")
    narrowed = parse_ruleset("IF range = [20, 150] THEN SET turn = 0 AND speed = 16 (strength 0.45)", "tracking")
    child, extra = _narrow_in(parent, parent, 0, narrowed)
    assert extra == [] and len(child) == 2 and child.take([0]) == narrowed and child.take([1]) == parent.take([1])
    other = parent.take([1])  # crossover left the child without the rule: the narrowed copy joins it
    child, extra = _narrow_in(other, parent, 0, narrowed)
    assert child == other and len(extra) == 1 and extra[0] == narrowed


def test_docking_splits_rules_by_default_the_others_do_not() -> None:
    def split_rate(behaviour: str, **given: object) -> float | None:
        return ga_settings(FUEL, behaviour, GAConfig(**given)).split_rate

    assert split_rate("docking") == 0.5
    assert split_rate("tracking") == split_rate("executive") == 0.0
    assert split_rate("docking", split_rate=0.0) == 0.0
    assert split_rate("tracking", split_rate=0.2) == 0.2


def test_every_setting_left_to_the_task_is_filled_in_for_every_behaviour() -> None:
    left = [name for name, field in GAConfig.model_fields.items() if field.default is None]
    assert left, "GAConfig leaves no setting to the task"
    for behaviour in FUEL.behaviours:
        filled = ga_settings(FUEL, behaviour, GAConfig())
        assert all(getattr(filled, name) is not None for name in left), (behaviour, filled)


def test_partial_cover_widens_the_rule_that_fired(rng) -> None:
    rs = parse_ruleset("IF range = [0, 10] AND bearing = [350, 10] THEN SET turn = 24 AND speed = 4 (strength 0.5)", "tracking")
    state = [20, 10, 3, 12, 60]  # range 100, bearing 50
    exp = _exp([1], [0.7], [(state, 0, False, 0)], 5)
    new = cover(rs, exp, rng, partial=True)
    assert new is not None and new.matches(np.array([state]))[0, 0]
    assert new.lo[0, 0] == 0 and new.hi[0, 0] == 20 and new.lo[0, 1] == 70 and new.hi[0, 1] == 10
    assert (new.action == rs.action).all() and new.strength[0] == rs.strength[0]


def test_specialise_ignores_strong_rules(rng) -> None:
    rs = parse_ruleset("IF range = [25, 55] THEN SET turn = 24 AND speed = 4 (strength 0.9)", "tracking")
    exp = _exp([1], [0.8], [([8, 20, 0, 10, 0], 0, True, 0)], 5)
    assert specialise(rs, exp, rng, low_strength=0.3) is None


def test_cover_builds_a_rule_matching_the_unmatched_state(rng) -> None:
    rs = parse_ruleset("IF range = [0, 10] THEN SET turn = 24 AND speed = 4 (strength 0.5)", "tracking")
    state = [20, 40, 3, 12, 60]
    exp = _exp([1], [0.7], [(state, 0, False, 0)], 5)
    new = cover(rs, exp, rng)
    assert new is not None and new.matches(np.array([state]))[0, 0]


def test_generalise_widens(rng) -> None:
    rs = parse_ruleset("IF range = [35, 45] AND bearing = [50, 140] THEN SET turn = 24 AND speed = 4 (strength 0.9)", "tracking")
    new = generalise(rs, Experience.empty(5), rng)
    assert (interval_width(new) >= interval_width(rs)).all() and (interval_width(new) > interval_width(rs)).any()


def test_delete_drops_the_weakest_idle_rule(rng) -> None:
    rs = random_ruleset("tracking", 4, rng).replace(strength=np.array([0.5, 0.2, 0.9, 0.1]))
    out, idle = delete(rs, np.array([False, True, False, True]))
    assert len(out) == 3 and 0.1 not in out.strength.tolist() and idle.tolist() == [False, True, False]


def test_strengths_move_towards_the_payoff_of_the_episodes_they_fired_in(rng) -> None:
    rs = random_ruleset("tracking", 3, rng)
    out = update_strengths(rs, np.array([0b011, 0b001], dtype=np.uint64), np.array([1.0, 0.0]), 0.5)
    assert out.strength[0] == pytest.approx(0.5 + 0.5 * (0.5 - 0.5))
    assert out.strength[1] == pytest.approx(0.5 + 0.5 * (1.0 - 0.5))
    assert out.strength[2] == 0.5  # never fired


def test_fixed_rate_mutation_changes_about_rate_of_rules(rng) -> None:
    rs = random_ruleset("docking", 64, rng)
    changed = 0
    for _ in range(50):
        m = FixedRate(0.25).mutate(rs, rng, generation=0)
        changed += int((np.any(m.lo != rs.lo, axis=1) | np.any(m.hi != rs.hi, axis=1) | np.any(m.action != rs.action, axis=1)).sum())
    assert 0.15 < changed / (50 * 64) < 0.3  # some mutations are no-ops (a clipped end, the same action)
    with pytest.raises(ConfigError):
        FixedRate(1.5)


def test_same_seed_same_learning_curve_bit_for_bit(small_ga: GAConfig) -> None:
    def run() -> list[tuple[float, float]]:
        ga = GA(FUEL, "tracking", world=WorldConfig(), ga=small_ga, seed=7)
        reps = [ga.generation({}) for _ in range(2)]
        return [(r.best_fitness, r.population_mean) for r in reps] + [tuple(ga.best.strength.tolist())]

    assert run() == run()


def test_same_seed_same_world_outcome(world_cfg, rng) -> None:
    pols = [random_ruleset("docking", 10, np.random.default_rng(i)) for i in range(3)]
    ev = Evaluator("docking", world_cfg, GAConfig(episodes=20))
    a = ev.evaluate(pols, {}, np.random.default_rng(5))
    b = ev.evaluate(pols, {}, np.random.default_rng(5))
    for field in ("steps", "tracked", "payoff", "docked", "collided"):
        assert np.array_equal(getattr(a.details, field), getattr(b.details, field))
    assert np.array_equal(a.fitness, b.fitness)


def test_executive_needs_both_partners(world_cfg, small_ga) -> None:
    ga = GA(FUEL, "executive", world=world_cfg, ga=small_ga, seed=0)
    with pytest.raises(ConfigError, match="Tracking and Docking"):
        ga.generation({})


def test_executive_learns_against_fixed_partners(world_cfg, small_ga) -> None:
    t = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)", "tracking")
    d = parse_ruleset("IF ANY THEN SET turn = 8 AND speed = 4 (strength 0.5)", "docking")
    ga = GA(FUEL, "executive", world=world_cfg, ga=small_ga, seed=0)
    rep = ga.generation({"tracking": t, "docking": d})
    assert 0.0 <= rep.best_fitness <= 1.0 and ga.best is not None


def test_mutual_tracking_is_starved_when_the_executive_never_picks_it(world_cfg, small_ga) -> None:
    never_track = parse_ruleset("IF ANY THEN SET task = dock (strength 0.5)", "executive")
    d = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)", "docking")
    ga = GA(FUEL, "tracking", world=world_cfg, ga=small_ga, seed=0)
    rep = ga.generation({"executive": never_track, "docking": d})
    assert rep.starved == small_ga.population and rep.best_fitness == 0.0


def test_seed_policy_starts_the_population(world_cfg, small_ga) -> None:
    seed = parse_ruleset("IF ANY THEN SET turn = 0 AND speed = 4 (strength 0.5)", "tracking")
    ga = GA(FUEL, "tracking", world=world_cfg, ga=small_ga, seed=0, seed_policy=seed)
    assert ga.population[0] == seed
    with pytest.raises(ConfigError):
        GA(FUEL, "docking", world=world_cfg, ga=small_ga, seed=0, seed_policy=seed)


def test_population_rule_counts_stay_capped(world_cfg) -> None:
    cfg = GAConfig(population=6, episodes=10, best_episodes=10, initial_rules=8, max_rules=10, specialise_rate=1, cover_rate=1, generalise_rate=1)
    ga = GA(FUEL, "tracking", world=world_cfg, ga=cfg, seed=1)
    for _ in range(3):
        ga.generation({})
        assert all(1 <= len(p) <= 10 for p in ga.population)
        assert all(isinstance(p, RuleSet) for p in ga.population)


def test_replace_puts_policies_in_place_and_refuses_bad_input() -> None:
    from coevo.tasks.door import DOOR, DoorConfig, default_ruleset

    ga = GA(get_task("door"), DOOR, world=DoorConfig(), ga=GAConfig(population=6, episodes=4, best_episodes=4), seed=0)
    before = list(ga.population)
    ga.replace([1, 4], [default_ruleset(), default_ruleset()])
    assert ga.population[1] is default_ruleset() and ga.population[4] is default_ruleset()
    assert [ga.population[i] for i in (0, 2, 3, 5)] == [before[i] for i in (0, 2, 3, 5)]
    assert ga.genes.tolist() == [0] * 6
    with pytest.raises(ConfigError, match="2 indices for 1 policies"):
        ga.replace([0, 1], [default_ruleset()])
    with pytest.raises(ConfigError, match="distinct"):
        ga.replace([6], [default_ruleset()])
    with pytest.raises(ConfigError, match="cannot join"):
        ga.replace([0], [random_ruleset("tracking", 3, np.random.default_rng(0))])
