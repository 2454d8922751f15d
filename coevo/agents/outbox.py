"""What a worker publishes, and the store's confirmation that it holds it.

Delivery to the store: a put nobody hears is lost silently (a broker that is down
or restarting).  The worker follows the broker's liveliness token
(:class:`BrokerWatch`) and, while the broker is up, asks its store which versions
it holds; what is missing the :class:`Outbox` publishes again from its log
(``published.jsonl``, every version in full, fsynced before anything leaves).  So a
broker killed and restarted, or messages dropped on the way, leave the store's
history complete once the broker is back.

A broker that holds no key for an open run (one started without ``--key-file``) and
is not ``--open`` stores nothing of it and counts its policies ``unauthenticated``;
its status for the run says so, and the watch (given the run) tells the worker at
once, so a hand-started run does not learn for an hour into a store that refuses it.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from pathlib import Path
from collections.abc import Callable
from typing import IO

import msgpack

from coevo.bus import keys
from coevo.bus.messages import BrokerStatus, PolicyUpdate
from coevo.bus.session import CallbackSubscriber, Publisher, Sample, Session, is_put, query
from coevo.bus.trust import OPEN, Gate
from coevo.errors import MessageError
from coevo.rundir.layout import append_durably, read_store

__all__ = ["BrokerWatch", "Outbox"]

log = logging.getLogger(__name__)


class BrokerWatch:
    """Follows the broker's liveliness token: is a broker with its store up, and did it just (re)appear?  Given an
    open ``run``, also the broker's status of it: does the broker refuse to store it (:attr:`refused`)?"""

    def __init__(self, session: Session, run: str | None = None, gate: Gate = OPEN) -> None:
        self._session = session
        self.up = threading.Event()
        self.back = threading.Event()  # the broker (re)appeared: ask its store what it holds
        self.refused = threading.Event()  # the broker stores nothing of this open run (it holds no key for it)
        self._run = run if gate.open else None  # a keyed run's broker holds its key: coevo keygen put it there
        self._subs: list[CallbackSubscriber] = []

    def __enter__(self) -> BrokerWatch:
        self._subs.append(self._session.liveliness().declare_subscriber(keys.BROKER, self._on_token, history=True))
        if self._run is not None:
            self._subs.append(self._session.declare_subscriber(keys.broker_status(self._run), self._on_status))
        return self

    def _on_token(self, sample: Sample) -> None:
        if is_put(sample):
            self.up.set()
            self.back.set()
        else:
            self.up.clear()

    def _on_status(self, sample: Sample) -> None:
        """An open run's broker status: refused when the broker counts its policies unauthenticated and stores none."""
        try:
            msg = OPEN.decode(str(sample.key_expr), sample.payload.to_bytes())
        except MessageError:
            return  # not a status this worker can read: it says nothing of the store
        if not isinstance(msg, BrokerStatus) or self.refused.is_set():
            return
        if msg.rejected.get("unauthenticated", 0) > 0 and not any(msg.stored.values()):
            self.refused.set()
            log.error("run %s has no key and the broker refuses to store it (%d policies counted 'unauthenticated', "
                      "none stored): start the broker with --open, or make a key (coevo keygen) and give it to the "
                      "broker (DATA_DIR/%s/secret.key) and every worker (--key-file)",
                      self._run, msg.rejected["unauthenticated"], self._run)

    def wait(self, timeout: float, stop: threading.Event) -> bool:
        """Wait up to ``timeout`` s for a broker (the watch's history reports one already there); False if none came."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and not stop.is_set():
            if self.up.wait(0.2):
                return True
        return self.up.is_set()

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self._subs = []

    def __exit__(self, *exc: object) -> None:
        self.close()


class Outbox:
    """A worker's publications: the log of every version, the puts, and the store sync."""

    def __init__(self, session: Session, broker: BrokerWatch, *, run: str, behaviour: str, worker_id: str, log_path: Path,
                 store_timeout: float = 2.0, confirm_every: float = 2.0, gate: Gate = OPEN) -> None:
        self._session, self.broker = session, broker
        self.gate = gate  # seals what this worker publishes; checks the store's answers
        self.run, self.behaviour, self.worker_id = run, behaviour, worker_id
        self.log_path = Path(log_path)
        self.store_timeout, self.confirm_every = store_timeout, confirm_every
        self.published: dict[int, PolicyUpdate] = {}  # version -> policy (sealed afresh at every put: freshness)
        self.stored: set[int] = set()  # versions the store confirmed holding
        self.republished = 0
        self.net_seconds = 0.0
        self._last_query = -math.inf  # monotonic time the store was last asked what it holds
        self._log: IO[str] | None = None
        self._pub: Publisher | None = None
        self._current: Publisher | None = None
        self._policy_key = keys.policy(run, behaviour)
        for msg in read_store(self.log_path):  # the outbox log holds stored-policy lines, like the store's files
            self.published[msg.version] = msg

    def __enter__(self) -> Outbox:
        self._log = open(self.log_path, "a", encoding="utf-8")
        self._pub = self._session.declare_publisher(keys.policy(self.run, self.behaviour))
        self._current = self._session.declare_publisher(keys.current(self.run, self.behaviour))
        return self

    def close(self) -> None:
        for name in ("_pub", "_current"):
            pub = getattr(self, name)
            if pub is not None:
                pub.undeclare()
                setattr(self, name, None)
        if self._log is not None:
            self._log.close()
            self._log = None

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def next_version(self) -> int:
        return len(self.published) + 1

    @property
    def top(self) -> int:
        return max(self.published, default=0)

    @property
    def unconfirmed(self) -> list[int]:
        return sorted(set(self.published) - self.stored)

    def record(self, msg: PolicyUpdate) -> None:
        """Log a new version (fsynced) before anything of it leaves: the outbox survives a crash."""
        if self._log is None:
            raise RuntimeError("the outbox is closed")
        append_durably(self._log, msg.model_dump(mode="json"))
        self.published[msg.version] = msg

    def _publisher(self, which: Publisher | None) -> Publisher:
        if which is None:
            raise RuntimeError("the outbox is closed")
        return which

    def put_current(self, msg: PolicyUpdate) -> None:
        """The current generation's best, on its own key (the ``current`` partner model); not stored."""
        self._publisher(self._current).put(self.gate.seal(msg, keys.current(self.run, self.behaviour)))

    def put_latest(self) -> None:
        """The newest version; every generation, not only on improvement: partners that missed a put catch up."""
        if self.published:
            self._publisher(self._pub).put(self.gate.seal(self.published[self.top], self._policy_key))

    def sync(self, *, upto: int, now: bool = False) -> bool:
        """Make sure the store holds every version up to ``upto``; republish what it lacks.  True if it does.

        Asks the store only when there is something unconfirmed or the broker has
        just (re)appeared, at most once per ``confirm_every`` seconds unless ``now``
        or the broker is back, and never while the broker is down (a query would
        wait for its timeout).  The newest version is confirmed a generation later,
        so the check never races the put that carries it.
        """
        if not self.broker.up.is_set():
            return False
        back = self.broker.back.is_set()
        if not back and all(v in self.stored for v in self.published if v <= upto):
            return True
        if not (back or now) and time.monotonic() - self._last_query < self.confirm_every:
            return False
        self.broker.back.clear()
        self._last_query = time.monotonic()
        have = self._store_versions()
        if have is None:
            return False
        self.stored = have & set(self.published)
        missing = sorted(v for v in self.published if v <= upto and v not in have)
        for v in missing:
            self._publisher(self._pub).put(self.gate.seal(self.published[v], self._policy_key))
        if missing:
            self.republished += len(missing)
            log.info("%s republished versions %s the store lacked", self.worker_id, missing)
        return not missing

    def final_sync(self, timeout: float, stop: threading.Event, beat: Callable[[], None]) -> None:
        """Before saying done: wait (up to ``timeout`` s) until the store holds every version."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and not stop.is_set():
            if self.sync(upto=self.top, now=True):
                return
            beat()
            time.sleep(0.2)
        if self.unconfirmed:
            log.warning("%s: the broker's store has not confirmed versions %s after %.0f s; they stay in %s",
                        self.worker_id, self.unconfirmed, timeout, self.log_path)

    def _store_versions(self) -> set[int] | None:
        """The versions of this worker's policies the store holds; None if it did not answer."""
        for key, payload in query(self._session, keys.store_versions(self.run, self.behaviour), timeout=self.store_timeout,
                                  what="store versions"):
            try:
                data = msgpack.unpackb(self.gate.unseal(payload, key), raw=False)
                return {int(v) for v in data.get("workers", {}).get(self.worker_id, [])}
            except MessageError as err:  # not the broker's answer: it confirms nothing
                if self.gate.reject is not None:
                    self.gate.reject(err, key)
            except (ValueError, TypeError, AttributeError, msgpack.UnpackException) as exc:
                log.warning("%s: the store's versions reply is unreadable: %s", self.worker_id, exc)
        return None
