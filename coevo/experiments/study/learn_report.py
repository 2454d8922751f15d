"""A study of learning runs' report (``learn``): per cell the behaviour's final measures over its runs; per factor a
test and a plot.

Every number is read from the runs' own ``measures.json`` (what ``coevo learn`` wrote of its best policy on fresh
trials), so the report can be rebuilt at any time (``--report-only``).

Per cell, each of the behaviour's measures (:data:`LEARN_MEASURES`: its learning target's measure first, as ``coevo
seeds`` judges it, then a second of its own and the GA's best fitness) as the mean over the cell's finished runs with
its 95 % t interval, none below three runs (:func:`~coevo.experiments.compare.stats.mean_interval`), and
the median.

Per factor with two levels or more, on each measure: the Kruskal–Wallis test across its levels, pooled over the
other factors' levels, its ε², and the largest difference between two levels that the data allow
(:func:`~coevo.experiments.study.report.factor_test`, as a comparison study's); the p-values of every test in the
study corrected together with Holm's method; the verdict reads the corrected ones.

Files: ``results.json`` (everything, and every run's measures), ``report.md``, ``effect-FACTOR.png``, ``cells.png``.
"""

from __future__ import annotations

import json
import math
import statistics
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.experiments.common import below_report, plural
from coevo.experiments.compare.stats import format_p, mean_interval
from coevo.experiments.glossary import bounds_of
from coevo.experiments.seeds.experiment import TARGETS
from coevo.experiments.study import plots
from coevo.experiments.study.declaration import LearnCell, StudySpec, learn_cells, level_text
from coevo.experiments.study.experiment import cell_dir, learn_jobs
from coevo.experiments.study.report import (adjust, difference_unit, factor_test, format_mean, report_head, strict_json,
                                          verdict_lines)
from coevo.rundir.layout import write_json, write_text

__all__ = ["LEARN_MEASURES", "learn_measures", "collect_learn_cell", "learn_cell_rows", "analyse_learning", "write_learn_report"]

#: Each behaviour's measures in its report, as (name in measures.json, title): the learning target's first.
LEARN_MEASURES: dict[str, tuple[tuple[str, str], ...]] = {
    "docking": ((TARGETS["docking"][0], "Docking from random starts (%)"),
                ("docking_success_rate", "Docking success rate (%)"), ("best_fitness", "best fitness")),
    "tracking": ((TARGETS["tracking"][0], "Quality Tracking (%)"),
                 ("collision_rate", "collision rate (%)"), ("best_fitness", "best fitness")),
}


def learn_measures(behaviour: str) -> tuple[tuple[str, str], ...]:
    """The measures a study reports of ``behaviour``'s runs: the fuel task's (:data:`LEARN_MEASURES`), else its task's
    declared measures (``Task.measure_labels``' names, as the glossary names them) and the GA's best fitness."""
    if behaviour in LEARN_MEASURES:
        return LEARN_MEASURES[behaviour]
    from coevo.experiments.glossary import label
    from coevo.tasks import task_of

    return (*((k, label(k)) for k in task_of(behaviour).measure_labels), ("best_fitness", "best fitness"))


def _value(record: dict[str, Any], key: str) -> float:
    v = record["measures"].get(key)
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else float("nan")


def collect_learn_cell(out: Path, cell: LearnCell) -> list[dict[str, Any]]:
    """One record per finished run of ``cell``: its cell, run, seed, the cell's levels, its measures.json and its
    seconds.  A finished run whose files cannot be read is a RunDirError naming it."""
    folder = cell_dir(out, cell)
    records = []
    for job, seed in zip(learn_jobs(cell), cell.spec.seeds, strict=True):
        if not job.finished(folder):
            continue
        d = folder / job.output
        try:
            measures = json.loads((d / "measures.json").read_text())
            seconds = float(json.loads((d / "timing.json").read_text())["seconds"])
            if not isinstance(measures, dict):
                raise TypeError(f"measures.json holds {type(measures).__name__}, not a table")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise RunDirError(f"{d}: a finished learning run cannot be read ({type(exc).__name__}: {exc})") from None
        records.append({"cell": cell.id, "run": job.name, "seed": seed, "levels": dict(cell.levels),
                        "measures": measures, "seconds": seconds})
    return records


