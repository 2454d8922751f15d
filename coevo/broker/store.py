"""The policy store: latest and full history of every published policy, per run and behaviour.

It keeps everything in memory for queries and appends each accepted update to
``<data_dir>/<run>/store/<behaviour>.jsonl`` (flushed and fsynced), so a broker
that restarts reloads what it had.  An update whose (worker, version) is already
stored is a duplicate (a worker republishing after a reconnect) and is ignored.
"""

from __future__ import annotations

import json
import logging
import os
import threading
from collections import Counter
from pathlib import Path

from coevo import keys
from coevo.behaviours import Behaviour
from coevo.errors import MessageError
from coevo.messages import PolicyUpdate

__all__ = ["PolicyStore"]

log = logging.getLogger(__name__)


class PolicyStore:
    def __init__(self, data_dir: Path) -> None:
        self.data_dir = Path(data_dir)
        self._lock = threading.Lock()
        self._history: dict[tuple[str, Behaviour], list[PolicyUpdate]] = {}
        self._seen: set[tuple[str, str, str, int]] = set()
        self.rejected: Counter[str] = Counter()
        self._load()

    def _file(self, run: str, behaviour: Behaviour) -> Path:
        return self.data_dir / run / "store" / f"{behaviour.value}.jsonl"

    def _load(self) -> None:
        if not self.data_dir.exists():
            return
        for f in sorted(self.data_dir.glob("*/store/*.jsonl")):
            for n, line in enumerate(f.read_text(encoding="utf-8").splitlines(), start=1):
                if not line.strip():
                    continue
                try:
                    msg = PolicyUpdate.model_validate(json.loads(line))
                except Exception as exc:  # a torn last line after a crash mid-write
                    log.warning("store %s line %d unreadable, skipped: %s", f, n, exc)
                    continue
                self._remember(msg)
        if self._seen:
            log.info("store reloaded %d policies from %s", len(self._seen), self.data_dir)

    def _remember(self, msg: PolicyUpdate) -> bool:
        ident = (msg.run, msg.behaviour.value, msg.worker, msg.version)
        if ident in self._seen:
            return False
        self._seen.add(ident)
        self._history.setdefault((msg.run, msg.behaviour), []).append(msg)
        return True

    def add(self, msg: PolicyUpdate) -> bool:
        """Store and persist an update; False if it was a duplicate."""
        with self._lock:
            if not self._remember(msg):
                return False
            f = self._file(msg.run, msg.behaviour)
            f.parent.mkdir(parents=True, exist_ok=True)
            with open(f, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(msg.model_dump(mode="json"), sort_keys=True) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
            return True

    def reject(self, err: MessageError, key: str) -> None:
        with self._lock:
            self.rejected[err.reason] += 1
        log.warning("rejected message on %s: %s", key, err)

    def latest(self, run: str, behaviour: Behaviour) -> PolicyUpdate | None:
        with self._lock:
            h = self._history.get((run, behaviour))
            return h[-1] if h else None

    def history(self, run: str, behaviour: Behaviour) -> list[PolicyUpdate]:
        with self._lock:
            return list(self._history.get((run, behaviour), []))

    def runs(self) -> list[str]:
        with self._lock:
            return sorted({r for r, _ in self._history})

    def matching(self, run_pattern: str, behaviour_pattern: str) -> list[tuple[str, Behaviour]]:
        """(run, behaviour) pairs a query's chunks select (``*`` or a literal)."""
        with self._lock:
            pairs = list(self._history)
        return [
            (r, b) for r, b in pairs
            if run_pattern in ("*", "**", r) and behaviour_pattern in ("*", "**", b.value)
        ]

    @staticmethod
    def key_of(run: str, behaviour: Behaviour, latest: bool) -> str:
        return keys.store_latest(run, behaviour) if latest else keys.store_history(run, behaviour)
