"""Pacing: a worker stays at most ``max_lead`` generations ahead of its partners.

The report ran each agent's GA on its own processor, and their generations took
comparable time, so the three learning curves advance together (its Figures 5
and 6 share one generation axis).  Here the agents' generations cost very
different amounts: in the Independent regime the Executive can finish all 50 of
its generations while Tracking and Docking are still at their tenth, and then it
has only learned against near-random partners.  Pacing *(ours, on by default
with a lead of 1 generation)* restores the report's setting without making the
run synchronous: each worker still runs at its own pace and adopts whatever
arrived, but before starting generation ``g+1`` it waits until every partner it
models has reported finishing generation ``g - max_lead`` (or finished its run,
or is absent).  A partner is absent once its liveliness token has been gone for
``settle`` seconds while the broker is up (it died), when it has shown neither a
token nor a heartbeat within ``grace`` seconds of this worker's start (it finished
before this worker was restarted, or was never started), and after ``wait_limit``
seconds of waiting for one that stopped reporting: a dead partner must not stall
the others.  It is waited for again once it is back (a resumed worker), so the run
closes up again behind it.

A broker outage is not a death: the broker is the router that carries every
token, so when it goes, every partner's token goes with it at once.  While a
broker was seen and none is present now (neither ``coevo/_broker`` nor
``coevo/_broker/degraded``), partners whose tokens went are *unknown*, not gone:
the worker keeps to ``max_lead`` and waits for them, up to ``wait_limit``, as for
any partner that stopped reporting.  ``settle`` covers the moment between the
partners' tokens and the broker's going, which arrive in either order.  The two
modules of a CEL run give each other a longer ``settle`` and ``grace``, a restart's time
(:mod:`coevo.cel_service.robot`, :mod:`coevo.cel_service.learner`).  Progress is read from the partners' status
heartbeats, kept in rings inside Zenoh (no Python runs per heartbeat, so a flood
on the status keys cannot slow the worker), so pacing needs nothing beyond what
status already publishes.  While it waits, the worker
keeps its own heartbeat going (``tick``), so status never mistakes a paced worker
for a stalled one and its rejection counts stay current.  ``max_lead=None`` turns
it off.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable

from coevo.bus import keys
from coevo.bus.messages import Message, Status
from coevo.bus.session import Sample, Session, drain_messages, is_put, ring_subscriber
from coevo.config import DEFAULT_MAX_LEAD, parse_max_lead

__all__ = ["DEFAULT_MAX_LEAD", "Pacer", "parse_max_lead"]

log = logging.getLogger(__name__)

class Pacer:
    """Follows the partners' heartbeats and liveliness and holds a worker back when it is too far ahead."""

    def __init__(self, session: Session, run: str, partners: Iterable[str], *, max_lead: int | None,
                 wait_limit: float = 120.0, grace: float = 10.0, settle: float = 0.5) -> None:
        self.run = run
        self.partners = tuple(partners)
        self.max_lead = max_lead
        self.wait_limit = wait_limit
        self.grace = grace
        self.settle = settle
        self.waited = 0.0
        self._t0 = time.monotonic()
        self._seen: set[str] = set()
        self._progress: dict[str, int] = {b: 0 for b in self.partners}
        self._finished: set[str] = set()
        self._absent: set[str] = set()  # stopped reporting (wait_limit passed): back with a heartbeat
        self._gone: dict[str, float] = {}  # its token went (dead, or cut off) -> when: back only with a token
        self._brokers: set[str] = set()  # the broker tokens present (up or degraded)
        self._broker_seen = False
        self._outage_noted = False
        self._live: dict[str, set[str]] = {b: set() for b in self.partners}
        self._lock = threading.Lock()
        on = max_lead is not None and bool(self.partners)
        self._subs = [ring_subscriber(session, self._status_key(b), 64) for b in self.partners] if on else []
        self._tokens = [session.liveliness().declare_subscriber(k, cb, history=True)
                        for k, cb in ((self._alive_key(), self._on_token), (keys.BROKER, self._on_broker),
                                      (keys.BROKER_DEGRADED, self._on_broker))] if on else []

    # What a partner is, on the bus: a behaviour's worker (a subclass paces by another kind of process).
    def _status_key(self, partner: str) -> str:
        return keys.status(self.run, partner)

    def _alive_key(self) -> str:
        return keys.alive(self.run)

    def _token_partner(self, parts: dict[str, str]) -> tuple[str, str]:
        """(partner, process id) of a liveliness token's key parts."""
        return parts.get("behaviour", ""), parts.get("worker", "")

    def _progress_of(self, msg: Message) -> tuple[str, int, bool] | None:
        """(partner, generations completed, finished) of a heartbeat; None for anything else."""
        if not isinstance(msg, Status):
            return None
        return msg.behaviour, msg.generation, msg.done or msg.generation >= msg.generations

    def _on_broker(self, sample: Sample) -> None:
        key = str(sample.key_expr)
        with self._lock:
            if is_put(sample):
                self._brokers.add(key)
                self._broker_seen = True
            else:
                self._brokers.discard(key)

    def _on_token(self, sample: Sample) -> None:
        beh, who = self._token_partner(keys.parse(str(sample.key_expr)))
        if beh not in self._live:
            return
        with self._lock:
            if is_put(sample):
                self._live[beh].add(who)
                self._gone.pop(beh, None)
                self._absent.discard(beh)
                self._seen.add(beh)
            else:
                self._live[beh].discard(who)
                if not self._live[beh]:
                    self._gone[beh] = time.monotonic()  # a heartbeat still in the ring must not bring it back

    def _poll(self) -> None:
        for sub in self._subs:
            # Bad messages on the status keys are not pacing's business (status counts them): skipped.
            for _, msg in drain_messages(sub, 64):
                got = self._progress_of(msg)
                if got is None or got[0] not in self._progress:
                    continue
                who, generation, finished = got
                with self._lock:
                    self._progress[who] = max(self._progress[who], generation)
                    if finished:
                        self._finished.add(who)
                    self._absent.discard(who)
                    self._seen.add(who)

    @property
    def outage(self) -> bool:
        """A broker was seen and none is present: partners' tokens say nothing now."""
        with self._lock:
            return self._broker_seen and not self._brokers

    def _dead(self, b: str, now: float, outage: bool) -> bool:
        went = self._gone.get(b)
        return went is not None and not outage and now - went >= self.settle

    def _behind(self, need: int) -> list[str]:
        now = time.monotonic()
        late = now - self._t0 > self.grace
        outage = self.outage
        with self._lock:
            behind = [b for b in self.partners
                      if b not in self._finished and b not in self._absent and not self._dead(b, now, outage)
                      and self._progress[b] < need and not (late and b not in self._seen)]
        if outage and behind and not self._outage_noted:
            log.warning("pacing: the broker is down; partners %s unknown, not gone: waiting for them (up to %.0f s)",
                        behind, self.wait_limit)
            self._outage_noted = True
        elif not outage:
            self._outage_noted = False  # once per outage
        return behind

    def progress(self, partner: str) -> int:
        """The generations ``partner`` reported completing (its latest heartbeat)."""
        self._poll()
        with self._lock:
            return self._progress[partner]

    def wait(self, completed: int, stop: threading.Event, tick: Callable[[], None] | None = None,
             tick_every: float = 1.0, poll: float = 0.05) -> float:
        """Block before the generation after ``completed`` ones until the partners are close enough.

        ``tick`` is called about every ``tick_every`` seconds while waiting.
        """
        if not self._subs or self.max_lead is None:
            return 0.0
        need = completed - self.max_lead
        t0 = time.monotonic()
        end = t0 + self.wait_limit
        next_tick = t0 + tick_every
        while True:
            self._poll()
            behind = self._behind(need)
            if not behind or stop.is_set():
                break
            now = time.monotonic()
            if now >= end:
                log.warning("pacing: partners %s still behind generation %d after %.0f s; going on "
                            "without waiting for them until they report again",
                            [b for b in behind], need, self.wait_limit)
                with self._lock:
                    self._absent.update(behind)
                break
            stop.wait(poll)
            if tick is not None and time.monotonic() >= next_tick:
                tick()
                next_tick = time.monotonic() + tick_every
        waited = time.monotonic() - t0
        self.waited += waited
        return waited

    def __enter__(self) -> Pacer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for s in self._subs + self._tokens:
            s.undeclare()
        self._subs, self._tokens = [], []
