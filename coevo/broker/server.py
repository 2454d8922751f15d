"""``coevo broker``: the Zenoh router workers meet at, plus the policy store.

A Python zenoh session in router mode (there is no zenohd here) listens for
clients.  Subscribers on ``coevo/*/policy/*`` (and ``coevo/*/case/*``, a CEL run's
case base) feed a bounded inbox; one thread
decodes, validates and stores what arrives (the callback only checks the size and
queues, so a slow disk never stalls the connection).  The inbox holds at most
``inbox_bytes`` bytes: a flood beyond that is dropped unread and counted
(``flood``), and the workers' store sync republishes any real policy that was
among it.  Queryables on ``coevo/*/store/{latest,history,versions,cases}/*`` answer from
memory, which holds only what was fsynced (:mod:`coevo.broker.store`).  Every
``status_every`` seconds the broker publishes, for each run it has heard of, a
:class:`~coevo.bus.messages.BrokerStatus` (policies stored, messages rejected by
reason, and whether the store is degraded) on ``coevo/RUN/broker``.

The broker holds one liveliness token: ``coevo/_broker`` while its store writes,
``coevo/_broker/degraded`` while a write error stands.  Workers follow the first
only, so they stop asking a degraded store for confirmations (and keep their
versions for later) until it writes again; ``coevo status`` shows *degraded*.

Trust (:class:`Keyring`): the broker learns a run's key from its own data
directory, ``DATA_DIR/RUN/secret.key`` (``coevo run`` writes it there; on other
hosts copy it there, see deploy/README.md), and the run's roster and generations
from ``DATA_DIR/RUN/run.json`` when that is there too.  A run it holds a key for is
verified like a worker verifies it, and everything the broker says about it (store
replies, versions, its status) is sealed with that key.  A run it holds no key for
is refused: nothing of it is stored, every policy counts as ``unauthenticated`` —
unless the broker runs with ``--open``, which stores such runs unverified and marks
them ``open`` in its status.
"""

from __future__ import annotations

import argparse
import logging
import queue
import threading
import time
from pathlib import Path

import msgpack

from coevo.broker.store import PolicyStore, Quota
from coevo.bus import keys
from coevo.bus.auth import RunKey
from coevo.bus.freshness import KeptSeen
from coevo.bus.lifecycle import Lifecycle, main_of
from coevo.bus.messages import MAX_BYTES, BrokerStatus, CaseUpdate, PolicyUpdate
from coevo.bus.session import Config, LivelinessToken, Query, Sample, Session, SessionGone, config_from_args
from coevo.bus.trust import OPEN, Gate
from coevo.errors import CoevoError, MessageError
from coevo.rundir.layout import RunPaths

__all__ = ["Broker", "Keyring", "serve_broker", "serve_router"]

log = logging.getLogger(__name__)


class Keyring:
    """The gates of the runs a broker serves, from the run keys in its data directory.

    A run's key is looked for when the run is first heard of and, while it is missing, again
    at most every ``retry`` seconds (so a key copied in later is picked up without a restart).
    """

    def __init__(self, data_dir: Path, *, open_runs: bool = False, retry: float = 2.0) -> None:
        self.data_dir = Path(data_dir)
        self.open_runs = open_runs
        self.retry = retry
        self._gates: dict[str, Gate] = {}
        self._missing: dict[str, float] = {}  # run -> monotonic time its key was last looked for
        self._lock = threading.Lock()

    def gate(self, run: str) -> Gate | None:
        """The run's gate; None when the broker holds no key for it and is not ``--open`` (refuse it)."""
        with self._lock:
            gate = self._gates.get(run)
            if gate is not None:
                return gate
            last = self._missing.get(run)
            if last is not None and time.monotonic() - last < self.retry:
                return OPEN if self.open_runs else None
            gate = self._load(run)
            if gate is None:
                if last is None:
                    if self.open_runs:
                        log.warning("run %s is OPEN on this broker: no key in %s, its policies are stored "
                                    "unauthenticated", run, RunPaths.of(self.data_dir, run).key_file)
                    else:
                        log.warning("run %s: no key at %s; nothing of it is stored (copy the run's key there, or "
                                    "start the broker with --open)", run, RunPaths.of(self.data_dir, run).key_file)
                self._missing[run] = time.monotonic()
                return OPEN if self.open_runs else None
            self._missing.pop(run, None)
            self._gates[run] = gate
            return gate

    def _load(self, run: str) -> Gate | None:
        if not keys.valid_id(run):
            return None
        paths = RunPaths.of(self.data_dir, run)
        if not paths.key_file.exists():
            return None
        try:
            key = RunKey.load(paths.key_file, run=run)
        except CoevoError as exc:
            log.error("run %s: %s; its messages are refused", run, exc)
            return None
        gate = Gate(key=key)
        if paths.run_json.exists():
            try:
                from coevo.rundir.settings import RunSettings

                gate = RunSettings.load(paths.run_json).gate(key)
            except CoevoError as exc:
                log.warning("run %s: %s; checking its key only, not its roster", run, exc)
        gate.fresh.seen = KeptSeen(paths.seen_file)  # what it took before a restart is still refused as a replay
        log.info("run %s: key loaded%s", run, ", roster " + str(gate.roster) if gate.roster else "")
        return gate


