"""``coevo status``: follow the workers of a run (heartbeats plus liveliness tokens).

A worker is *alive* while its liveliness token exists and its last heartbeat is
recent, *stalled* when the token exists but no heartbeat came for ``stall``
seconds (a token proves the process exists, not that it progresses), *dead* when
its token is gone, and *done* when it said so.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from coevo import keys
from coevo.errors import MessageError
from coevo.messages import Status, decode

__all__ = ["WorkerView", "StatusBoard"]


@dataclass
class WorkerView:
    behaviour: str
    worker: str
    regime: str = "?"
    generation: int = 0
    generations: int = 0
    best_fitness: float = 0.0
    partner_versions: dict[str, int] = field(default_factory=dict)
    rejected: int = 0
    token: bool = False
    done: bool = False
    last_heartbeat: float = 0.0

    def state(self, now: float, stall: float) -> str:
        if self.done:
            return "done"
        if not self.token:
            return "dead"
        if self.last_heartbeat and now - self.last_heartbeat > stall:
            return "stalled"
        return "alive"

    def as_dict(self, now: float, stall: float) -> dict[str, Any]:
        return {
            "behaviour": self.behaviour, "worker": self.worker, "regime": self.regime,
            "generation": self.generation, "generations": self.generations, "best_fitness": self.best_fitness,
            "partner_versions": self.partner_versions, "rejected": self.rejected, "state": self.state(now, stall),
            "heartbeat_age": round(now - self.last_heartbeat, 3) if self.last_heartbeat else None,
        }


class StatusBoard:
    """Subscribes to a run's heartbeats and liveliness; thread-safe snapshot for display."""

    def __init__(self, session: Any, run: str, *, stall: float = 10.0) -> None:
        self.run = run
        self.stall = stall
        self._lock = threading.Lock()
        self.workers: dict[str, WorkerView] = {}
        self.rejected = 0
        self.changed = threading.Event()
        self._decls = [
            session.declare_subscriber(keys.status(run), self._on_status),
            session.liveliness().declare_subscriber(keys.alive(run), self._on_token, history=True),
        ]

    def close(self) -> None:
        for d in self._decls:
            try:
                d.undeclare()
            except Exception:
                pass

    def _view(self, behaviour: str, worker: str) -> WorkerView:
        v = self.workers.get(worker)
        if v is None:
            v = self.workers[worker] = WorkerView(behaviour, worker)
        return v

    def _on_status(self, sample: Any) -> None:
        try:
            msg = decode(bytes(sample.payload.to_bytes()), key=str(sample.key_expr))
        except MessageError:
            with self._lock:
                self.rejected += 1
            return
        if not isinstance(msg, Status):
            return
        with self._lock:
            v = self._view(msg.behaviour.value, msg.worker)
            v.regime, v.generation, v.generations = msg.regime, msg.generation, msg.generations
            v.best_fitness, v.partner_versions = msg.best_fitness, msg.partner_versions
            v.rejected, v.done, v.last_heartbeat = sum(msg.rejected.values()), msg.done, time.time()
            if not msg.done:
                v.token = True  # a heartbeat proves the process is there
        self.changed.set()

    def _on_token(self, sample: Any) -> None:
        parts = keys.parse(str(sample.key_expr))
        if "worker" not in parts:
            return
        alive = str(sample.kind).endswith("PUT")
        with self._lock:
            v = self._view(parts.get("behaviour", "?"), parts["worker"])
            v.token = alive
        self.changed.set()

    def snapshot(self) -> list[dict[str, Any]]:
        now = time.time()
        with self._lock:
            return [self.workers[k].as_dict(now, self.stall) for k in sorted(self.workers)]

    def json_line(self) -> str:
        return json.dumps({"run": self.run, "time": time.time(), "workers": self.snapshot()})
