"""Message codec and keys: round trips and every kind of bad payload."""

from __future__ import annotations

import math

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coevo.bus import keys
from coevo.bus.messages import MAX_BYTES, REASONS, Control, PolicyUpdate, Status, decode, encode
from coevo.errors import ConfigError, MessageError
from coevo.policy import random_ruleset


def policy_msg(**over) -> PolicyUpdate:
    rs = random_ruleset("docking", 12, np.random.default_rng(0))
    base = dict(run="r1", behaviour="docking", worker="w-1", version=3, generation=7, fitness=0.42, episodes=90,
                rules=rs.to_dict(), sent_at=1.5)
    base.update(over)
    return PolicyUpdate(**base)


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 10**6), st.integers(0, 10**4), st.floats(-1e6, 1e6, allow_nan=False), st.integers(0, 2**32 - 1))
def test_policy_round_trip(version: int, gen: int, fitness: float, seed: int) -> None:
    rs = random_ruleset("tracking", 1 + seed % 64, np.random.default_rng(seed))
    m = PolicyUpdate(run="run.1", behaviour="tracking", worker="t0", version=version, generation=gen, fitness=fitness,
                     episodes=90, rules=rs.to_dict(), sent_at=0.0)
    back = decode(encode(m), key=keys.policy("run.1", "tracking"))
    assert back == m and back.ruleset() == rs


def test_status_and_control_round_trip() -> None:
    s = Status(run="r", behaviour="executive", worker="e0", regime="mutual", generation=3, generations=50,
               best_fitness=0.7, partner_versions={"tracking": 2}, rejected={"invalid": 1}, sent_at=2.0)
    assert decode(encode(s), key=keys.status("r", "executive", "e0")) == s
    c = Control(run="r", command="stop", sent_at=3.0)
    assert decode(encode(c), key=keys.control("r")) == c


@pytest.mark.parametrize(
    "payload,reason",
    [
        (b"\xc1\xc1garbage", "not_msgpack"),
        (encode(policy_msg())[:-7], "truncated"),
        (msgpack.packb([1, 2, 3]), "invalid"),
        (msgpack.packb({"kind": "policy", "schema_version": 1, "run": "r1"}), "invalid"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"), "schema_version": 99}), "schema_version"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"), "fitness": math.nan}), "non_finite"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"), "fitness": math.inf}), "non_finite"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"), "fitness": "high"}), "invalid"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"), "extra": 1}), "invalid"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"), "rules": {"behaviour": "docking", "lo": [[200] * 8],
                        "hi": [[0] * 8], "action": [[0, 0]], "strength": [0.5]}}), "bad_rules"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"),
                        "rules": random_ruleset("tracking", 3, np.random.default_rng(1)).to_dict()}), "bad_rules"),
        (msgpack.packb({**policy_msg().model_dump(mode="json"), "version": [3]}), "invalid"),
        (b"\x00" * (MAX_BYTES + 1), "oversize"),
    ],
)
def test_bad_payloads_are_rejected_with_a_reason(payload: bytes, reason: str) -> None:
    with pytest.raises(MessageError) as err:
        decode(payload, key=keys.policy("r1", "docking"))
    assert err.value.reason == reason and reason in REASONS


def test_message_on_the_wrong_key_or_run_is_rejected() -> None:
    data = encode(policy_msg())
    with pytest.raises(MessageError) as err:
        decode(data, key=keys.policy("r1", "tracking"))  # a docking policy on tracking's key
    assert err.value.reason == "wrong_behaviour"
    with pytest.raises(MessageError) as err:
        decode(data, key=keys.status("r1", "docking", "w-1"))  # a policy on a status key
    assert err.value.reason == "wrong_key"
    with pytest.raises(MessageError) as err:
        decode(data, key=keys.policy("other", "docking"))
    assert err.value.reason == "wrong_run"


def test_keys_are_built_and_parsed_consistently() -> None:
    assert keys.policy("r1", "tracking") == "coevo/r1/policy/tracking"
    assert keys.policy("r1") == "coevo/r1/policy/*"
    assert keys.parse(keys.status("r1", "docking", "w2")) == {"run": "r1", "topic": "status", "behaviour": "docking", "worker": "w2"}
    assert keys.parse(keys.store_latest("r1", "docking"))["topic"] == "store/latest"
    for bad in ("", "a/b", "a*", "..", "x" * 65):
        with pytest.raises(ConfigError):
            keys.policy(bad)
    with pytest.raises(ConfigError):
        keys.policy("r", "flying")
