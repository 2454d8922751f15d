"""A comparison directory (``coevo compare --out OUT``) as the dashboard shows it: its replicates, done, running,
failed or waiting; the report's Table 1 counted over the runs finished so far beside the report's own counts; the
verdict of its report once written; and the regimes' curves.

The curves are the report's panels (:data:`coevo.experiments.compare.plots.PANELS`: each behaviour's best fitness per
generation, and the Executive's and Docking's measures), per regime: every live run's line (a running one as far as
it got) and, over the finished runs, the mean per generation with its 95 % t interval, none below three runs
(:func:`~coevo.experiments.compare.stats.mean_intervals`, the statistic of the report's Executive-curve table and of
regimes.png, so a band ends on the report's interval at the last generation; the percentile bootstrap used before
covered the mean far less often than 95 % at a comparison's usual 2–10 runs).  A band is computed once per set of
finished runs (a run that has finished no longer changes).

The replicates, their run directories, what "finished" means and the Table 1 classes are the
comparison's own (:mod:`coevo.experiments.compare`), so the page counts exactly what the report
will.  Whether an unfinished replicate is running or failed is read from its files: running while
its log or its workers' logs grew in the last ``stale`` seconds; failed when its run ended
interrupted (``summary.json`` without measures) or went quiet.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from coevo.errors import ConfigError, RunDirError
from coevo.dashboard.files import mtime

if TYPE_CHECKING:
    from coevo.experiments.compare.experiment import CompareSpec, Replicate

__all__ = ["ComparisonFiles"]


class VerdictFile:
    """The verdict in a report's results.json (a comparison's or a study's), read again only when the file changes:
    ``{"text", "finished", "expected"}``, or None before it is written whole."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._held: tuple[float, dict[str, Any] | None] = (-1.0, None)  # (mtime, what it says)

    def read(self) -> dict[str, Any] | None:
        changed = mtime(self.path)
        if changed != self._held[0]:
            try:
                data = json.loads(self.path.read_text(encoding="utf-8"))
                held = {"text": str(data["verdict"]), "finished": int(data["runs_finished"]),
                        "expected": int(data["runs_expected"])}
            except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, ValueError):
                held = None
            self._held = (changed, held)
        return self._held[1]


