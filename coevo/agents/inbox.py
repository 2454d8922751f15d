"""What arrives for a worker: its partners' policies and the run's control messages.

Partner policies wait in rings of the newest few inside Zenoh (no Python runs per
arriving message, so a flood cannot slow the GA); between generations the
:class:`Inbox` decodes and validates them, keeps the newest version of each
partner, hands it to the partner models and logs the adoption (what ``coevo
replay`` needs).  A late, restarted or flooded worker also asks the broker's store
for its partners' latest.

Every message passes the run's :class:`~coevo.bus.trust.Gate` (key, roster, version
bounds); on top, a partner's versions must follow its own sequence: a version
``v`` at generation ``g`` after the held ``v0`` at ``g0`` needs ``v - v0 <= g - g0``
(one version per generation at most), so no message can claim a version its
publisher cannot have reached yet, and none can freeze a partner model.
"""

from __future__ import annotations

import hashlib
import json
import logging
import threading
import time
from collections.abc import Callable
from typing import IO, Any

from coevo.agents.models import PartnerModels
from coevo.agents.outbox import BrokerWatch
from coevo.bus import keys
from coevo.bus.messages import Control, PolicyUpdate
from coevo.bus.session import Ring, Session, drain, drain_messages, query, ring_subscriber
from coevo.bus.trust import OPEN, Gate
from coevo.errors import MessageError, ServiceError
from coevo.policy.rules import RuleSet

__all__ = ["Inbox", "INBOX", "rules_digest"]

log = logging.getLogger(__name__)

INBOX = 32  # newest partner messages kept per key between two generations


def rules_digest(rules: dict[str, Any]) -> str:
    """sha256 of a rule set's canonical JSON (sorted keys, no spaces): what ``coevo check`` compares."""
    return hashlib.sha256(json.dumps(rules, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


class Inbox:
    """A worker's subscriptions: partner policies (adopted between generations) and control (stop)."""

    def __init__(self, session: Session, broker: BrokerWatch, *, run: str, models: PartnerModels, adoptions: IO[str],
                 reject: Callable[[MessageError, str], None], store_timeout: float = 2.0, gate: Gate = OPEN) -> None:
        self._session, self.broker = session, broker
        self.gate = gate
        self._held: dict[str, tuple[int, int]] = {}  # partner -> (version, generation) of the policy adopted last
        self.run, self.models, self._adoptions, self._reject = run, models, adoptions, reject
        self.store_timeout = store_timeout
        self.stop = threading.Event()
        self.refetch = True  # ask the store for the partners' latest before the next generation
        self._fetched: list[tuple[str, bytes]] = []  # partner policies fetched from the store
        self._partner_key = keys.current if models.generational else keys.policy
        self._subs: list[Ring] = []
        self._control: Ring | None = None

    def __enter__(self) -> Inbox:
        self._subs = [ring_subscriber(self._session, self._partner_key(self.run, b), INBOX) for b in self.models.needed]
        self._control = ring_subscriber(self._session, keys.control(self.run), 64)
        return self

    def close(self) -> None:
        for sub in (*self._subs, self._control):
            if sub is not None:
                sub.undeclare()
        self._subs, self._control = [], None

    def __exit__(self, *exc: object) -> None:
        self.close()

    def stop_requested(self) -> bool:
        """Has a stop arrived on the run's control key (or been asked for locally)?"""
        if self._control is not None:
            for _, msg in drain_messages(self._control, 64, self._reject):
                if isinstance(msg, Control) and msg.command == "stop":
                    self.stop.set()
        return self.stop.is_set()

    def fetch(self) -> None:
        """If asked to: the partners' current best from the broker's store (a late, restarted or flooded worker)."""
        if not self.refetch:
            return
        self.refetch = False
        if self.models.generational or not self.models.needed or not self.broker.up.is_set():
            return  # current policies are not stored; the next generation's arrives within a generation
        for b in self.models.needed:
            try:
                # Kept with the key they were answered on: the store seals its replies for that key.
                self._fetched += query(self._session, keys.store_latest(self.run, b), timeout=self.store_timeout,
                                       what=f"the store's latest {b}")
            except ServiceError as exc:  # the broker went away meanwhile: the subscription will catch up
                log.info("%s", exc)

    def _in_sequence(self, msg: PolicyUpdate) -> None:
        """A version beyond what its publisher can have reached since the one held is ``bad_version``."""
        held = self._held.get(msg.behaviour)
        if held is None or msg.version <= held[0] or self.models.generational:
            return  # "current" versions are generations, checked by the gate
        if msg.version - held[0] > msg.generation - held[1]:
            raise MessageError("bad_version", f"{msg.behaviour} v{msg.version} at generation {msg.generation} after "
                                              f"v{held[0]} at generation {held[1]}: more versions than generations")

    def adopt(self, generation: int) -> None:
        """Take the newest valid version of each partner that arrived; log each adoption."""
        items = [(k, p, None) for k, p in self._fetched]  # store replies: the gate's memory
        self._fetched = []
        for sub in self._subs:
            got = drain(sub, INBOX)
            if len(got) == INBOX:  # the ring was full: older messages were dropped unread
                self._reject(MessageError("flood", f"over {INBOX} messages on {got[0][0]!r} within one generation"), got[0][0])
                self.refetch = True
            items += [(k, p, getattr(sub, "seen", None)) for k, p in got]
        newest: dict[str, tuple[PolicyUpdate, RuleSet]] = {}
        for key, payload, seen in items:
            try:
                msg = self.gate.decode(key, payload, seen)  # a replayed or stale one is refused (and counted) here
                if not isinstance(msg, PolicyUpdate) or msg.behaviour not in self.models.needed:
                    raise MessageError("wrong_key", f"{msg.kind} of {getattr(msg, 'behaviour', '?')} on {key!r}")
                self._in_sequence(msg)
                rules = msg.ruleset()
            except MessageError as err:
                self._reject(err, key)
                continue
            cur = newest.get(msg.behaviour)
            if cur is None or msg.version > cur[0].version:
                newest[msg.behaviour] = (msg, rules)
        for beh, (msg, rules) in newest.items():
            if self.models.adopt(beh, msg.version, rules):
                self._held[beh] = (msg.version, msg.generation)
                entry = {
                    "generation": generation, "partner": beh, "version": msg.version,
                    "from_worker": msg.worker, "fitness": msg.fitness, "received_at": time.time(),
                    "rules": msg.rules,  # so a replay needs nothing but this log
                    "rules_digest": rules_digest(msg.rules),  # what coevo check compares with the partner's published.jsonl
                }
                self._adoptions.write(json.dumps(entry) + "\n")
                self._adoptions.flush()
