"""Feeding an Executive the recorded history of Tracking and Docking at a chosen rate.

The report's Independent regime lets Tracking and Docking learn first, then
replays their best-so-far history to the Executive "at various rates of
asynchrony" (it found no appreciable difference).  ``rate`` is how many partner
generations pass per Executive generation: before its generation ``g+1`` the
Executive adopts, for each partner, the newest version published at a partner
generation ``<= g * rate``.  Deterministic, and needs no network.
"""

from __future__ import annotations

import json
from pathlib import Path

from coevo.behaviours import Behaviour
from coevo.errors import ConfigError, RunDirError
from coevo.messages import PolicyUpdate

__all__ = ["HistoryFeed"]


class HistoryFeed:
    def __init__(self, run_dir: Path, rate: float) -> None:
        if not rate > 0:
            raise ConfigError(f"rate of asynchrony must be positive, got {rate!r}")
        self.rate = rate
        self.updates: dict[Behaviour, list[PolicyUpdate]] = {}
        for b in (Behaviour.TRACKING, Behaviour.DOCKING):
            f = Path(run_dir) / "store" / f"{b.value}.jsonl"
            if not f.exists():
                raise RunDirError(f"{f} is missing: --history needs a run directory with stored {b.value} policies")
            rows = [PolicyUpdate.model_validate(json.loads(x)) for x in f.read_text().splitlines() if x.strip()]
            if not rows:
                raise RunDirError(f"{f} holds no policies")
            self.updates[b] = sorted(rows, key=lambda m: (m.generation, m.version))

    def due(self, generation: int) -> list[PolicyUpdate]:
        """The newest update per partner published by partner generation ``generation * rate``."""
        limit = generation * self.rate
        out = []
        for rows in self.updates.values():
            ready = [m for m in rows if m.generation <= limit]
            if ready:
                out.append(ready[-1])
        return out
