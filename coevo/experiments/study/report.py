"""A study's report: per cell Table 1 with intervals and the Executive's measures; per factor a test and a plot.

Everything is computed from the cells' run files (each cell read by the comparison's own
:func:`~coevo.experiments.compare.report.collect`), so the report can be rebuilt at any time (``--report-only``).

Per cell and group (a regime, or independent-offline at one rate): the nine Table 1 classes and the three docking
classes, each k of n with its 95 % Wilson interval (:mod:`.intervals`); the Executive curve's end (its best fitness
at the last generation) and the Average Epoch Length (AEL), each a mean with its 95 % t interval, none below three
runs (:func:`~coevo.experiments.compare.stats.mean_interval`).

Per factor with two levels or more, and per stratum (a between-cell factor is tested within each group; ``regime``
across the live regimes; ``rate`` across independent-offline's rates), on each of four measures (the Executive
curve's end, AEL, and the shares of Good Docking and of No Docking runs): the Kruskal–Wallis test across the
levels, pooled over the other factors' levels (on a 0/1 measure it is the χ² test of the 2 × k table, scaled by
(N − 1)/N; exact for small designs, with the smallest p its design can give), its ε², and the largest difference
between two levels that the data allow (:mod:`.intervals`).  The p-values of every test in the study are corrected
together with Holm's method; the verdict reads the corrected ones, and never calls an effect absent beside a large
effect size or a pair of levels whose 95 % interval of their difference excludes 0: that is "not established", with
the reason (decided on the pairs' differences, not on whether the levels' own intervals overlap).

Files: ``results.json`` (everything), ``report.md``, ``effect-FACTOR.png``, ``cells.png``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.experiments.common import below_report
from coevo.experiments.compare.experiment import OFFLINE, groups, replicates
from coevo.experiments.compare.report import collect
from coevo.experiments.compare.stats import (MeanInterval, compare_groups, design_floor, format_p, holm,
                                             mean_interval)
from coevo.experiments.compare.table1 import CLASSES, DOCKING, REPORT_COUNTS
from coevo.experiments.glossary import TERMS, bounds_of, label
from coevo.experiments.study import plots
from coevo.experiments.study.declaration import Cell, StudySpec, cells, level_text
from coevo.experiments.study.experiment import cell_dir
from coevo.experiments.study.intervals import Difference, difference_interval, share_difference, wilson
from coevo.rundir.layout import write_json, write_text

__all__ = ["MEASURES", "collect_cell", "collect_study", "cell_rows", "analyse", "factor_test", "adjust", "write_report",
           "strict_json", "format_mean", "difference_unit", "verdict_lines", "undecided", "excluding_zero",
           "difference_text"]

#: The measures every factor is tested on: name -> (title, value of a run record, is it a 0/1 share?).
MEASURES: dict[str, tuple[str, Callable[[dict[str, Any]], float], bool]] = {
    "executive_end": (f"{label('executive_end')} (generation's best fitness)", lambda r: _executive_end(r), False),
    "average_epoch_length": (f"{label('average_epoch_length')} (episodes)",
                             lambda r: float(r["measures"]["average_epoch_length"]), False),
    "good_docking": (f"{label('good_docking')} (share of runs)",
                     lambda r: float(r["class"].startswith("Good Docking")), True),
    "no_docking": (f"{label('no_docking')} (share of runs)", lambda r: float(r["class"].startswith("No Docking")), True),
}
ALPHA = 0.05


def _executive_end(record: dict[str, Any]) -> float:
    curve = record["curves"].get("executive", {}).get("best_fitness", [])
    return float(curve[-1]) if curve else float("nan")


def collect_cell(out: Path, cell: Cell, *, known: dict[str, dict[str, Any]] | None = None) -> list[dict[str, Any]]:
    """One record per finished run of ``cell``: the comparison's record, plus ``cell`` and the run's level of every
    factor (``known``: records already made, by run id, as :func:`~coevo.experiments.compare.report.collect`)."""
    return [x | {"cell": cell.id, "levels": {**dict(cell.levels), "regime": x["regime"], "rate": x["rate"]}}
            for x in collect(cell_dir(out, cell), cell.spec, known=known)]


def collect_study(out: Path, spec: StudySpec) -> tuple[list[Cell], list[dict[str, Any]]]:
    """The cells, and one record per finished run of any cell (:func:`collect_cell`)."""
    the_cells = cells(spec)
    return the_cells, [x for c in the_cells for x in collect_cell(out, c)]


def _summary(values: Sequence[float], share: bool, bounds: tuple[float, float] | None = None) -> dict[str, Any]:
    """Mean with its interval: Wilson for a 0/1 share, Student t for the rest (cut at ``bounds``, the measure's
    range)."""
    v = [x for x in values if not math.isnan(x)]
    if share:
        p = wilson(int(sum(v)), len(v))
        return {"n": p.n, "mean": p.p, "low": p.low, "high": p.high}
    return mean_interval(v, bounds=bounds).as_dict()


def cell_rows(the_cells: list[Cell], records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per cell and group: its runs (``n`` of ``runs_expected``), Table 1's classes and the docking classes as k of n
    with 95 % Wilson intervals, and the Executive curve's end and AEL as means with 95 % t intervals."""
    rows = []
    for c in the_cells:
        for g in groups(c.spec):
            xs = [x for x in records if x["cell"] == c.id and x["group"] == g]
            expected = sum(1 for r in replicates(c.spec) if r.group == g)
            classes = [x["class"] for x in xs]
            rows.append({
                "cell": c.id, "levels": dict(c.levels), "group": g, "seed": c.spec.seed, "runs_expected": expected,
                "n": len(xs),
                "table1": {k: wilson(classes.count(k), len(xs)).as_dict() for k in CLASSES},
                "docking": {d: wilson(sum(1 for k in classes if k.startswith(d)), len(xs)).as_dict() for d in DOCKING},
                "good_docking": wilson(sum(1 for k in classes if k.startswith("Good Docking")), len(xs)).as_dict(),
                "no_docking": wilson(sum(1 for k in classes if k.startswith("No Docking")), len(xs)).as_dict(),
                "executive_end": mean_interval([_executive_end(x) for x in xs], bounds=bounds_of("executive_end")).as_dict(),
                "average_epoch_length": mean_interval([x["measures"]["average_epoch_length"] for x in xs]).as_dict(),
            })
    return rows


