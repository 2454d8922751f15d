"""Feeding a learner its partners' recorded history at a chosen rate (an Executive, Tracking's and Docking's).

The report's Independent regime lets Tracking and Docking learn first, then
replays their best-so-far history to the Executive "at various rates of
asynchrony" (it found no appreciable difference).  ``rate`` is how many partner
generations pass per Executive generation: before its generation ``g+1`` the
Executive adopts, for each partner, the newest version published at a partner
generation ``<= g * rate``.  Deterministic, and needs no network.
"""

from __future__ import annotations

import math
from pathlib import Path

from coevo.bus.messages import PolicyUpdate
from coevo.errors import ConfigError, RunDirError
from coevo.rundir.layout import RunPaths, read_json, read_jsonl, read_store

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
    """A history must be a whole run of a task with these partners: its run.json, and every partner done with
    every generation, its logs whole (a damaged line of ``published.jsonl`` or ``adoptions.jsonl`` is a RunDirError
    naming the file and line, as every reader of a run refuses one)."""
    from coevo.rundir.records import AdoptionLine
    from coevo.rundir.settings import RunSettings

    paths = RunPaths(run_dir)
    if not paths.run_json.is_file():
        raise RunDirError(f"{str(run_dir)!r} is not a run directory (no run.json): --history needs a finished "
                          "coevo run directory")
    settings = RunSettings.load(paths.run_json)
    behaviours = tuple(settings.the_task.behaviours)
    missing = [b for b in partners if b not in behaviours]
    if missing:
        raise RunDirError(f"{str(run_dir)!r} is a run of the {settings.the_task.name} task (behaviours "
                          f"{', '.join(behaviours)}): it holds no {' or '.join(missing)} history to learn on")
    for b in partners:
        w = paths.worker(b)
        if not (w.done.exists() or w.done.is_symlink()):
            raise RunDirError(f"{str(run_dir)!r} is incomplete: its {b} worker did not finish (no done.json); "
                              f"continue it with coevo run --resume {run_dir}")
        done = read_json(w.done, what="worker directory (its done.json)")
        if not done.get("finished"):
            raise RunDirError(f"{str(run_dir)!r} is incomplete: its {b} worker did not finish "
                              f"({done.get('generations')} generations); continue it with coevo run --resume {run_dir}")
        read_store(w.published)
        read_jsonl(w.adoptions, schema=AdoptionLine)
