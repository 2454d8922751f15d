"""Feeding a learner its partners' recorded history at a chosen rate (an Executive, Tracking's and Docking's).

The report's Independent regime lets Tracking and Docking learn first, then
replays their best-so-far history to the Executive "at various rates of
asynchrony" (it found no appreciable difference).  ``rate`` is how many partner
generations pass per Executive generation: before its generation ``g+1`` the
Executive adopts, for each partner, the newest version published at a partner
generation ``<= g * rate``.  Deterministic, and needs no network.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from coevo.bus.messages import PolicyUpdate
from coevo.errors import ConfigError, RunDirError
from coevo.rundir.layout import RunPaths, read_store

__all__ = ["HistoryFeed"]


class HistoryFeed:
    def __init__(self, run_dir: Path, rate: float, *, partners: tuple[str, ...]) -> None:
        if not (rate > 0 and math.isfinite(rate)):
            raise ConfigError(f"rate of asynchrony must be positive and finite, got {rate!r}")
        self.rate = rate
        self.updates: dict[str, list[PolicyUpdate]] = {}
        _check_finished(Path(run_dir), partners)
        for b in partners:
            f = RunPaths(Path(run_dir)).store_file(b)
            if not f.exists():
                raise RunDirError(f"{f} is missing: --history needs a run directory with stored {b} policies")
            rows = read_store(f)
            if any(m.behaviour != b for m in rows):
                raise RunDirError(f"{f} holds policies of another behaviour than {b}")
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


def _check_finished(run_dir: Path, partners: tuple[str, ...]) -> None:
    """A history must be a whole run: its run.json, and every partner done with every generation."""
    if not RunPaths(run_dir).run_json.is_file():
        raise RunDirError(f"{str(run_dir)!r} is not a run directory (no run.json): --history needs a finished "
                          "coevo run directory")
    for b in partners:
        f = RunPaths(run_dir).worker(b).done
        try:
            done = json.loads(f.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            done = None  # reported below as "no done.json"
        if not isinstance(done, dict) or not done.get("finished"):
            got = f"{done.get('generations')} generations" if isinstance(done, dict) else "no done.json"
            raise RunDirError(f"{str(run_dir)!r} is incomplete: its {b} worker did not finish ({got}); "
                              f"continue it with coevo run --resume {run_dir}")