def _summary(values: list[float], key: str) -> dict[str, Any]:
    v = [x for x in values if not math.isnan(x)]
    return {**mean_interval(v, bounds=bounds_of(key)).as_dict(), "median": statistics.median(v) if v else float("nan")}


def learn_cell_rows(the_cells: list[LearnCell], records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per cell: its runs (``n`` of ``runs_expected``) and each of the behaviour's measures as a mean with its 95 %
    t interval, and the median."""
    rows = []
    for c in the_cells:
        xs = [x for x in records if x["cell"] == c.id]
        rows.append({"cell": c.id, "levels": dict(c.levels), "label": c.label, "seed": c.spec.seed,
                     "seeds": c.spec.seeds, "runs_expected": c.spec.runs, "n": len(xs),
                     "measures": {k: _summary([_value(x, k) for x in xs], k)
                                  for k, _ in learn_measures(c.spec.behaviour)}})
    return rows


def analyse_learning(spec: StudySpec, records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every factor's test on every measure (module docstring), with Holm-adjusted p-values; each level's summary
    also has its median."""
    behaviour = str(spec.learn)
    tests: list[dict[str, Any]] = []
    for factor, levels in spec.between.items():
        by_level = {level_text(factor, lv): [x for x in records if x["levels"].get(factor) == lv] for lv in levels}
        for measure, _ in learn_measures(behaviour):
            samples = {k: [v for v in (_value(x, measure) for x in rs) if not math.isnan(v)]
                       for k, rs in by_level.items()}
            t = factor_test(factor, behaviour, measure, samples, share=False, bounds=bounds_of(measure))
            if t is not None:
                for row in t["levels"]:
                    got = samples[row["level"]]
                    row["median"] = statistics.median(got) if got else float("nan")
                tests.append(t)
    return adjust(tests)


def _verdict(behaviour: str, tests: list[dict[str, Any]], finished: int, expected: int) -> str:
    titles = dict(learn_measures(behaviour))
    parts = verdict_lines(tests, lambda t: (f"{behaviour}'s {titles[t['measure']]}", ""), finished, expected)
    return "\n".join(p if p.startswith("- ") else f"\n{p}\n" for p in parts).strip()


def write_learn_report(out: Path, spec: StudySpec, *, elapsed: float | None = None) -> dict[str, Any]:
    """Write results.json, report.md and the figures of a study of learning runs; returns the results.  A
    RunDirError when no run finished."""
    out = Path(out)
    behaviour = str(spec.learn)
    the_cells = learn_cells(spec)
    records = [x for c in the_cells for x in collect_learn_cell(out, c)]
    if not records:
        raise RunDirError(f"{out} holds no finished runs to report on")
    expected = sum(c.spec.runs for c in the_cells)
    rows = learn_cell_rows(the_cells, records)
    tests = analyse_learning(spec, records)
    verdict = _verdict(behaviour, tests, len(records), expected)
    ga = the_cells[0].spec.ga
    caveat = below_report({"generations": ga.generations, "population": ga.population, "episodes": ga.episodes})
    figures = _figures(out, behaviour, tests, rows, records)
    results = {
        "kind": "learn", "behaviour": behaviour, "measures": [k for k, _ in learn_measures(behaviour)],
        "spec": spec.as_dict(),
        "cells": [{"id": c.id, "levels": dict(c.levels), "seed": c.spec.seed, "seeds": c.spec.seeds,
                   "settings": json.loads(c.spec.model_dump_json()), "learn_args": list(c.args)} for c in the_cells],
        "runs_expected": expected, "runs_finished": len(records), "cell_rows": rows, "tests": tests,
        "verdict": verdict, "caveat": caveat, "elapsed_seconds": elapsed, "figures": figures, "runs": records,
    }
    write_json(out / "results.json", strict_json(results))
    write_text(out / "report.md", _markdown(spec, the_cells, rows, tests, verdict, caveat, figures, len(records),
                                            expected, elapsed))
    return results


def _figures(out: Path, behaviour: str, tests: list[dict[str, Any]], rows: list[dict[str, Any]],
             records: list[dict[str, Any]]) -> list[str]:
    titles = dict(learn_measures(behaviour))
    files = []
    for factor in dict.fromkeys(t["factor"] for t in tests):
        mine = [t for t in tests if t["factor"] == factor]
        panels = {t["measure"]: {behaviour: t["levels"]} for t in mine}
        name = f"effect-{factor}.png"
        plots.effect_figure(factor, [r["level"] for r in mine[0]["levels"]], panels, titles, out / name)
        files.append(name)
    key, title = learn_measures(behaviour)[0]
    shown = [r for r in rows if r["n"]]
    if shown:
        values = {r["cell"]: [_value(x, key) for x in records if x["cell"] == r["cell"]] for r in shown}
        plots.learn_cells_figure([r["cell"] for r in shown], values, [r["measures"][key] for r in shown], title,
                                 out / "cells.png")
        files.append("cells.png")
    return files


def _markdown(spec: StudySpec, the_cells: list[LearnCell], rows: list[dict[str, Any]], tests: list[dict[str, Any]],
              verdict: str, caveat: str, figures: list[str], finished: int, expected: int,
              elapsed: float | None) -> str:
    behaviour = str(spec.learn)
    measures = learn_measures(behaviour)
    titles = dict(measures)
    c0 = the_cells[0].spec
    runs = sorted({c.spec.runs for c in the_cells})  # (runs may be a factor)
    each = plural(runs[0], "run") if len(runs) == 1 else f"{runs[0]} to {runs[-1]} runs"
    lines = report_head(spec, f"A study of learning runs: {plural(len(the_cells), 'cell')}, each "
                              f"{each} of `coevo learn --behaviour {behaviour}`, one per seed. {finished} of {expected} "
                              "runs finished", elapsed,
                        f"GA: {c0.ga.generations} generations, population {c0.ga.population}, {c0.ga.episodes} episodes "
                        f"per evaluation; each final policy measured on {c0.measure_epochs} fresh epochs.", caveat, verdict)
    lines += ["Each measure of the cell's runs' best policies (their measures.json): the mean with its 95 % t "
              "interval (none below 3 runs), and the median.", "",
              "| cell | cell seed | runs | " + " | ".join(f"{t} mean [95 %] | median" for _, t in measures) + " |",
              "|---|---|---|" + "---|---|" * len(measures)]
    for r in rows:
        vals = []
        for k, _ in measures:
            m = r["measures"][k]
            vals += [format_mean(m, False), "–" if math.isnan(m["median"]) else f"{m['median']:.2f}"]
        lines.append(f"| {r['cell']} | {r['seed']} | {r['n']}/{r['runs_expected']} | " + " | ".join(vals) + " |")
    lines.append("")
    if tests:
        lines += ["## Factor tests", "",
                  "Kruskal–Wallis across the factor's levels, pooled over the other factors; p-values corrected "
                  f"together with Holm's method ({len(tests)} tests); *largest difference*: the farthest end of any "
                  "two levels' 95 % Welch t interval of their difference (– when a level has too few runs): a larger "
                  "difference would very likely have been seen. p is exact for small designs; *smallest p possible*: the "
                  "lowest any outcome of this many runs can give.", "",
                  "| factor | measure | levels (mean [95 %]; median) | H | p | smallest p possible | Holm p | ε² | "
                  "largest difference |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for t in tests:
            levels = "; ".join(f"{r['level']}: {format_mean(r, False)}; {r['median']:.2f}" if r["n"] else
                               f"{r['level']}: –" for r in t["levels"])
            big = "–" if math.isnan(t["largest_difference"]) else difference_unit(False, t["largest_difference"])
            lines.append(f"| {t['factor']} | {titles[t['measure']]} | {levels} | {t['h']:.2f} | {format_p(t['p'])} | "
                         f"{format_p(t['min_p'])} | {format_p(t['p_holm'])} | {t['epsilon2']:.2f} ({t['magnitude']}) | "
                         f"{big} |")
        lines.append("")
    lines += ["## Figures", ""] + [f"![{f}]({f})" for f in figures]
    lines += ["", "Files: `results.json` (everything above, and every run's measures), `study.json` (the declaration), "
              "`cells/CELL/learn.json` (a cell's settings and its runs' `coevo learn` arguments), "
              f"`cells/CELL/runs/{behaviour}-seedN/` (each a `coevo learn` folder: its curve, best rules and measures; "
              "`coevo show` replays its best policy).", ""]
    return "\n".join(lines)
