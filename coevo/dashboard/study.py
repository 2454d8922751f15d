"""A study directory (``coevo study --out OUT``) as the dashboard shows it: how far it is, overall and per cell, which
cells are running, finished, stopped or not started, and per cell and group the report's numbers so far (Table 1's
classes with 95 % Wilson intervals, the Executive curve's end and AEL with 95 % bootstrap intervals); and, for the
cells a page asks for, each one's comparison (:class:`~coevo.dashboard.compare.ComparisonFiles`).

Everything is counted by the study's own code, so the page says what its report will: the runs done and whether
the study is complete are :func:`~coevo.experiments.study.experiment.study_progress`'s (the completion marker alone
makes a study finished); a cell's numbers are :func:`~coevo.experiments.study.report.cell_rows` over
:func:`~coevo.experiments.study.report.collect_cell`'s records.  What they cost is paid once: a finished run's record
is made once (it holds a Docking probe of 300 episodes) and a cell's rows are made again only when its set of finished
runs changes (each mean's interval is 9,999 bootstrap resamples).

A cell's replicates are followed by a :class:`~coevo.dashboard.compare.ComparisonFiles` on its folder with the cell's
settings from the declaration (so a cell whose folder is not written yet shows as waiting, not as an error) and the
study's logs (``logs/CELL@RUN.log``): running while its files grew in the last ``stale`` seconds, failed when its run
stopped early or went quiet, as on a comparison's page.  The study itself is stopped when nothing ran and none of its
files moved for ``stale`` seconds.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coevo.dashboard.compare import ComparisonFiles
from coevo.errors import ConfigError, RunDirError

__all__ = ["StudyFiles", "CELL_STATES"]

#: A cell's states, as the page names them.
CELL_STATES = ("finished", "running", "stopped", "waiting", "not started")


def _mtime(p: Path) -> float:
    try:
        return p.stat().st_mtime
    except OSError:
        return 0.0


def _cell_state(counts: dict[str, int], done: int, total: int) -> str:
    """A cell's state from its replicates': finished (every run done), running (one is), stopped (one failed and
    none runs), not started (none has begun), else waiting (for the runner: a study runs run 0 of every cell first)."""
    if done == total:
        return "finished"
    if counts["running"]:
        return "running"
    if counts["failed"]:
        return "stopped"
    return "not started" if done == 0 else "waiting"


class StudyFiles:
    """A study directory, followed."""

    def __init__(self, out: Path, *, stale: float) -> None:
        from coevo.experiments.study.declaration import StudySpec, cells
        from coevo.experiments.study.experiment import MARKER, SEP, cell_dir
        from coevo.rundir.layout import read_json

        self.out, self.stale = Path(out), stale
        f = self.out / MARKER
        data = read_json(f, what="study (its study.json)")
        try:
            self.spec = StudySpec.from_dict(data["spec"])
            self.cells = cells(self.spec)
        except (KeyError, TypeError, ValueError, AttributeError, ConfigError) as exc:
            raise RunDirError(f"{str(f)!r} is not a study's declaration ({type(exc).__name__}: {exc})") from None

        def log_of(cell: str) -> Callable[[str], Path]:
            return lambda run: self.out / "logs" / f"{cell}{SEP}{run}.log"

        self.files = {c.id: ComparisonFiles(cell_dir(self.out, c), stale=stale, spec=c.spec, log_of=log_of(c.id))
                      for c in self.cells}
        self._known: dict[str, dict[str, dict[str, Any]]] = {c.id: {} for c in self.cells}  # cell -> run -> record
        # cell -> (its finished runs, its rows, what could not be read of them)
        self._rows: dict[str, tuple[tuple[str, ...], list[dict[str, Any]], str]] = {}
        self._results: tuple[float, dict[str, Any] | None] = (-1.0, None)  # results.json: (mtime, what it says)

    def _cell_rows(self, cell: Any, finished: tuple[str, ...], problems: list[str]) -> list[dict[str, Any]]:
        """The report's rows of ``cell`` (one per group), made again only when its finished runs changed.  While a
        finished run cannot be read (the report could not either), that is said in ``problems`` and the rows made
        before are kept."""
        from coevo.experiments.study.report import cell_rows, collect_cell

        held = self._rows.get(cell.id)
        if held is None or held[0] != finished:
            try:
                held = (finished, cell_rows([cell], collect_cell(self.out, cell, known=self._known[cell.id])), "")
            except (RunDirError, OSError, ValueError, KeyError, TypeError) as exc:
                why = f"cell {cell.id}: a finished run cannot be read ({type(exc).__name__}: {exc})"
                held = (finished, held[1] if held is not None else cell_rows([cell], []), why)
            self._rows[cell.id] = held
        if held[2]:
            problems.append(held[2] + ("; its numbers are from before" if any(r["n"] for r in held[1]) else ""))
        return held[1]

    def _verdict(self) -> dict[str, Any] | None:
        """The study's report's verdict from results.json, once written: ``{"text", "finished", "expected"}``."""
        f = self.out / "results.json"
        mtime = _mtime(f)
        if mtime != self._results[0]:
            try:
                data = json.loads(f.read_text(encoding="utf-8"))
                held = {"text": str(data["verdict"]), "finished": int(data["runs_finished"]),
                        "expected": int(data["runs_expected"])}
            except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, ValueError):
                held = None
            self._results = (mtime, held)
        return self._results[1]

    def _latest(self) -> float:
        """When any of the study's own files last moved (its declaration, the replicates' logs, the report)."""
        try:
            logs = list((self.out / "logs").iterdir())
        except OSError:
            logs = []
        return max([_mtime(self.out / n) for n in ("study.json", "results.json", "complete.json")]
                   + [_mtime(p) for p in logs])

    def read(self, shown: list[str]) -> dict[str, Any]:
        """The study as the page shows it: ``{"dir", "name", "description", "factors", "state", "why", "runs_done",
        "runs_total", "cells_done", "cells_total", "complete", "counts", "cells": [...], "verdict", "caveat",
        "problems", "default", "shown": {cell: its comparison}}`` (``shown``: the cells whose comparison is read,
        :meth:`ComparisonFiles.read`, besides ``default``, the cell a new page opens on: the first running, else the
        first with a finished run, else the first; an id that is no cell of this study is left out)."""
        from coevo.experiments.common import below_report
        from coevo.experiments.study.declaration import level_text
        from coevo.experiments.study.experiment import study_progress

        progress = study_progress(self.out)
        problems: list[str] = []
        cells = []
        states: dict[str, list[dict[str, Any]]] = {}
        totals = {s: 0 for s in ("done", "running", "failed", "waiting")}
        for c, cp in zip(self.cells, progress.cells, strict=True):
            reps = states[c.id] = self.files[c.id].states()
            counts = {s: sum(1 for r in reps if r["state"] == s) for s in totals}
            for s, n in counts.items():
                totals[s] += n
            finished = tuple(r["run"] for r in reps if r["state"] == "done")
            cells.append({"id": c.id, "label": c.label, "seed": c.spec.seed, "runs_done": cp.runs_done,
                          "runs_total": cp.runs_total, "counts": counts,
                          "state": _cell_state(counts, cp.runs_done, cp.runs_total),
                          "failed": [f"{r['run']}: {r['why']}" for r in reps if r["state"] == "failed"],
                          "rows": self._cell_rows(c, finished, problems)})
        quiet = time.time() - self._latest()
        if progress.complete:
            state, why = "finished", "every run done and the report written"
        elif totals["running"]:
            state, why = "running", ""
        elif quiet < self.stale:  # between two runs, or its report being written
            state, why = ("writing its report" if progress.runs_done == progress.runs_total else "running"), ""
        elif progress.runs_done == progress.runs_total:
            state, why = "stopped", (f"every run is done but the report is not written: coevo study --report-only "
                                     f"--out {self.out}")
        else:
            state, why = "stopped", (f"nothing has run for {quiet:.0f} s: coevo study --resume --out {self.out} "
                                     "continues it")
        ga = self.cells[0].spec.ga
        caveat = below_report({"generations": ga.generations, "population": ga.population, "episodes": ga.episodes,
                               "runs a regime": min(c.spec.runs for c in self.cells)})
        factors = "; ".join(f"{k}: {', '.join(level_text(k, v) for v in lv)}"
                            for k, lv in self.spec.factors.items()) or "none"
        default = next((c["id"] for c in cells if c["state"] == "running"),
                       next((c["id"] for c in cells if c["runs_done"]), cells[0]["id"]))
        return {"dir": str(self.out), "name": self.spec.name, "description": self.spec.description,
                "factors": factors, "state": state, "why": why, "runs_done": progress.runs_done,
                "runs_total": progress.runs_total, "cells_done": progress.cells_done,
                "cells_total": progress.cells_total, "complete": progress.complete, "counts": totals, "cells": cells,
                "verdict": self._verdict(), "caveat": caveat, "problems": problems, "default": default,
                "shown": {cid: self.files[cid].read(states[cid]) for cid in dict.fromkeys([default, *shown])
                          if cid in self.files}}
