"""Counting and logging rejected bus messages, one counter per reason.

Every receiver (worker, broker, status) rejects bad messages the same way: it
counts them by :data:`coevo.bus.messages.REASONS` key and names each in its log.  A
flood of thousands of bad messages a second must not turn into thousands of log
lines a second, so after ``burst`` lines per reason the log falls silent for that
reason and says every ``every`` seconds how many more arrived.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter

from coevo.errors import MessageError

__all__ = ["Rejections"]


class Rejections:
    """Thread-safe reason counter with a rate-limited log."""

    def __init__(self, who: str, log: logging.Logger, *, burst: int = 5, every: float = 10.0) -> None:
        self.who = who
        self.log = log
        self.burst = burst
        self.every = every
        self._counts: Counter[str] = Counter()
        self._quiet: Counter[str] = Counter()  # counted but not logged since the last summary
        self._last_summary = time.monotonic()
        self._lock = threading.Lock()

    def note(self, err: MessageError, key: str, n: int = 1) -> None:
        with self._lock:
            self._counts[err.reason] += n
            if self._counts[err.reason] <= self.burst:
                self.log.warning("%s rejected %s on %s: %s", self.who, err.reason, key, err.detail)
            else:
                self._quiet[err.reason] += n
            self._summarise()

    def _summarise(self) -> None:
        now = time.monotonic()
        if self._quiet and now - self._last_summary >= self.every:
            self.log.warning("%s rejected %s more in the last %.0f s (totals %s)", self.who,
                             ", ".join(f"{n} {r}" for r, n in sorted(self._quiet.items())), now - self._last_summary,
                             dict(self._counts))
            self._quiet.clear()
            self._last_summary = now

    def flush(self) -> None:
        """Log what is still unsummarised (call at shutdown)."""
        with self._lock:
            self._last_summary = -float("inf")
            self._summarise()

    def as_dict(self) -> dict[str, int]:
        with self._lock:
            return dict(self._counts)

    def load(self, counts: dict[str, int]) -> None:
        """Continue from earlier counts (a resumed worker)."""
        with self._lock:
            self._counts.update({str(k): int(v) for k, v in counts.items()})
