"""The report of a comparison of any task (one whose reading is :func:`~coevo.experiments.compare.reading.generic`):
what its runs' final policies together measure, each behaviour's final best so far, rank tests between the regimes,
the learning curves and a verdict in words.

Everything is read from the runs' own files (``summary.json``'s measures, the task's ``run_measures``, and the
workers' ``curve.jsonl``), so the report can be rebuilt at any time (``coevo compare --report-only``).  Files
written to OUT: ``results.json`` (everything), ``runs.csv`` (a row per run), ``curves.csv`` (a row per run,
behaviour and generation), ``figure-REGIME.png``, ``regimes.png`` and ``report.md``.

With two regimes, each measure is compared by the two-sided Mann–Whitney test with the Vargha–Delaney A
(:mod:`~coevo.experiments.compare.stats`); with more, every pair, the p-values Holm-adjusted over the pairs of one
measure.  Means carry 95 % t intervals, none below three runs.
"""

from __future__ import annotations

import json
import math
from itertools import combinations
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.experiments.common import below_report, plural
from coevo.experiments.compare import plots
from coevo.experiments.compare.experiment import CompareSpec, Replicate, is_finished, replicates, run_dir
from coevo.experiments.compare.reading import reading_of
from coevo.experiments.compare.stats import (
    EXACT_ARRANGEMENTS,
    RankComparison,
    compare_samples,
    design_floor,
    format_p,
    holm,
    mean_interval,
    MeanInterval,
)
from coevo.experiments.glossary import label
from coevo.rundir.layout import RunPaths, read_jsonl, write_csv, write_json, write_text

__all__ = ["collect", "write_report", "test_sentence", "winner", "undecided"]

CURVE_COLUMNS = ("best_fitness", "best_so_far")


def _number(v: Any) -> float:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else float("nan")


def _record(out: Path, spec: CompareSpec, rep: Replicate) -> dict[str, Any]:
    d = run_dir(out, rep)
    summary = json.loads(RunPaths(d).summary.read_text(encoding="utf-8"))
    curves: dict[str, dict[str, list[float]]] = {}
    final: dict[str, float] = {}
    for b in spec.the_task.behaviours:
        rows = read_jsonl(RunPaths(d).worker(b).curve, missing_ok=True)
        curves[b] = {c: [_number(r.get(c)) for r in rows] for c in CURVE_COLUMNS}
        final[b] = _number(rows[-1].get("best_so_far")) if rows else float("nan")
    return {"run": rep.run_id, "regime": rep.regime, "group": rep.group, "index": rep.index, "seed": rep.seed,
            "seconds": _number(summary.get("seconds")),
            "measures": {k: _number(v) for k, v in (summary.get("measures") or {}).items()},
            "final_best_so_far": final, "curves": curves}


def collect(out: Path, spec: CompareSpec) -> list[dict[str, Any]]:
    """One record per finished live run: its measures, each behaviour's final best so far, and its curves."""
    return [_record(Path(out), spec, rep) for rep in replicates(spec) if not rep.offline and is_finished(out, rep)]


