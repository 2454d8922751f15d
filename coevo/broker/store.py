"""The policy store: latest and full history of every published policy, per run and behaviour.

It keeps everything in memory for queries and appends each accepted update to
``<data_dir>/<run>/store/<behaviour>.jsonl`` (flushed and fsynced before it counts
as stored), so a broker that restarts reloads what it had.  A broker killed
mid-write leaves at most a torn last line; the reload cuts it off (that update was
never confirmed to its worker, which publishes it again).  An update whose
(worker, version) is already stored is a duplicate (a worker republishing) and is
ignored.  Rejected messages are counted per run, by reason.
"""

from __future__ import annotations

import json
import logging
import os
import threading
from collections import Counter
from pathlib import Path

from coevo.bus import keys
from coevo.bus.messages import PolicyUpdate
from coevo.bus.rejections import Rejections
from coevo.errors import MessageError
from coevo.runs.layout import RunPaths, read_store

__all__ = ["PolicyStore"]

log = logging.getLogger(__name__)


class PolicyStore:
    def __init__(self, data_dir: Path) -> None:
        self.data_dir = Path(data_dir)
        self._lock = threading.Lock()
        self._history: dict[tuple[str, str], list[PolicyUpdate]] = {}
        self._seen: set[tuple[str, str, str, int]] = set()
        self._rejected: dict[str, Rejections] = {}  # per run (the key's run chunk)
        self._dropped: Counter[str] = Counter()  # per run: dropped unread (flood)
        self._active: set[str] = set()  # runs heard of since this broker started
        self._load()

    def _file(self, run: str, behaviour: str) -> Path:
        return RunPaths.of(self.data_dir, run).store_file(behaviour)

    def _load(self) -> None:
        if not self.data_dir.exists():
            return
        for f in sorted(self.data_dir.glob("*/store/*.jsonl")):
            _cut_torn_tail(f)
            damaged: list[str] = []
            for msg in read_store(f, problems=damaged):  # damaged in the middle: keep the rest
                self._remember(msg)
            for problem in damaged:
                log.warning("store: %s; skipped", problem)
        if self._seen:
            log.info("store reloaded %d policies from %s", len(self._seen), self.data_dir)

    def _remember(self, msg: PolicyUpdate) -> bool:
        ident = (msg.run, msg.behaviour, msg.worker, msg.version)
        if ident in self._seen:
            return False
        self._seen.add(ident)
        self._history.setdefault((msg.run, msg.behaviour), []).append(msg)
        return True

    def add(self, msg: PolicyUpdate) -> bool:
        """Store and persist an update; False if it was a duplicate."""
        with self._lock:
            self._active.add(msg.run)
            if not self._remember(msg):
                return False
            f = self._file(msg.run, msg.behaviour)
            f.parent.mkdir(parents=True, exist_ok=True)
            with open(f, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(msg.model_dump(mode="json"), sort_keys=True) + "\n")
                fh.flush()
                os.fsync(fh.fileno())
            return True

    def reject(self, err: MessageError, key: str, *, dropped: bool = False) -> None:
        run = keys.parse(key).get("run", "?")
        with self._lock:
            if run not in self._rejected:
                self._rejected[run] = Rejections(f"broker (run {run})", log)
            self._active.add(run)
            if dropped:
                self._dropped[run] += 1
            counter = self._rejected[run]
        counter.note(err, key)

    def rejected(self, run: str) -> dict[str, int]:
        with self._lock:
            counter = self._rejected.get(run)
        return counter.as_dict() if counter is not None else {}

    def flush_log(self) -> None:
        with self._lock:
            counters = list(self._rejected.values())
        for c in counters:
            c.flush()

    def accounts(self) -> dict[str, tuple[dict[str, int], dict[str, int], int]]:
        """For each run heard of since start: (policies stored per behaviour, rejections by reason, dropped)."""
        with self._lock:
            runs = sorted(r for r in self._active if keys.valid_id(r))
            stored = {r: {b: len(h) for (rr, b), h in self._history.items() if rr == r} for r in runs}
            dropped = {r: self._dropped[r] for r in runs}
        return {r: (stored[r], self.rejected(r), dropped[r]) for r in runs}

    def versions(self, run: str, behaviour: str) -> dict[str, list[int]]:
        """The versions held of each worker's policies for (run, behaviour)."""
        out: dict[str, list[int]] = {}
        for m in self.history(run, behaviour):
            out.setdefault(m.worker, []).append(m.version)
        return {w: sorted(v) for w, v in out.items()}

    def latest(self, run: str, behaviour: str) -> PolicyUpdate | None:
        with self._lock:
            h = self._history.get((run, behaviour))
            return h[-1] if h else None

    def history(self, run: str, behaviour: str) -> list[PolicyUpdate]:
        with self._lock:
            return list(self._history.get((run, behaviour), []))

    def matching(self, run_pattern: str, behaviour_pattern: str) -> list[tuple[str, str]]:
        """(run, behaviour) pairs a query's chunks select (``*`` or a literal)."""
        with self._lock:
            pairs = list(self._history)
        return [
            (r, b) for r, b in pairs
            if run_pattern in ("*", "**", r) and behaviour_pattern in ("*", "**", b)
        ]

    @staticmethod
    def key_of(run: str, behaviour: str, latest: bool) -> str:
        return keys.store_latest(run, behaviour) if latest else keys.store_history(run, behaviour)


def _cut_torn_tail(f: Path) -> None:
    """Cut a last line that a crash left without its newline (it was never fsynced as a whole)."""
    data = f.read_bytes()
    if data and not data.endswith(b"\n"):
        keep = data.rfind(b"\n") + 1
        log.warning("store %s: cut a torn last line of %d bytes (a crash mid-write)", f, len(data) - keep)
        with open(f, "r+b") as fh:
            fh.truncate(keep)
            os.fsync(fh.fileno())