#: What a broker that is not open reads as its stop: set.
_STOPPED = threading.Event()
_STOPPED.set()


class Broker:
    """Router + store; use as a context manager, or call :meth:`serve_forever`."""

    def __init__(self, conf: Config, data_dir: Path, *, inbox_bytes: int = 64 << 20, status_every: float = 2.0,
                 open_runs: bool = False, quota: Quota | None = None) -> None:
        self.conf = conf
        self.store = PolicyStore(Path(data_dir), quota=quota)
        self.keyring = Keyring(Path(data_dir), open_runs=open_runs)
        self.inbox_bytes = inbox_bytes
        self.status_every = status_every
        self._inbox: queue.Queue[tuple[str, bytes] | None] = queue.Queue()
        self._queued = 0  # bytes waiting in the inbox
        self._qlock = threading.Lock()
        self._life: Lifecycle | None = None
        self._token: LivelinessToken | None = None
        self._token_key = ""
        self._token_lock = threading.Lock()

    @property
    def session(self) -> Session:
        if self._life is None:
            raise RuntimeError("the broker is not open (use it as a context manager)")
        return self._life.session

    def __enter__(self) -> Broker:
        life = self._life = Lifecycle(self.conf, what="router").__enter__()
        try:
            s = life.session
            life.start(self._drain, name="coevo-store", wake=lambda: self._inbox.put(None))
            life.start(self._report, name="coevo-broker-status")
            life.declare(s.declare_subscriber(f"{keys.ROOT}/*/policy/*", self._on_policy))
            life.declare(s.declare_subscriber(f"{keys.ROOT}/*/case/*", self._on_policy))  # a CEL run's case base
            for topic in ("latest", "history", "versions", "cases"):
                life.declare(s.declare_queryable(f"{keys.ROOT}/*/store/{topic}/*", self._on_query))
            life.at_end(self._drop_token)  # its token ends first of all
            self._sync_token()  # last: the store is ready
        except BaseException:
            self.close()
            raise
        return self

    def _sync_token(self) -> None:
        """Hold ``coevo/_broker`` while the store writes, ``coevo/_broker/degraded`` while it cannot."""
        want = keys.BROKER_DEGRADED if self.store.degraded else keys.BROKER
        with self._token_lock:
            life = self._life
            if want == self._token_key or life is None or life.stop.is_set():  # unchanged, or closing
                return
            try:
                token = life.session.liveliness().declare_token(want)
                if self._token is not None:
                    self._token.undeclare()
            except SessionGone as exc:  # the session is closing
                log.debug("broker token not changed: %s", exc)
                return
            before, self._token, self._token_key = self._token_key, token, want
        if want == keys.BROKER_DEGRADED:
            log.error("store degraded: token %s instead of %s (workers stop counting on it)", want, keys.BROKER)
        elif before:
            log.warning("store writes again: token %s back", want)

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Its token, subscribers and queryables end, then its threads (the store drains what was queued), then
        the session; the store's log is flushed.  Idempotent.

        The life stays reachable until it has ended: a status put that the report thread has under way meets the
        session (or SessionGone once it closes), never a broker without one; its ``stop``, set first, tells
        :meth:`_sync_token` not to declare a token on a session that is closing."""
        life = self._life
        if life is None:
            return
        try:
            life.close()
        finally:
            self._life = None
            self.store.flush_log()

    def _drop_token(self) -> None:
        with self._token_lock:
            token, self._token, self._token_key = self._token, None, ""
        if token is not None:
            try:
                token.undeclare()
            except SessionGone as exc:  # already gone with the session
                log.debug("broker token: undeclare after the session went: %s", exc)

    @property
    def _stop(self) -> threading.Event:
        return self._life.stop if self._life is not None else _STOPPED

    def serve_forever(self) -> None:
        # A wait with a timeout, so that a signal lands: an untimed wait blocks in C, and a SIGTERM that the kernel
        # hands to one of zenoh's threads then never reaches Python's handler in the main thread (seen: a broker
        # signalled while its workers were still talking to it slept through SIGTERM until killed 10 s later).
        while not self._stop.wait(0.25):
            pass

    # Callbacks: check the size, queue and return (policies and cases alike).
    def _on_policy(self, sample: Sample) -> None:
        key = str(sample.key_expr)
        payload = bytes(sample.payload.to_bytes())
        if len(payload) > MAX_BYTES:
            self.store.reject(MessageError("oversize", f"{len(payload)} bytes > {MAX_BYTES}"), key)
            return
        with self._qlock:
            full = self._queued + len(payload) > self.inbox_bytes
            if not full:
                self._queued += len(payload)
        if full:
            self.store.reject(MessageError("flood", f"inbox holds over {self.inbox_bytes} bytes; dropped unread"), key,
                              dropped=True)
            return
        self._inbox.put((key, payload))

    def _drain(self) -> None:
        while True:
            item = self._inbox.get()
            if item is None:
                return
            key, payload = item
            with self._qlock:
                self._queued -= len(payload)
            try:
                run = keys.parse(key).get("run", "?")
                gate = self.keyring.gate(run)
                if gate is None:
                    raise MessageError("unauthenticated", f"this broker holds no key for run {run!r}")
                msg = gate.decode(key, payload)
                if not isinstance(msg, (PolicyUpdate, CaseUpdate)):  # decode checked it fits its key
                    raise MessageError("wrong_key", f"{msg.kind} message on {key!r}")
                stored = self.store.add(msg)
            except MessageError as err:
                self.store.reject(err, key)
                continue
            if stored:
                log.info("stored %s %s v%d of %s (fitness %.3f)", msg.behaviour, msg.kind, msg.version, msg.run, msg.fitness)
            self._sync_token()

    def _report(self) -> None:
        """Publish each known run's BrokerStatus every ``status_every`` s."""
        while not self._stop.wait(self.status_every):
            degraded = self.store.degraded
            for run, (stored, rejected, dropped) in self.store.accounts().items():
                gate = self.keyring.gate(run) or OPEN
                try:
                    self.session.put(keys.broker_status(run), gate.seal(BrokerStatus(
                        run=run, stored=stored, rejected=rejected, dropped=dropped, open=gate.open, degraded=degraded[:500],
                        sent_at=time.time()), keys.broker_status(run)))
                except SessionGone as exc:  # the session is closing
                    log.debug("broker status not sent: %s", exc)
                    return

    def _on_query(self, query: Query) -> None:
        parts = keys.parse(str(query.key_expr))
        topic = parts.get("topic", "")
        cases = topic == "store/cases"
        run, beh = parts.get("run", "*"), parts.get("behaviour", "*")
        pairs = self.store.matching(run, beh, cases=cases)
        if topic == "store/versions" and not pairs and keys.valid_id(run) and keys.valid_id(beh):
            # A behaviour it holds nothing of (its store file lost, or nothing arrived yet): answer "none", so that
            # its worker republishes every version; silence would read as a store that did not answer.
            pairs = [(run, beh)]
        for run, beh in pairs:
            gate = self.keyring.gate(run)
            if gate is None:
                continue  # a run this broker holds no key for (stored before its key went): it says nothing of it
            if topic == "store/versions":
                key = keys.store_versions(run, beh)
                query.reply(key, gate.seal_bytes(msgpack.packb(
                    {"run": run, "behaviour": beh, "workers": self.store.versions(run, beh)}), key))
                continue
            if cases:
                key = keys.store_cases(run, beh)
                for c in self.store.cases(run, beh):
                    query.reply(key, gate.seal(c, key))
                continue
            latest = topic == "store/latest"
            key = PolicyStore.key_of(run, beh, latest)
            publisher = gate.roster.get(beh) if gate.roster else None  # the roster's worker, when the run has one
            msgs = [self.store.latest(run, beh, worker=publisher)] if latest else self.store.history(run, beh)
            for m in msgs:
                if m is not None:
                    query.reply(key, gate.seal(m, key))


