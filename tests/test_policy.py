"""Rule sets: validation, batched matching against the reference, text round trip."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coevo.errors import RuleParseError, RuleSetError
from coevo.policy import CompiledPolicies, RuleSet, format_ruleset, parse_ruleset, random_ruleset
from coevo.policy.schema import schema
from coevo.tasks.fuel.behaviours import Behaviour

BEHAVIOURS = [b.value for b in Behaviour]


@st.composite
def rulesets(draw, behaviour: str | None = None) -> RuleSet:
    beh = behaviour or draw(st.sampled_from(BEHAVIOURS))
    sch = schema(beh)
    n = draw(st.integers(1, 64))
    lo, hi = [], []
    for _ in range(n):
        lrow, hrow = [], []
        for s in sch.sensors:
            a = draw(st.integers(0, s.bins - 1))
            b = draw(st.integers(0, s.bins - 1))
            if not s.circular and a > b:
                a, b = b, a
            lrow.append(a)
            hrow.append(b)
        lo.append(lrow)
        hi.append(hrow)
    action = [[draw(st.integers(0, len(a.values) - 1)) for a in sch.actions] for _ in range(n)]
    strength = [draw(st.floats(0, 1, allow_nan=False)) for _ in range(n)]
    return RuleSet(beh, np.array(lo), np.array(hi), np.array(action), np.array(strength))


@settings(max_examples=150, deadline=None)
@given(rulesets())
def test_text_round_trip_is_exact(rs: RuleSet) -> None:
    assert parse_ruleset(format_ruleset(rs)) == rs


@settings(max_examples=60, deadline=None)
@given(st.lists(rulesets("docking"), min_size=1, max_size=4), st.integers(0, 2**32 - 1))
def test_batched_match_picks_the_strongest_full_match_or_best_partial(pols: list[RuleSet], seed: int) -> None:
    rng = np.random.default_rng(seed)
    cp = CompiledPolicies(pols)
    n = 200
    which = rng.integers(0, len(pols), n)
    bins = np.stack([rng.integers(0, s.bins, n) for s in cp.schema.sensors], axis=1).astype(np.uint8)
    rank, full = cp.decide(which, bins)
    rule = cp.rule_index(which, rank)
    for i in range(n):
        rs = pols[which[i]]
        m = rs.matches(bins[i : i + 1])[0]
        assert full[i] == m.any()
        if m.any():
            cand = np.flatnonzero(m)
        else:
            b = bins[i][None, :]
            ok = np.where(rs.lo <= rs.hi, (b >= rs.lo) & (b <= rs.hi), (b >= rs.lo) | (b <= rs.hi)).sum(axis=1)
            cand = np.flatnonzero(ok == ok.max())
        best = cand[rs.strength[cand] == rs.strength[cand].max()]
        assert rule[i] == best.min()  # ties go to the earliest rule


def test_bearing_interval_wraps_through_zero() -> None:
    rs = parse_ruleset("IF bearing = [340, 35] THEN SET turn = -24 AND speed = 4 (strength 0.8)", "tracking")
    bins = np.zeros((4, 5), dtype=np.uint8)
    bins[:, 1] = [68, 0, 7, 30]  # 340, 0, 35 degrees inside; 150 outside
    assert rs.matches(bins)[:, 0].tolist() == [True, True, True, False]


def test_report_example_parses() -> None:
    rs = parse_ruleset("IF range = [35, 45] AND bearing = [340, 35] THEN SET turn = -24 AND speed = 4 (Strength 0.8)", "tracking")
    assert len(rs) == 1 and rs.strength[0] == 0.8


@pytest.mark.parametrize(
    "text,needle",
    [
        ("IF range = [45, 35] THEN SET turn = 0 AND speed = 0 (strength 0.5)", "empty"),
        ("IF range = [35, 400] THEN SET turn = 0 AND speed = 0 (strength 0.5)", "400"),
        ("IF range = [33, 45] THEN SET turn = 0 AND speed = 0 (strength 0.5)", "33"),
        ("IF speed = [0, 5] THEN SET turn = 0 AND speed = 0 (strength 0.5)", "speed"),
        ("IF ANY THEN SET turn = 5 AND speed = 0 (strength 0.5)", "turn = 5"),
        ("IF ANY THEN SET turn = 0 (strength 0.5)", "speed"),
        ("IF ANY THEN SET turn = 0 AND speed = 0 (strength 1.5)", "1.5"),
        ("IF ANY THEN SET turn = 0 AND speed = 0 (strength nan)", "nan"),
        ("WHEN x THEN y", "expected"),
        ("", "no rules"),
    ],
)
def test_bad_rule_text_names_the_bad_value(text: str, needle: str) -> None:
    with pytest.raises(RuleParseError) as err:
        parse_ruleset(text, "tracking")
    assert needle in str(err.value)


def test_parse_error_names_the_line() -> None:
    text = "# behaviour: tracking\nIF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)\nIF range = [9, 10] THEN SET turn = 0 AND speed = 0 (strength 0.5)\n"
    with pytest.raises(RuleParseError) as err:
        parse_ruleset(text)
    assert err.value.line == 3


def test_behaviour_mismatch_is_refused() -> None:
    with pytest.raises(RuleParseError, match="tracking"):
        parse_ruleset("# behaviour: tracking\nIF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)\n", "docking")


def test_ruleset_validation_names_the_problem() -> None:
    with pytest.raises(RuleSetError, match="outside"):
        RuleSet("tracking", np.array([[0, 0, 0, 0, 99]]), np.array([[0, 0, 0, 0, 99]]), np.array([[0, 0]]), np.array([0.5]))
    with pytest.raises(RuleSetError, match="1 to 64"):
        random_ruleset("tracking", 65, np.random.default_rng(0))


def test_dict_round_trip_and_bad_dicts() -> None:
    rs = random_ruleset("executive", 5, np.random.default_rng(0))
    assert RuleSet.from_dict(rs.to_dict()) == rs
    bad = rs.to_dict() | {"lo": [[1.5, 0, 0]] * 5}
    with pytest.raises(RuleSetError):
        RuleSet.from_dict(bad)
    with pytest.raises(RuleSetError):
        RuleSet.from_dict({"behaviour": "nope"})
