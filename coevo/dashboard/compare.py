"""A comparison directory (``coevo compare --out OUT``) as the dashboard shows it: its replicates, done, running,
failed or waiting, and the report's Table 1 counted over the runs finished so far.

The replicates, their run directories, what "finished" means and the Table 1 classes are the
comparison's own (:mod:`coevo.experiments.compare`), so the page counts exactly what the report
will.  Whether an unfinished replicate is running or failed is read from its files: running while
its log or its workers' logs grew in the last ``stale`` seconds; failed when its run ended
interrupted (``summary.json`` without measures) or went quiet.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError

__all__ = ["ComparisonFiles"]


def _mtime(p: Path) -> float:
    try:
        return p.stat().st_mtime
    except OSError:
        return 0.0


class ComparisonFiles:
    """A comparison directory, followed."""

    def __init__(self, out: Path, *, stale: float) -> None:
        from pydantic import ValidationError

        from coevo.experiments.compare.experiment import CompareSpec, replicates
        from coevo.rundir.layout import read_json

        self.out, self.stale = Path(out), stale
        marker = read_json(self.out / "compare.json", what="comparison (its compare.json)")
        try:
            self.spec = CompareSpec.model_validate(marker["spec"])
        except (KeyError, TypeError, ValidationError) as exc:
            raise RunDirError(f"{self.out / 'compare.json'} is not a comparison's settings: "
                              f"{str(exc).splitlines()[0]}") from None
        self.replicates = replicates(self.spec)
        self._classes: dict[str, str] = {}  # a finished replicate's Table 1 class: it no longer changes
        self._curves: dict[str, list[float]] = {}  # ... and its Executive curve (best per generation)

    def run_dirs(self) -> list[Path]:
        """The live replicates' run directories that exist so far (their curves go on the page)."""
        from coevo.experiments.compare.experiment import run_dir
        from coevo.rundir.layout import RunPaths

        dirs = [run_dir(self.out, r) for r in self.replicates if not r.offline]
        return [d for d in dirs if RunPaths(d).run_json.exists()]

    def _state(self, rep: Any, now: float) -> tuple[str, str]:
        """(state, why) of one replicate."""
        from coevo.experiments.compare.experiment import is_finished, run_dir
        from coevo.rundir.layout import RunPaths

        if rep.run_id in self._classes or is_finished(self.out, rep):
            return "done", ""
        d = run_dir(self.out, rep)
        log = self.out / "logs" / f"{rep.run_id}.log"
        paths = RunPaths(d)
        summary = paths.summary
        if summary.exists():
            try:
                if json.loads(summary.read_text()).get("interrupted"):
                    return "failed", "stopped early (summary.json: interrupted)"
            except (OSError, json.JSONDecodeError):
                pass
        if not d.exists() and not log.exists():
            return "waiting", ""
        latest = max([_mtime(log), _mtime(d)] + [_mtime(w / "curve.jsonl") for w in paths.workers_dir.glob("*")]
                     + [_mtime(f) for f in paths.logs_dir.glob("*.log")])
        if now - latest < self.stale:
            return "running", ""
        return "failed", f"no progress for {now - latest:.0f} s; see {log}"

    def _class(self, rep: Any) -> str | None:
        from coevo.experiments.compare.experiment import run_dir
        from coevo.experiments.compare.table1 import classify
        from coevo.rundir.layout import LearnPaths, RunPaths

        if rep.run_id not in self._classes:
            d = run_dir(self.out, rep)
            f = LearnPaths(d).measures if rep.offline else RunPaths(d).summary
            try:
                data = json.loads(f.read_text())
                self._classes[rep.run_id] = classify(data if rep.offline else data["measures"])
            except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError):
                return None
        return self._classes[rep.run_id]

    def _executive_curve(self, rep: Any) -> list[float]:
        """A finished live replicate's Executive curve, the best of each generation (damaged lines left out)."""
        from coevo.experiments.compare.experiment import run_dir
        from coevo.rundir.layout import RunPaths, read_jsonl

        if rep.run_id not in self._curves:
            rows = read_jsonl(RunPaths(run_dir(self.out, rep)).worker("executive").curve, missing_ok=True, problems=[])
            self._curves[rep.run_id] = [float(r["best_fitness"]) for r in rows
                                        if isinstance(r.get("best_fitness"), (int, float))]
        return self._curves[rep.run_id]

    def read(self) -> dict[str, Any]:
        """Replicates by state, the Table 1 so far and the Executive curve of the finished live runs:
        ``{"dir", "replicates": [...], "counts", "table1", "executive_curve"}``."""
        from coevo.experiments.compare.experiment import generations_done, generations_of, groups
        from coevo.experiments.compare.report import executive_curve
        from coevo.experiments.compare.table1 import CLASSES, count

        now = time.time()
        rows = []
        classes: dict[str, list[str]] = {g: [] for g in groups(self.spec)}
        curves: dict[str, list[list[float]]] = {g: [] for g in groups(self.spec)}
        for rep in self.replicates:
            state, why = self._state(rep, now)
            cls = self._class(rep) if state == "done" else None
            if cls is not None:
                classes.setdefault(rep.group, []).append(cls)
                if not rep.offline:
                    curves.setdefault(rep.group, []).append(self._executive_curve(rep))
            total = generations_of(self.spec, rep)
            done = total if state == "done" else min(total, generations_done(self.out, rep))
            rows.append({"run": rep.run_id, "group": rep.group, "state": state, "why": why, "class": cls or "",
                         "generations": done, "of": total})
        counts = {s: sum(1 for r in rows if r["state"] == s) for s in ("done", "running", "failed", "waiting")}
        return {"dir": str(self.out), "replicates": rows, "counts": counts, "classes": list(CLASSES),
                "table1": {g: count(c) for g, c in classes.items()},
                "executive_curve": {g: executive_curve(c) for g, c in curves.items() if c}}