def _strata(spec: StudySpec, records: list[dict[str, Any]]) -> list[tuple[str, str, list[dict[str, Any]], list[Any]]]:
    """(factor, stratum, its records, the factor's levels) for every test the study makes."""
    out = []
    for name, levels in spec.between.items():
        for g in dict.fromkeys(x["group"] for x in records):
            out.append((name, g, [x for x in records if x["group"] == g], list(levels)))
    factors = spec.factors
    if "regime" in factors:
        live = [r for r in factors["regime"] if r != OFFLINE]
        if len(live) > 1:
            out.append(("regime", "live regimes", [x for x in records if x["regime"] in live], live))
    if "rate" in factors:
        out.append(("rate", OFFLINE, [x for x in records if x["rate"] is not None], list(factors["rate"])))
    return out


def analyse(spec: StudySpec, records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every factor test (module docstring), with Holm-adjusted p-values."""
    tests: list[dict[str, Any]] = []
    for factor, stratum, xs, levels in _strata(spec, records):
        by_level = {level_text(factor, lv): [x for x in xs if x["levels"].get(factor) == lv] for lv in levels}
        for measure, (_, value, share) in MEASURES.items():
            samples = {k: [v for v in (value(x) for x in rs) if not math.isnan(v)] for k, rs in by_level.items()}
            t = factor_test(factor, stratum, measure, samples, share=share, bounds=bounds_of(measure))
            if t is not None:
                tests.append(t)
    return adjust(tests)


def factor_test(factor: str, stratum: str, measure: str, samples: dict[str, list[float]], *,
                share: bool, bounds: tuple[float, float] | None = None) -> dict[str, Any] | None:
    """One factor's test on one measure in one stratum (``samples``: each level's values, NaN left out, in the
    factor's order): Kruskal–Wallis across the levels with runs, its ε², each level's summary (a mean's interval cut
    at ``bounds``, the measure's range) and every two levels' difference; None when fewer than two levels have
    runs."""
    present: dict[str, Sequence[float]] = {k: v for k, v in samples.items() if v}
    if len(present) < 2:
        return None
    g = compare_groups(measure, present)
    names = list(present)
    diffs = [_difference(a, present[a], b, present[b], share) for i, a in enumerate(names) for b in names[i + 1:]]
    farthest = [d.bound for d in diffs]
    return {
        "factor": factor, "stratum": stratum, "measure": measure, "share": share,
        "levels": [{"level": k, **_summary(samples[k], share, bounds)} for k in samples],
        "h": g.h, "p": g.p_value, "min_p": g.min_p, "epsilon2": g.epsilon2, "magnitude": g.magnitude, "n": g.n,
        # only when every pair has an interval: "excluded by every pair's interval" is then true
        "largest_difference": (max(farthest) if farthest and not any(math.isnan(b) for b in farthest)
                               else float("nan")),
        "differences": [d.as_dict() for d in diffs],
    }


def adjust(tests: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``tests`` with their p-values corrected together with Holm's method (``p_holm``) and ``detected`` at 5 %."""
    for t, p in zip(tests, holm([float(t["p"]) for t in tests]), strict=True):
        t["p_holm"] = p
        t["detected"] = p < ALPHA
    return tests


def _difference(a: str, xa: Sequence[float], b: str, xb: Sequence[float], share: bool) -> Difference:
    if share:
        return share_difference(a, int(sum(xa)), len(xa), b, int(sum(xb)), len(xb))
    return difference_interval(a, xa, b, xb, seed=7)


def format_mean(row: dict[str, Any], share: bool) -> str:
    """A level's or cell's summary as the reports print it (its n shown elsewhere): a share with its Wilson
    interval, a mean with its t interval or why it has none (:meth:`MeanInterval.text`)."""
    if row["n"] == 0:
        return "–"
    if share:
        return f"{100 * row['mean']:.0f} % [{100 * row['low']:.0f}–{100 * row['high']:.0f}]"
    low, high = (float("nan") if row[k] is None else float(row[k]) for k in ("low", "high"))  # null in results.json
    return MeanInterval(int(row["n"]), float(row["mean"]), low, high, tuple(row.get("clipped") or ())).text(runs=False)


def _nan(x: Any) -> float:
    """A number of results.json (null for NaN) as a float."""
    return float("nan") if x is None else float(x)


def excluding_zero(test: dict[str, Any]) -> list[dict[str, Any]]:
    """The pairs of levels whose 95 % interval of their difference (Welch's for means, Newcombe's for shares:
    :mod:`.intervals`) lies wholly above or below 0; a pair without an interval (too few runs) is none of them."""
    return [d for d in test.get("differences", []) if _nan(d["low"]) > 0 or _nan(d["high"]) < 0]


def difference_text(d: dict[str, Any], share: bool) -> str:
    """'off − 2 = -0.06 [-0.11, -0.01]'; of shares in percentage points: 'current − best = +18 percentage points
    [+3, +32]'."""
    scale, digits, unit = (100, 0, " percentage points") if share else (1, 2, "")
    low, diff, high = (f"{scale * _nan(d[k]):+.{digits}f}" for k in ("low", "diff", "high"))
    return f"{d['b']} − {d['a']} = {diff}{unit} [{low}, {high}]"


def undecided(test: dict[str, Any]) -> str:
    """Why a test that detected nothing cannot be read as "no effect" ('' when it can): a large effect size, or a
    pair of levels whose 95 % interval of their difference excludes 0 (decided on the difference, never on whether
    the levels' own intervals overlap: two intervals can overlap while their difference's excludes 0)."""
    if test["detected"]:
        return ""
    why = []
    if test["magnitude"] == "large":
        why.append(f"the effect size is large (ε² = {test['epsilon2']:.2f})")
    apart = [difference_text(d, bool(test.get("share", False))) for d in excluding_zero(test)]
    if len(apart) == 1:
        why.append(f"the 95 % interval of the difference {apart[0]} excludes 0")
    elif apart:
        why.append("the 95 % intervals of the differences " + ", ".join(apart[:-1]) + f" and {apart[-1]} exclude 0")
    return " and ".join(why)


def difference_unit(share: bool, x: float) -> str:
    return f"{100 * x:.0f} percentage points" if share else f"{x:.2f}"


def _verdict(spec: StudySpec, cell_rows: list[dict[str, Any]], tests: list[dict[str, Any]], finished: int,
             expected: int) -> str:
    parts = verdict_lines(tests, lambda t: (MEASURES[t["measure"]][0], f" in {t['stratum']}"), finished,
                          expected)
    starved = [r for r in cell_rows if r["n"] and r["no_docking"]["k"] * 2 > r["n"]]
    if starved:
        parts.append("Docking starved (No Docking) in most runs of: " + "; ".join(
            f"{r['cell']} · {r['group']} ({r['no_docking']['k']}/{r['n']}, 95 % "
            f"{100 * r['no_docking']['low']:.0f}–{100 * r['no_docking']['high']:.0f} %)" for r in starved) + ".")
    return "\n".join(p if p.startswith("- ") else f"\n{p}\n" for p in parts).strip()


def verdict_lines(tests: list[dict[str, Any]], subject: Callable[[dict[str, Any]], tuple[str, str]], finished: int,
                  expected: int) -> list[str]:
    """The verdict's lines: partial or not, then each test in words (the detected first).  ``subject(test)`` names
    what it measured in two parts, the second left out of the bold (e.g. "average epoch length (episodes)",
    " in mutual")."""
    parts = []
    if finished < expected:
        parts.append(f"**Partial**: {finished} of {expected} runs finished; the numbers below are from those.")
    for t in sorted(tests, key=lambda t: not t["detected"]):
        share = bool(t.get("share", False))
        what, where = subject(t)
        levels = "; ".join(f"{r['level']}: {format_mean(r, share)}" for r in t["levels"])
        if t["detected"]:
            parts.append(f"- **{t['factor']} changes {what}**{where} ({levels}; Kruskal–Wallis "
                         f"H = {t['h']:.2f}, p = {format_p(t['p'])}, Holm-adjusted {format_p(t['p_holm'])}; ε² = "
                         f"{t['epsilon2']:.2f}, {t['magnitude']}).")
        else:
            runs = f"{t['n']} runs in {len(t['levels'])} levels"
            floor = design_floor(float(t.get("min_p", 0.0)), runs)
            p_text = f"Holm-adjusted p = {format_p(t['p_holm'])}" + (f"; {floor}" if floor else "")
            why = undecided(t)
            if why:
                parts.append(f"- **Not established**: an effect of {t['factor']} on {what}{where} ({levels}; {p_text}):"
                             f" {why}, but the test does not reach 5 % after Holm's correction; more runs would tell.")
                continue
            if float(t.get("min_p", 0.0)) >= ALPHA:  # "no detectable effect" from a test that could detect none
                parts.append(f"- Too few runs to test {t['factor']} on {what}{where}: {runs} cannot give p below "
                             f"{format_p(t['min_p'])} ({levels}).")
                continue
            res = ("; too few runs to bound the difference between two levels (an interval needs 3 runs a level)"
                   if math.isnan(t["largest_difference"]) else
                   f"; a difference between two levels beyond {difference_unit(share, t['largest_difference'])} is "
                   "excluded by every pair's 95 % interval")
            parts.append(f"- No detectable effect of {t['factor']} on {what}{where} ({p_text}; {levels}{res}).")
    if not tests:
        parts.append("No factor has two levels with finished runs: nothing to test; the cells' numbers are below.")
    return parts


def write_report(out: Path, spec: StudySpec, *, elapsed: float | None = None) -> dict[str, Any]:
    """Write results.json, report.md and the figures; returns the results.  A RunDirError when no run finished.
    A study of learning runs has its own report (:func:`.learn_report.write_learn_report`)."""
    if spec.learn is not None:
        raise ValueError("a study of learning runs is reported by learn_report.write_learn_report")
    out = Path(out)
    the_cells, records = collect_study(out, spec)
    if not records:
        raise RunDirError(f"{out} holds no finished runs to report on")
    expected = sum(len(replicates(c.spec)) for c in the_cells)
    rows = cell_rows(the_cells, records)
    tests = analyse(spec, records)
    verdict = _verdict(spec, rows, tests, len(records), expected)
    ga = the_cells[0].spec.ga
    runs = sorted({c.spec.runs for c in the_cells})
    caveat = below_report({"generations": ga.generations, "population": ga.population, "episodes": ga.episodes,
                           "runs a regime": min(runs)})
    figures = _figures(out, spec, tests, rows)
    results = {
        "spec": spec.as_dict(), "cells": [{"id": c.id, "levels": dict(c.levels), "seed": c.spec.seed,
                                           "settings": json.loads(c.spec.model_dump_json())} for c in the_cells],
        "runs_expected": expected, "runs_finished": len(records), "cell_rows": rows, "tests": tests,
        "verdict": verdict, "caveat": caveat, "elapsed_seconds": elapsed, "figures": figures,
        "runs": [{k: x[k] for k in ("cell", "run", "group", "seed", "class", "measures", "levels", "seconds")}
                 | {"executive_end": _executive_end(x)} for x in records],
    }
    write_json(out / "results.json", strict_json(results))
    write_text(out / "report.md", _markdown(spec, the_cells, rows, tests, verdict, caveat, figures, len(records),
                                            expected, elapsed))
    return results


def strict_json(x: Any) -> Any:
    """NaN as null: results.json is strict JSON (a browser's JSON.parse refuses NaN)."""
    if isinstance(x, float):
        return None if math.isnan(x) or math.isinf(x) else x
    if isinstance(x, dict):
        return {k: strict_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [strict_json(v) for v in x]
    return x


def _figures(out: Path, spec: StudySpec, tests: list[dict[str, Any]], rows: list[dict[str, Any]]) -> list[str]:
    files = []
    for factor in dict.fromkeys(t["factor"] for t in tests):
        mine = [t for t in tests if t["factor"] == factor]
        levels = [r["level"] for r in mine[0]["levels"]]
        panels: dict[str, dict[str, list[dict[str, Any]]]] = {}
        for t in mine:
            panels.setdefault(t["measure"], {})[t["stratum"]] = t["levels"]
        name = f"effect-{factor}.png"
        plots.effect_figure(factor, levels, panels, {m: v[0] for m, v in MEASURES.items()}, out / name)
        files.append(name)
    if any(r["n"] for r in rows):
        plots.cells_figure([r for r in rows if r["n"]], out / "cells.png")
        files.append("cells.png")
    return files


def report_head(spec: StudySpec, count: str, elapsed: float | None, settings: str, caveat: str,
                verdict: str) -> list[str]:
    """report.md's lines down to its "## Cells" heading, for either kind of study: the title and description,
    ``count`` (what ran and finished) with the time taken and the base seed, the factors and the fixed levels
    (``learn`` is what kind of study it is, said in ``count``) before ``settings``, the caveat and the verdict."""
    fixed = ", ".join(f"{k} {level_text(k, v)}" for k, v in spec.fixed.items() if k != "learn") or "none"
    factors = "; ".join(f"{k}: {', '.join(level_text(k, v) for v in lv)}" for k, lv in spec.factors.items()) or "none"
    lines = [f"# Study `{spec.name}`", ""]
    if spec.description:
        lines += [spec.description, ""]
    lines += [count + (f" (the last coevo study command on it took {elapsed / 60:.1f} min)" if elapsed else "")
              + f"; base seed {spec.seed}.", "", f"Factors: {factors}. Fixed: {fixed}. {settings}", ""]
    if caveat:
        lines += [caveat, ""]
    return lines + ["## Verdict", "", verdict, "", "## Cells", ""]


def _markdown(spec: StudySpec, the_cells: list[Cell], rows: list[dict[str, Any]], tests: list[dict[str, Any]],
              verdict: str, caveat: str, figures: list[str], finished: int, expected: int,
              elapsed: float | None) -> str:
    c0 = the_cells[0].spec
    lines = report_head(spec, f"{len(the_cells)} cells, {finished} of {expected} runs finished", elapsed,
                        f"GA: {c0.ga.generations} generations, population {c0.ga.population}, {c0.ga.episodes} "
                        "episodes per evaluation.", caveat, verdict)
    lines += ["Shares are k/n with the 95 % Wilson interval; means with the 95 % t interval (none below 3 runs). "
              f"Executive end: {TERMS['executive_end'].definition} AEL: Average Epoch Length, "
              f"{TERMS['average_epoch_length'].definition} (docs/glossary.md lists every measure once.)", "",
              "| cell | group | cell seed | runs | Good Docking | No Docking | Executive end | AEL |",
              "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['cell']} | {r['group']} | {r['seed']} | {r['n']}/{r['runs_expected']} | "
                     f"{wilson(r['good_docking']['k'], r['n']).text()} | {wilson(r['no_docking']['k'], r['n']).text()} | "
                     f"{format_mean(r['executive_end'], False)} | {format_mean(r['average_epoch_length'], False)} |")
    lines += ["", "## Table 1 per cell, with 95 % Wilson intervals", ""]
    for c in the_cells:
        mine = [r for r in rows if r["cell"] == c.id and r["n"]]
        if not mine:
            continue
        report = [g for g in (r["group"] for r in mine) if g in REPORT_COUNTS]
        head = [f"{r['group']} (ours)" for r in mine] + [f"{g} (report, 10 runs)" for g in report]
        lines += [f"**{c.id}** ({c.label})", "", "| class | " + " | ".join(head) + " |",
                  "|---|" + "---|" * len(head)]
        for k in CLASSES:
            ours = [wilson(r["table1"][k]["k"], r["n"]).text() for r in mine]
            theirs = [wilson(REPORT_COUNTS[g].get(k, 0), 10).text() for g in report]
            lines.append(f"| {k} | " + " | ".join(ours + theirs) + " |")
        lines.append("")
    if tests:
        lines += ["## Factor tests", "",
                  "Kruskal–Wallis across the factor's levels, pooled over the other factors; p-values corrected "
                  f"together with Holm's method ({len(tests)} tests); *largest difference*: the farthest end of any "
                  "two levels' 95 % interval of their difference (Newcombe's for shares, Welch's t for means; – when "
                  "a level has too few runs): a larger difference would very likely have been seen. p is exact for "
                  "small designs; *smallest p possible*: the lowest any outcome of this many runs can give.", "",
                  "| factor | stratum | measure | levels (mean [95 %]) | H | p | smallest p possible | Holm p | ε² | "
                  "largest difference |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for t in tests:
            levels = "; ".join(f"{r['level']}: {format_mean(r, t['share'])}" for r in t["levels"])
            big = "–" if math.isnan(t["largest_difference"]) else difference_unit(t["share"], t["largest_difference"])
            lines.append(f"| {t['factor']} | {t['stratum']} | {MEASURES[t['measure']][0]} | {levels} | {t['h']:.2f} | "
                         f"{format_p(t['p'])} | {format_p(t['min_p'])} | {format_p(t['p_holm'])} | "
                         f"{t['epsilon2']:.2f} ({t['magnitude']}) | {big} |")
        lines.append("")
    lines += ["## Figures", ""] + [f"![{f}]({f})" for f in figures]
    lines += ["", "Files: `results.json` (everything above, and every run's measures), `study.json` (the declaration), "
              "`cells/CELL/` (each cell a `coevo compare` folder: `coevo compare --report-only --out cells/CELL` "
              "writes its full comparison report).", ""]
    return "\n".join(lines)