class ComparisonFiles:
    """A comparison directory, followed."""

    def __init__(self, out: Path, *, stale: float, spec: CompareSpec | None = None,
                 log_of: Callable[[str], Path] | None = None) -> None:
        """``spec``: the comparison's settings when they are known already (a study's cell: from its declaration,
        so a cell whose compare.json is not written yet is shown too), else read from ``out/compare.json``;
        ``log_of``: where a replicate's log is, by its run id (default ``out/logs/RUN.log``)."""
        from coevo.experiments.compare.experiment import CompareSpec, replicates
        from coevo.rundir.layout import read_json

        self.out, self.stale = Path(out), stale
        self.log_of = log_of or (lambda run: self.out / "logs" / f"{run}.log")
        if spec is None:
            marker = read_json(self.out / "compare.json", what="comparison (its compare.json)")
            try:
                spec = CompareSpec.saved(marker["spec"])
            except (KeyError, TypeError, ConfigError) as exc:
                raise RunDirError(f"{self.out / 'compare.json'} is not a comparison's settings: "
                                  f"{str(exc).splitlines()[0]}") from None
        from coevo.experiments.compare.reading import reading_of

        self.spec = spec
        self.reading = reading_of(spec.the_task)  # its panels, its classes of runs (the fuel task's Table 1)
        self.replicates = replicates(self.spec)
        self._classes: dict[str, str] = {}  # a finished replicate's Table 1 class: it no longer changes
        self._curves: dict[str, list[float]] = {}  # ... and its headline curve (best per generation)
        self._tails: dict[tuple[str, str], Any] = {}  # (run, behaviour) -> the Tail of its curve.jsonl
        self._rows: dict[tuple[str, str], list[dict[str, Any]]] = {}  # ... and the rows read so far
        self._bands: dict[tuple[int, str], tuple[tuple[str, ...], dict[str, list[float]] | None]] = {}
        self._verdict = VerdictFile(self.out / "results.json")

    def run_dirs(self) -> list[Path]:
        """The live replicates' run directories that exist so far (their curves go on the page)."""
        from coevo.experiments.compare.experiment import run_dir
        from coevo.rundir.layout import RunPaths

        dirs = [run_dir(self.out, r) for r in self.replicates if not r.offline]
        return [d for d in dirs if RunPaths(d).run_json.exists()]

    def _state(self, rep: Replicate, now: float) -> tuple[str, str]:
        """(state, why) of one replicate."""
        from coevo.experiments.compare.experiment import is_finished, run_dir
        from coevo.rundir.layout import RunPaths

        if rep.run_id in self._classes or is_finished(self.out, rep):
            return "done", ""
        d = run_dir(self.out, rep)
        log = self.log_of(rep.run_id)
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
        latest = max([mtime(log), mtime(d)] + [mtime(w / "curve.jsonl") for w in paths.workers_dir.glob("*")]
                     + [mtime(f) for f in paths.logs_dir.glob("*.log")])
        if now - latest < self.stale:
            return "running", ""
        return "failed", f"no progress for {now - latest:.0f} s; see {log}"

    def _class(self, rep: Replicate) -> str | None:
        """A finished replicate's class (None: its task's reading classes no runs, or its files cannot be read)."""
        from coevo.experiments.compare.experiment import run_dir
        from coevo.rundir.layout import LearnPaths, RunPaths

        classify = self.reading.classify
        if classify is None:
            return None
        if rep.run_id not in self._classes:
            d = run_dir(self.out, rep)
            f = LearnPaths(d).measures if rep.offline else RunPaths(d).summary
            try:
                data = json.loads(f.read_text())
                self._classes[rep.run_id] = classify(data if rep.offline else data["measures"])
            except (OSError, json.JSONDecodeError, KeyError, TypeError, ValueError):
                return None
        return self._classes[rep.run_id]

    def _headline_curve(self, rep: Replicate, behaviour: str) -> list[float]:
        """A finished live replicate's curve of the behaviour its reading quotes (the fuel task's Executive), the
        best of each generation (damaged lines left out)."""
        from coevo.experiments.compare.experiment import run_dir
        from coevo.rundir.layout import RunPaths, read_jsonl

        if rep.run_id not in self._curves:
            rows = read_jsonl(RunPaths(run_dir(self.out, rep)).worker(behaviour).curve, missing_ok=True, problems=[])
            self._curves[rep.run_id] = [float(r["best_fitness"]) for r in rows
                                        if isinstance(r.get("best_fitness"), (int, float))]
        return self._curves[rep.run_id]

    def _curve_rows(self, rep: Any) -> dict[str, list[dict[str, Any]]]:
        """A live replicate's curve rows per behaviour, read on from where the last call stopped."""
        from coevo.dashboard.files import Tail
        from coevo.experiments.compare.experiment import run_dir
        from coevo.rundir.layout import RunPaths

        out = {}
        for b in self.spec.the_task.behaviours:
            key = (rep.run_id, b)
            tail = self._tails.get(key)
            if tail is None:
                tail = self._tails[key] = Tail(RunPaths(run_dir(self.out, rep)).worker(b).curve)
            new = tail.read()
            rows = self._rows.setdefault(key, [])
            if tail.reset:  # a resumed worker cut its log back to its checkpoint
                rows.clear()
            rows += [r for r in new if isinstance(r.get("generation"), int)]
            out[b] = rows
        return out

    def _panels(self, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """The report's panels with, per live regime, its runs' lines and its finished runs' mean and band."""
        import numpy as np

        state = {r["run"]: r["state"] for r in rows}
        by_group: dict[str, list[Replicate]] = {}
        for rep in self.replicates:
            if not rep.offline and state.get(rep.run_id) in ("done", "running", "failed"):
                by_group.setdefault(rep.group, []).append(rep)
        curves = {rep.run_id: self._curve_rows(rep) for reps in by_group.values() for rep in reps}
        panels = []
        for i, the_panel in enumerate(self.reading.panels):
            title, behaviour, column, ylabel, top = the_panel
            groups: dict[str, dict[str, Any]] = {}
            for group, reps in by_group.items():
                lines = []
                for rep in reps:
                    pts = [(int(r["generation"]), float(r[column])) for r in curves[rep.run_id][behaviour]
                           if isinstance(r.get(column), (int, float)) and np.isfinite(r[column])]
                    if pts:
                        lines.append({"run": rep.run_id, "state": state[rep.run_id], "generation": [g for g, _ in pts],
                                      "value": [v for _, v in pts]})
                finished = tuple(ln["run"] for ln in lines if ln["state"] == "done")
                held = self._bands.get((i, group))
                if held is None or held[0] != finished:
                    held = self._bands[(i, group)] = (finished, self._band([ln for ln in lines if ln["run"] in finished],
                                                                           the_panel.bounds))
                groups[group] = {"lines": lines, "band": held[1]}
            panels.append({"title": title, "behaviour": behaviour, "column": column, "ylabel": ylabel, "top": top,
                           "groups": groups})
        return panels

    @staticmethod
    def _band(lines: list[dict[str, Any]], bounds: tuple[float, float] | None = None) -> dict[str, Any] | None:
        """The mean per generation of finished runs' lines and its 95 % interval (NaN ends below three runs), cut
        at ``bounds``, the panel's measure's range (``clipped``: the ends it was cut at, [] for none); None below
        two runs."""
        import numpy as np

        from coevo.experiments.compare.stats import clip, mean_intervals

        if len(lines) < 2:
            return None
        last = max(g for ln in lines for g in ln["generation"])
        m = np.full((len(lines), last), np.nan)
        for k, ln in enumerate(lines):
            m[k, np.asarray(ln["generation"]) - 1] = ln["value"]
        mean, low, high = mean_intervals(m)
        low, high, cut = clip(low, high, bounds)
        keep = ~np.isnan(mean)
        return {"generation": [int(g) for g in np.flatnonzero(keep) + 1], "mean": mean[keep].tolist(),
                "low": low[keep].tolist(), "high": high[keep].tolist(), "clipped": list(cut),
                "n": (~np.isnan(m)).sum(axis=0)[keep].astype(int).tolist()}

    def states(self) -> list[dict[str, Any]]:
        """Each replicate's state (done, running, failed, waiting), why (a failed one), Table 1 class (a done one)
        and worker generations of the total: ``{"run", "group", "state", "why", "class", "generations", "of"}``."""
        from coevo.experiments.compare.experiment import generations_done, generations_of

        now = time.time()
        rows = []
        for rep in self.replicates:
            state, why = self._state(rep, now)
            cls = self._class(rep) if state == "done" else None
            total = generations_of(self.spec, rep)
            done = total if state == "done" else min(total, generations_done(self.out, rep,
                                                                              self.spec.the_task.behaviours))
            rows.append({"run": rep.run_id, "group": rep.group, "state": state, "why": why, "class": cls or "",
                         "generations": done, "of": total})
        return rows

    def read(self, states: list[dict[str, Any]] | None = None) -> dict[str, Any]:
        """Replicates by state, the Table 1 so far beside the report's, the headline curve (its reading's: the fuel task's Executive) of the finished live runs,
        the verdict and the regimes' panels: ``{"dir", "replicates": [...], "counts", "table1", "table1_report",
        "curve", "headline_curve", "verdict", "caveat", "panels", "regimes", "lengths"}`` (``lengths``: rows read per curve, what tells
        the page its panels changed); ``states``: :meth:`states` when just read."""
        from coevo.experiments.common import below_report
        from coevo.experiments.compare.experiment import OFFLINE, groups
        from collections import Counter

        from coevo.experiments.compare.report import executive_curve

        reading = self.reading
        rows = self.states() if states is None else states
        classes: dict[str, list[str]] = {g: [] for g in groups(self.spec)}
        curves: dict[str, list[list[float]]] = {g: [] for g in groups(self.spec)}
        for rep, row in zip(self.replicates, rows, strict=True):
            if row["class"]:
                classes.setdefault(rep.group, []).append(row["class"])
            if row["state"] == "done" and not rep.offline and reading.curve is not None:
                curves.setdefault(rep.group, []).append(self._headline_curve(rep, reading.curve))
        counts = {s: sum(1 for r in rows if r["state"] == s) for s in ("done", "running", "failed", "waiting")}
        ga = self.spec.ga
        caveat = below_report({"generations": ga.generations, "population": ga.population, "episodes": ga.episodes,
                               "runs a regime": self.spec.runs})
        return {"dir": str(self.out), "replicates": rows, "counts": counts, "classes": list(reading.classes),
                "table1": {g: {k: Counter(c).get(k, 0) for k in reading.classes} for g, c in classes.items()},
                "table1_report": {g: dict(reading.report_counts[g]) for g in classes if g in reading.report_counts},
                "finished": {g: sum(1 for rep, row in zip(self.replicates, rows, strict=True)
                                    if rep.group == g and row["state"] == "done") for g in groups(self.spec)},
                "curve": reading.curve,
                "headline_curve": {g: executive_curve(c) for g, c in curves.items() if c},
                "verdict": self._verdict.read(), "caveat": caveat, "panels": self._panels(rows),
                "regimes": [r for r in self.spec.regimes if r != OFFLINE],  # the live ones: those with curves
                "lengths": {f"{run}/{b}": len(r) for (run, b), r in sorted(self._rows.items())}}