def _measures(spec: CompareSpec, records: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """(key, readable name) of what is compared: the runs' measures in their first run's order, then each
    behaviour's final best so far."""
    keys: list[str] = []
    for x in records:
        keys += [k for k in x["measures"] if k not in keys]
    return [(k, label(k)) for k in keys] + [(f"final_{b}_fitness", f"{b}'s final best so far")
                                            for b in spec.the_task.behaviours]


def _values(x: dict[str, Any], key: str) -> float:
    if key.startswith("final_") and key.endswith("_fitness"):
        return float(x["final_best_so_far"].get(key[len("final_"):-len("_fitness")], float("nan")))
    return float(x["measures"].get(key, float("nan")))


def winner(t: RankComparison) -> tuple[str, str]:
    """(higher, lower) regime by the effect size: medians tie when most runs score 0, ranks do not."""
    return (t.b, t.a) if t.a12 > 0.5 else (t.a, t.b)


def undecided(magnitude: str, significant: bool) -> bool:
    """A large effect the test could not establish: neither "differs" nor "does not differ" is true of it."""
    return not significant and magnitude == "large"


def test_sentence(t: RankComparison, name: str, p: float | None = None) -> str:
    """One rank test in words: who beats whom on ``name``, or that it is not established and why (``p``: the
    adjusted p when not the test's own)."""
    p = t.p_value if p is None else p
    med = {t.a: t.median_a, t.b: t.median_b}
    if p < 0.05 and t.a12 != 0.5:
        hi, lo = winner(t)
        mean = {t.a: t.mean_a, t.b: t.mean_b}
        return (f"{hi} beats {lo} on {name} (medians {med[hi]:.3g} vs {med[lo]:.3g}, means {mean[hi]:.3g} vs "
                f"{mean[lo]:.3g}, Mann–Whitney p = {format_p(p)}, A = {t.a12:.2f}, {t.magnitude})")
    floor = design_floor(t.min_p, f"{t.n_a} and {t.n_b} runs")
    said = (f"a {t.magnitude} difference on {name} is not established" if undecided(t.magnitude, False)
            else f"the regimes do not differ significantly on {name}")
    return (f"{said} ({t.b} median {t.median_b:.3g}, {t.a} median {t.median_a:.3g}, p = {format_p(p)}, "
            f"A = {t.a12:.2f}, {t.magnitude}{'; ' + floor if floor else ''})")


def _tests(spec: CompareSpec, records: list[dict[str, Any]],
           measures: list[tuple[str, str]]) -> list[tuple[RankComparison, float]]:
    """Every pair of regimes on every measure, with its p (Holm-adjusted over the pairs when there are several)."""
    by = {r: [x for x in records if x["group"] == r] for r in spec.regimes}
    pairs = [(a, b) for a, b in combinations(spec.regimes, 2) if by[a] and by[b]]
    out: list[tuple[RankComparison, float]] = []
    for key, _ in measures:
        tests = []
        for a, b in pairs:
            xa = [v for v in (_values(x, key) for x in by[a]) if not math.isnan(v)]
            xb = [v for v in (_values(x, key) for x in by[b]) if not math.isnan(v)]
            if xa and xb:
                tests.append(compare_samples(key, a, xa, b, xb))
        ps = holm([t.p_value for t in tests]) if len(tests) > 1 else [t.p_value for t in tests]
        out += list(zip(tests, ps, strict=True))
    return out


def write_report(out: Path, spec: CompareSpec, *, elapsed: float | None = None) -> dict[str, Any]:
    """Write results.json, runs.csv, curves.csv, the figures and report.md; returns the results."""
    out = Path(out)
    records = collect(out, spec)
    if not records:
        raise RunDirError(f"{out} holds no finished runs to report on")
    reading = reading_of(spec.the_task)
    measures = _measures(spec, records)
    names = dict(measures)
    terms = spec.the_task.measure_terms
    summary = {g: {k: mean_interval([v for v in (_values(x, k) for x in records if x["group"] == g)
                                      if not math.isnan(v)], bounds=terms[k].bounds if k in terms else None).as_dict()
                   for k, _ in measures}
               for g in spec.regimes}
    tests = _tests(spec, records, measures)
    verdict = "; ".join(test_sentence(t, names[t.measure], p) for t, p in tests) + "." if tests else (
        "Nothing to compare: a rank test needs finished runs in two regimes.")
    verdict = verdict[0].upper() + verdict[1:]
    caveat = below_report({"generations": spec.ga.generations, "population": spec.ga.population,
                           "episodes": spec.ga.episodes, "runs a regime": spec.runs})
    verdict = f"{caveat}\n\n{verdict}" if caveat else verdict

    curves_by_group = {g: {x["run"]: x["curves"] for x in records if x["group"] == g} for g in spec.regimes}
    figures = []
    for r in spec.regimes:
        if curves_by_group[r]:
            plots.figure_for_regime(curves_by_group[r], r, out / f"figure-{r}.png", reading.panels)
            figures.append(f"figure-{r}.png")
    plots.figure_regimes(curves_by_group, out / "regimes.png", reading.panels)
    figures.append("regimes.png")
    expected = len(replicates(spec))
    results = {
        "spec": json.loads(spec.model_dump_json()), "runs_expected": expected, "runs_finished": len(records),
        "elapsed_seconds": elapsed, "measures": summary, "measure_names": names,
        "tests": [{**t.as_dict(), "p_adjusted": p} for t, p in tests], "verdict": verdict, "figures": figures,
        "runs": [{k: v for k, v in x.items() if k != "curves"} for x in records],
    }
    write_json(out / "results.json", results)
    write_csv(out / "runs.csv", [{"run": x["run"], "regime": x["regime"], "seed": x["seed"],
                                  "seconds": round(x["seconds"], 1), **{k: _values(x, k) for k, _ in measures}}
                                 for x in records])
    write_csv(out / "curves.csv", [
        {"run": x["run"], "regime": x["regime"], "behaviour": b, "generation": i + 1,
         **{c: cols[c][i] for c in CURVE_COLUMNS}}
        for x in records for b, cols in x["curves"].items() for i in range(len(cols["best_fitness"]))])
    write_text(out / "report.md", _markdown(spec, records, measures, summary, tests, verdict, figures, expected,
                                            elapsed))
    return results


def summary_lines(results: dict[str, Any]) -> list[str]:
    """The terminal's lines of a report: each regime's mean of each measure."""
    names = results["measure_names"]
    return [f"  {g}: " + ", ".join(f"{names[k]} {MeanInterval(**m).text(runs=False)}" for k, m in ms.items())
            for g, ms in results["measures"].items()]


def _markdown(spec: CompareSpec, records: list[dict[str, Any]], measures: list[tuple[str, str]],
              summary: dict[str, dict[str, dict[str, Any]]], tests: list[tuple[RankComparison, float]], verdict: str,
              figures: list[str], expected: int, elapsed: float | None) -> str:
    ga = spec.ga
    lines = [f"# Regime comparison: the {spec.task} task", "",
             f"{len(records)} of {expected} runs finished" + (f" in {elapsed / 60:.1f} min" if elapsed else "") + ". "
             f"Regimes: {', '.join(spec.regimes)}; {plural(spec.runs, 'run')} each; {ga.generations} generations, "
             f"population {ga.population}, {ga.episodes} episodes per evaluation, {ga.best_episodes} for the best; "
             f"partner model `{spec.model}`; pacing max lead {spec.max_lead if spec.max_lead is not None else 'off'}; "
             f"base seed {spec.seed}; measures on {spec.measure_epochs} fresh epochs.", "",
             "## Verdict", "", verdict, "",
             "## Measures", "",
             "Means over the runs with their 95 % t intervals (none below 3 runs): the task's measures of each run's "
             "final policies together, on fresh epochs, and each behaviour's best fitness so far at its last "
             "generation (the policy its worker published last).", "",
             "| measure | " + " | ".join(spec.regimes) + " |", "|---|" + "---|" * len(spec.regimes)]
    for key, name in measures:
        lines.append(f"| {name} | " + " | ".join(MeanInterval(**summary[g][key]).text() for g in spec.regimes) + " |")
    if tests:
        lines += ["", "## Statistical comparison", "",
                  "| measure | regimes (a, b) | median a | median b | Mann–Whitney U | p | smallest p possible | "
                  "A (b > a) | effect |", "|---|---|---|---|---|---|---|---|---|"]
        for t, p in tests:
            lines.append(f"| {dict(measures)[t.measure]} | {t.a}, {t.b} | {t.median_a:.3g} | {t.median_b:.3g} | "
                         f"{t.u:.1f} | {format_p(p)} | {format_p(t.min_p)} | {t.a12:.2f} | {t.magnitude} |")
        lines += ["", f"p: exact (a permutation of the runs) when they split in at most {EXACT_ARRANGEMENTS:,} ways, "
                  "else the normal approximation; with more than two regimes, Holm-adjusted over the pairs of one "
                  "measure. *Smallest p possible*: the lowest p any outcome of this many runs can give. A: the "
                  "chance that a run of b scores above one of a (ties half); 0.5 is no effect, beyond 0.71 or below "
                  "0.29 large."]
    lines += ["", "## Runs", "", "| run | " + " | ".join(n for _, n in measures) + " | minutes |",
              "|---|" + "---|" * (len(measures) + 1)]
    for x in records:
        lines.append(f"| {x['run']} | " + " | ".join(f"{_values(x, k):.3g}" for k, _ in measures)
                     + f" | {x['seconds'] / 60:.1f} |")
    lines += ["", "## Learning curves", "", *[f"![{f}]({f})" for f in figures], "",
              "Files: `results.json` (everything above), `runs.csv`, `curves.csv`, and each run under `runs/`.", ""]
    return "\n".join(lines)
