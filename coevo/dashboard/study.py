"""A study directory (``coevo study --out OUT``) as the dashboard shows it: how far it is, overall and per cell, which
cells are running, finished, stopped or not started, and per cell and group the report's numbers so far (Table 1's
classes with 95 % Wilson intervals, the Executive curve's end and AEL with 95 % t intervals); and, for the
cells a page asks for, each one's comparison (:class:`~coevo.dashboard.compare.ComparisonFiles`).

Everything is counted by the study's own code, so the page says what its report will: the runs done and whether
the study is complete are :func:`~coevo.experiments.study.experiment.study_progress`'s (the completion marker alone
makes a study finished); a cell's numbers are :func:`~coevo.experiments.study.report.cell_rows` over
:func:`~coevo.experiments.study.report.collect_cell`'s records.  What they cost is paid once: a finished run's record
is made once (it holds a Docking probe of 300 episodes) and a cell's rows are made again only when its set of finished
runs changes.

A cell's replicates are followed by a :class:`~coevo.dashboard.compare.ComparisonFiles` on its folder with the cell's
settings from the declaration (so a cell whose folder is not written yet shows as waiting, not as an error) and the
study's logs (``logs/CELL@RUN.log``): running while its files grew in the last ``stale`` seconds, failed when its run
stopped early or went quiet, as on a comparison's page.  The study itself is stopped when nothing ran and none of its
files moved for ``stale`` seconds.

A study of learning runs (``learn``) has no comparison to show: per cell its runs' states and the report's rows so far
(:func:`~coevo.experiments.study.learn_report.learn_cell_rows`: each of the behaviour's measures as a mean with its
95 % t interval, and the median), and ``shown`` is empty.  A ``coevo learn`` writes nothing until it ends
(its folder appears whole, its log gets its lines), so an unfinished run with an empty log is running while the study's
files moved in the last ``stale`` seconds, and stopped after; one whose log has lines but no folder failed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coevo.dashboard.compare import ComparisonFiles, VerdictFile
from coevo.dashboard.files import mtime
from coevo.errors import ConfigError, RunDirError

__all__ = ["StudyFiles", "CELL_STATES"]

#: A cell's states, as the page names them.
CELL_STATES = ("finished", "running", "stopped", "waiting", "not started")


def _said(log: Path) -> str | None:
    """The last line of a run's log ('' while it is empty); None when there is no log (the run has not started)."""
    try:
        text = log.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return None
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[-1][:200] if lines else ""


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
        from coevo.experiments.study.declaration import Cell, LearnCell, StudySpec, study_cells
        from coevo.experiments.study.experiment import MARKER, SEP, cell_dir
        from coevo.rundir.layout import read_json

        self.out, self.stale = Path(out), stale
        f = self.out / MARKER
        data = read_json(f, what="study (its study.json)")
        try:
            self.spec = StudySpec.from_dict(data["spec"])
            self.cells: list[Cell | LearnCell] = list(study_cells(self.spec))
        except (KeyError, TypeError, ValueError, AttributeError, ConfigError) as exc:
            raise RunDirError(f"{str(f)!r} is not a study's declaration ({type(exc).__name__}: {exc})") from None

        self._sep = SEP

        def log_of(cell: str) -> Callable[[str], Path]:
            return lambda run: self._log(cell, run)

        self.files = {c.id: ComparisonFiles(cell_dir(self.out, c), stale=stale, spec=c.spec, log_of=log_of(c.id))
                      for c in self.cells if isinstance(c, Cell)}
        self._known: dict[str, dict[str, dict[str, Any]]] = {c.id: {} for c in self.cells}  # cell -> run -> record
        # cell -> (its finished runs, its rows, what could not be read of them)
        self._rows: dict[str, tuple[tuple[str, ...], list[dict[str, Any]], str]] = {}
        self._verdict = VerdictFile(self.out / "results.json")

    def _cell_rows(self, cell: Any, finished: tuple[str, ...], problems: list[str]) -> list[dict[str, Any]]:
        """The report's rows of ``cell`` (one per group), made again only when its finished runs changed.  While a
        finished run cannot be read (the report could not either), that is said in ``problems`` and the rows made
        before are kept."""
        from coevo.experiments.study.declaration import LearnCell
        from coevo.experiments.study.learn_report import collect_learn_cell, learn_cell_rows
        from coevo.experiments.study.report import cell_rows, collect_cell

        def rows(records: list[dict[str, Any]] | None) -> list[dict[str, Any]]:
            if isinstance(cell, LearnCell):
                return learn_cell_rows([cell], collect_learn_cell(self.out, cell) if records is None else records)
            return cell_rows([cell], collect_cell(self.out, cell, known=self._known[cell.id]) if records is None
                             else records)

        held = self._rows.get(cell.id)
        if held is None or held[0] != finished:
            try:
                held = (finished, rows(None), "")
            except (RunDirError, OSError, ValueError, KeyError, TypeError) as exc:
                why = f"cell {cell.id}: a finished run cannot be read ({type(exc).__name__}: {exc})"
                held = (finished, held[1] if held is not None else rows([]), why)
            self._rows[cell.id] = held
        if held[2]:
            problems.append(held[2] + ("; its numbers are from before" if any(r["n"] for r in held[1]) else ""))
        return held[1]

    def _log(self, cell: str, run: str) -> Path:
        """A replicate's log, as the study's runner writes it (``logs/CELL@RUN.log``)."""
        return self.out / "logs" / f"{cell}{self._sep}{run}.log"

    @staticmethod
    def _learn_measures(behaviour: str) -> tuple[tuple[str, str], ...]:
        from coevo.experiments.study.learn_report import learn_measures

        return learn_measures(behaviour)

    def _learn_states(self, cell: Any, quiet: float) -> list[dict[str, Any]]:
        """A learning-run cell's runs: ``{"run", "state", "why"}`` each (module docstring)."""
        from coevo.experiments.study.experiment import cell_dir, learn_jobs

        folder = cell_dir(self.out, cell)
        rows = []
        for job in learn_jobs(cell):
            log = self._log(cell.id, job.name)
            if job.finished(folder):
                state, why = "done", ""
            elif (said := _said(log)) is None:
                state, why = "waiting", ""
            elif said:
                state, why = "failed", f"{said}; see {log}"
            elif quiet < self.stale:
                state, why = "running", ""
            else:
                state, why = "failed", f"no progress for {quiet:.0f} s; see {log}"
            rows.append({"run": job.name, "state": state, "why": why})
        return rows

    def _latest(self) -> float:
        """When any of the study's own files last moved (its declaration, the replicates' logs, the report)."""
        try:
            logs = list((self.out / "logs").iterdir())
        except OSError:
            logs = []
        return max([mtime(self.out / n) for n in ("study.json", "results.json", "complete.json")]
                   + [mtime(p) for p in logs])

    def read(self, shown: list[str]) -> dict[str, Any]:
        """The study as the page shows it: ``{"dir", "name", "description", "kind" (comparison or learn), "behaviour"
        (a study of learning runs': what it learns, else None), "measures" (its measures, [name, title] each),
        "factors", "state", "why", "runs_done",
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
        quiet = time.time() - self._latest()
        for c, cp in zip(self.cells, progress.cells, strict=True):
            reps = states[c.id] = self.files[c.id].states() if c.id in self.files else self._learn_states(c, quiet)
            counts = {s: sum(1 for r in reps if r["state"] == s) for s in totals}
            for s, n in counts.items():
                totals[s] += n
            finished = tuple(r["run"] for r in reps if r["state"] == "done")
            cells.append({"id": c.id, "label": c.label, "seed": c.spec.seed, "runs_done": cp.runs_done,
                          "runs_total": cp.runs_total, "counts": counts,
                          "state": _cell_state(counts, cp.runs_done, cp.runs_total),
                          "failed": [f"{r['run']}: {r['why']}" for r in reps if r["state"] == "failed"],
                          "rows": self._cell_rows(c, finished, problems)})
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
        low = {"generations": ga.generations, "population": ga.population, "episodes": ga.episodes}
        if self.spec.learn is None:
            low["runs a regime"] = min(c.spec.runs for c in self.cells)
        caveat = below_report(low)
        factors = "; ".join(f"{k}: {', '.join(level_text(k, v) for v in lv)}"
                            for k, lv in self.spec.factors.items()) or "none"
        default = next((c["id"] for c in cells if c["state"] == "running"),
                       next((c["id"] for c in cells if c["runs_done"]), cells[0]["id"]))
        learn = self.spec.learn
        measures = [] if learn is None else [list(m) for m in self._learn_measures(learn)]
        return {"dir": str(self.out), "name": self.spec.name, "description": self.spec.description,
                "kind": "comparison" if learn is None else "learn", "behaviour": learn, "measures": measures,
                "factors": factors, "state": state, "why": why, "runs_done": progress.runs_done,
                "runs_total": progress.runs_total, "cells_done": progress.cells_done,
                "cells_total": progress.cells_total, "complete": progress.complete, "counts": totals, "cells": cells,
                "verdict": self._verdict.read(), "caveat": caveat, "problems": problems, "default": default,
                "shown": {cid: self.files[cid].read(states[cid]) for cid in dict.fromkeys([default, *shown])
                          if cid in self.files}}