def _listen(args: argparse.Namespace) -> list[str]:
    """Where a router listens (default: loopback); a broker run as a client of another router only connects."""
    if args.mode != "router":
        return [f"(a {args.mode} of {', '.join(args.connect or [args.config or '?'])})"]
    if not args.listen and not args.config:
        args.listen = ["tls/127.0.0.1:7447" if args.tls_ca else "tcp/127.0.0.1:7447"]
    return args.listen or ["(from " + args.config + ")"]


def serve_broker(args: argparse.Namespace, *, data_dir: Path, inbox_bytes: int, open_runs: bool = False,
                 quota: Quota | None = None) -> int:
    """``coevo broker``: serve until SIGINT/SIGTERM (a clean stop at any moment, even while the store loads)."""
    listen = _listen(args)
    conf = config_from_args(args)
    if open_runs:
        log.warning("broker started with --open: runs it holds no key for are stored unauthenticated")

    def serve() -> None:
        with Broker(conf, data_dir, inbox_bytes=inbox_bytes, open_runs=open_runs, quota=quota) as broker:
            log.info("broker listening on %s, store in %s", listen, data_dir)
            print(f"coevo broker listening on {', '.join(listen)}; store in {data_dir}", flush=True)
            broker.serve_forever()

    main_of(serve)  # it serves until stopped: a signal is its normal end (exit status 0)
    return 0


def serve_router(args: argparse.Namespace) -> int:
    """``coevo router``: a plain Zenoh router, no store: another site's meeting point, joined to the broker."""
    listen = _listen(args)
    conf = config_from_args(args)

    def serve() -> None:
        with Lifecycle(conf, what="router") as life:
            print(f"coevo router listening on {', '.join(listen)}; joined to {', '.join(args.connect or ['-'])}", flush=True)
            while not life.stop.wait(0.25):  # a timed wait, so that a signal lands (Broker.serve_forever)
                pass

    main_of(serve)  # it serves until stopped: a signal is its normal end (exit status 0)
    return 0
