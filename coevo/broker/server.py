"""``coevo broker``: the Zenoh router workers meet at, plus the policy store.

A Python zenoh session in router mode (there is no zenohd here) listens for
clients.  A subscriber on ``coevo/*/policy/*`` feeds a queue; one thread decodes,
validates and stores what arrives (callbacks stay trivial, so a slow disk never
stalls the connection).  Queryables on ``coevo/*/store/latest/*`` and
``coevo/*/store/history/*`` answer from memory.
"""

from __future__ import annotations

import logging
import queue
import threading
from pathlib import Path
from typing import Any

from coevo import keys
from coevo.bus import open_session
from coevo.errors import MessageError
from coevo.messages import PolicyUpdate, decode, encode
from coevo.broker.store import PolicyStore

__all__ = ["Broker"]

log = logging.getLogger(__name__)


class Broker:
    """Router + store; use as a context manager, or call :meth:`serve_forever`."""

    def __init__(self, conf: Any, data_dir: Path) -> None:
        self.conf = conf
        self.store = PolicyStore(Path(data_dir))
        self._inbox: queue.Queue[tuple[str, bytes] | None] = queue.Queue()
        self._stop = threading.Event()
        self._session_cm: Any = None
        self._decls: list[Any] = []
        self._worker: threading.Thread | None = None

    def __enter__(self) -> Broker:
        self._session_cm = open_session(self.conf, what="router")
        s = self._session_cm.__enter__()
        self.session = s
        self._worker = threading.Thread(target=self._drain, name="coevo-store", daemon=True)
        self._worker.start()
        self._decls.append(s.declare_subscriber(f"{keys.ROOT}/*/policy/*", self._on_policy))
        self._decls.append(s.declare_queryable(f"{keys.ROOT}/*/store/latest/*", self._on_query))
        self._decls.append(s.declare_queryable(f"{keys.ROOT}/*/store/history/*", self._on_query))
        self._decls.append(s.liveliness().declare_token(keys.BROKER))  # last: the store is ready
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._session_cm is None:
            return
        for d in self._decls:
            try:
                d.undeclare()
            except Exception:  # already gone with the session
                pass
        self._decls.clear()
        self._inbox.put(None)
        if self._worker is not None:
            self._worker.join(timeout=5)
        cm, self._session_cm = self._session_cm, None
        cm.__exit__(None, None, None)

    def serve_forever(self) -> None:
        self._stop.wait()

    def stop(self) -> None:
        self._stop.set()

    # Callbacks: store and return.
    def _on_policy(self, sample: Any) -> None:
        self._inbox.put((str(sample.key_expr), bytes(sample.payload.to_bytes())))

    def _drain(self) -> None:
        while True:
            item = self._inbox.get()
            if item is None:
                return
            key, payload = item
            try:
                msg = decode(payload, key=key)
                if not isinstance(msg, PolicyUpdate):
                    raise MessageError("wrong_key", f"{msg.kind} message on {key!r}")
            except MessageError as err:
                self.store.reject(err, key)
                continue
            if self.store.add(msg):
                log.info("stored %s v%d of %s (fitness %.3f)", msg.behaviour, msg.version, msg.run, msg.fitness)

    def _on_query(self, query: Any) -> None:
        parts = keys.parse(str(query.key_expr))
        latest = parts.get("topic") == "store/latest"
        for run, beh in self.store.matching(parts.get("run", "*"), parts.get("behaviour", "*")):
            key = PolicyStore.key_of(run, beh, latest)
            msgs = [self.store.latest(run, beh)] if latest else self.store.history(run, beh)
            for m in msgs:
                if m is not None:
                    query.reply(key, encode(m))

    def wait_idle(self, timeout: float = 5.0) -> None:
        """Block until everything received so far is stored (for tests and shutdown)."""
        import time

        end = time.monotonic() + timeout
        while not self._inbox.empty() and time.monotonic() < end:
            time.sleep(0.01)
