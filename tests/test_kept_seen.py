"""The broker's memory of the messages it took (store/seen.log, :class:`coevo.bus.freshness.KeptSeen`) is bounded:
compacted once it outgrows what the memory needs, atomically, and a receiver started again from the compacted file
still refuses every replay the uncompacted one refused (issue 54).  In process, with real sealed envelopes; the
broker process killed and started again is tests/test_faults.py's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from coevo.bus import keys
from coevo.bus.auth import RunKey
from coevo.bus.freshness import WINDOW, KeptSeen
from coevo.bus.messages import PolicyUpdate
from coevo.bus.trust import Gate
from coevo.errors import MessageError
from coevo.policy import random_ruleset

RUN = "kept"


def _receiver(key: RunKey, path: Path, limit: int) -> Gate:
    gate = Gate(key=key)
    gate.fresh.seen = KeptSeen(path, limit=limit)
    return gate


RULES = {b: random_ruleset(b, 2, np.random.default_rng(0)).to_dict() for b in ("tracking", "docking")}


def _beat(n: int, behaviour: str = "tracking") -> PolicyUpdate:
    return PolicyUpdate(run=RUN, behaviour=behaviour, worker=f"{behaviour}-0", version=n + 1, generation=n + 1,
                        fitness=0.5, episodes=1, rules=RULES[behaviour], sent_at=0.0)


def _refused(gate: Gate, key_expr: str, payload: bytes) -> str | None:
    try:
        gate.decode(key_expr, payload)
    except MessageError as exc:
        return exc.reason
    return None


def _flood(seen: KeptSeen, n: int) -> None:
    """``n`` messages of another sender taken on another key: what makes the file outgrow the memory."""
    for seq in range(1, n + 1):
        seen.admit("coevo/kept/policy/docking", (0, 1.0, "other"), seq)


def test_a_compacted_seen_log_stays_bounded_and_a_restart_still_refuses_every_replay(tmp_path: Path) -> None:
    key = RunKey.create(RUN)
    path = tmp_path / "store" / "seen.log"
    sender = Gate(key=key)
    ka = keys.policy(RUN, "tracking")
    sent = [sender.seal(_beat(n), ka) for n in range(300)]  # more than WINDOW: the oldest are refused as below it
    broker = _receiver(key, path, limit=100)
    for payload in sent:
        assert _refused(broker, ka, payload) is None
    _flood(broker.fresh.seen, 3000)
    lines = path.read_text().splitlines()
    assert len(lines) <= 2 * (2 * WINDOW + 300) + 1, len(lines)  # bounded: not 3,300
    assert not path.with_name("seen.log.new").exists()
    assert all(len(json.loads(x)) == 5 for x in lines)

    again = _receiver(key, path, limit=100)  # the broker started again from the compacted file
    assert {_refused(again, ka, payload) for payload in sent} == {"replayed"}
    assert _refused(again, ka, sender.seal(_beat(300), ka)) is None  # a new genuine message is taken


def test_compaction_is_atomic_a_leftover_of_a_crash_changes_nothing(tmp_path: Path) -> None:
    """A crash while compacting leaves a torn ``seen.log.new`` beside the whole old file: the old file is read, the
    leftover is written over at the next compaction."""
    key = RunKey.create(RUN)
    path = tmp_path / "seen.log"
    sender = Gate(key=key)
    ka = keys.policy(RUN, "tracking")
    sent = [sender.seal(_beat(n), ka) for n in range(20)]
    broker = _receiver(key, path, limit=10**6)
    for payload in sent:
        broker.decode(ka, payload)
    _flood(broker.fresh.seen, 1500)
    before = path.read_bytes()
    path.with_name("seen.log.new").write_text('["torn", 1, 2')
    again = _receiver(key, path, limit=10**6)
    assert path.read_bytes() == before
    assert {_refused(again, ka, p) for p in sent} == {"replayed"}
    KeptSeen(path, limit=5)  # compacts on making: the leftover replaced, the file whole
    assert not path.with_name("seen.log.new").exists()
    assert len(path.read_bytes()) < len(before)
    assert {_refused(_receiver(key, path, limit=5), ka, p) for p in sent} == {"replayed"}
