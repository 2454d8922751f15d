"""The comparison's report: per-run measures, Table 1, rank tests, curves and a verdict.

Everything is computed from the runs' own files (``summary.json`` and the
workers' ``curve.jsonl``), so a report can be rebuilt from a comparison
directory at any time (``coevo compare --report-only``).  One diagnostic is
recomputed rather than read: how often each run's final Docking policy docks on
its own from a fresh random start (``DOCKING_PROBE_EPISODES`` single episodes),
which tells a starved Executive from a Docking agent that never learned.
Files written to OUT:
``results.json`` (everything), ``runs.csv`` (one row per run), ``curves.csv``
(one row per run, behaviour and generation), ``figure-REGIME.png``,
``regimes.png``, ``robot-REGIME-best.png`` and ``robot-REGIME-worst.png`` (the combined robot of
the regime's best and worst run by executive payoff, playing one epoch) and ``report.md``.
"""

from __future__ import annotations

import json
import math
import statistics
from pathlib import Path
from typing import Any

from coevo.errors import CoevoError, RuleSetError, RunDirError
from coevo.experiments.common import below_report, plural
from coevo.experiments.compare import plots
from coevo.experiments.compare.any_task import test_sentence, undecided, winner
from coevo.experiments.compare.experiment import (
    OFFLINE,
    CompareSpec,
    Replicate,
    groups,
    is_finished,
    replicates,
    run_dir,
)
from coevo.experiments.compare.stats import (
    GroupComparison,
    RankComparison,
    compare_groups,
    compare_samples,
    EXACT_ARRANGEMENTS,
    design_floor,
    format_p,
    MeanInterval,
    mean_interval,
)
from coevo.experiments.compare.table1 import CLASSES, PANELS, REPORT_COUNTS, classify, count
from coevo.experiments.glossary import TERMS, bounds_of, label
from coevo.policy.text import parse_ruleset
from coevo.rundir.layout import (
    LearnPaths,
    RunPaths,
    read_jsonl,
    write_csv,
    write_json,
    write_text,
)
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.robot import docking_from_random_starts
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["collect", "write_report", "MEASURES", "executive_curve", "tail_text"]

# The combined robot's measures shown per run (docs/spec.md §2 "Measures").
MEASURES = ("quality_tracking", "successful_docking", "docking_success_rate", "average_epoch_length", "dock_choice",
            "executive_payoff")
CURVE_COLUMNS = ("best_fitness", "best_so_far", "quality_tracking", "successful_docking", "dock_choice",
                 "docking_success_rate", "docking_from_random")
DOCKING_PROBE_EPISODES = 300


def collect(out: Path, spec: CompareSpec, *, known: dict[str, dict[str, Any]] | None = None) -> list[dict[str, Any]]:
    """One record per finished run: its measures, Table 1 class, final fitnesses and curves.

    ``known``: records already made, by run id, reused instead of made again and added to as runs finish (a
    finished run no longer changes; its record costs a Docking probe of ``DOCKING_PROBE_EPISODES`` episodes), for a
    reader that follows a growing comparison (the dashboard's study page)."""
    records: list[dict[str, Any]] = []
    by_run: dict[str, dict[str, Any]] = {}  # an offline replicate reads its live run's record, built just before
    for rep in replicates(spec):
        if not is_finished(out, rep):
            continue
        x = known.get(rep.run_id) if known is not None else None
        if x is None:
            live = by_run.get(rep.depends_on.run_id) if rep.offline and rep.depends_on else None
            x = _offline_record(out, rep, live) if rep.offline else _record(out, spec, rep)
            if known is not None and (not rep.offline or live is not None):  # not one made without its live run
                known[rep.run_id] = x
        records.append(x)
        if not rep.offline:
            by_run[rep.run_id] = x
    return records


def _docking_alone(d: Path, spec: CompareSpec, rep: Replicate) -> float:
    """% of fresh single episodes in which the run's final Docking policy docks (NaN if it published none)."""
    f = RunPaths(d).worker(Behaviour.DOCKING).best_rules
    try:
        rules = parse_ruleset(f.read_text(), Behaviour.DOCKING)
    except (OSError, RuleSetError):
        return float("nan")
    if not isinstance(spec.world, WorldConfig):
        raise TypeError(f"a Table 1 report reads the fuel task's comparisons, not the {spec.task} task's")
    return docking_from_random_starts(spec.world, rules, episodes=DOCKING_PROBE_EPISODES, seed=rep.seed + 7)


def _offline_record(out: Path, rep: Replicate, live: dict[str, Any] | None) -> dict[str, Any]:
    """An Executive learned on a live Independent run's recorded Tracking/Docking histories at one rate
    (``live``: that run's record, None if it is not finished)."""
    d = run_dir(out, rep)
    m = json.loads(LearnPaths(d).measures.read_text())
    rows = json.loads(LearnPaths(d).curve_json.read_text())
    curves = {Behaviour.EXECUTIVE.value: {c: [_number(r.get(c)) for r in rows] for c in CURVE_COLUMNS}}
    final = {Behaviour.EXECUTIVE.value: float(rows[-1]["best_so_far"]) if rows else float("nan")}
    for b in (Behaviour.TRACKING, Behaviour.DOCKING):
        final[b.value] = live["final_best_so_far"][b.value] if live else float("nan")
    timing = json.loads(LearnPaths(d).timing.read_text())
    return {
        "run": rep.run_id, "regime": rep.regime, "group": rep.group, "rate": rep.rate, "index": rep.index,
        "seed": rep.seed, "docking_from_random_starts": live["docking_from_random_starts"] if live else float("nan"),
        "seconds": float(timing.get("seconds", float("nan"))),
        "measures": {k: float(v) for k, v in m.items() if k != "best_fitness"},
        "class": classify(m), "final_best_so_far": final, "versions": {}, "curves": curves,
    }


def _record(out: Path, spec: CompareSpec, rep: Replicate) -> dict[str, Any]:
    d = run_dir(out, rep)
    summary = json.loads(RunPaths(d).summary.read_text())
    m = summary["measures"]
    curves: dict[str, dict[str, list[float]]] = {}
    final: dict[str, float] = {}
    for b in Behaviour:
        rows = read_jsonl(RunPaths(d).worker(b).curve, missing_ok=True)
        curves[b.value] = {c: [_number(r.get(c)) for r in rows] for c in CURVE_COLUMNS}
        final[b.value] = float(rows[-1]["best_so_far"]) if rows else float("nan")
    return {
        "run": rep.run_id, "regime": rep.regime, "group": rep.group, "rate": None, "index": rep.index,
        "seed": rep.seed, "docking_from_random_starts": _docking_alone(d, spec, rep),
        "seconds": float(summary.get("seconds", float("nan"))),
        "measures": {k: float(v) for k, v in m.items()},
        "class": classify(m),
        "final_best_so_far": final,
        "versions": summary.get("versions", {}),
        "curves": curves,
    }


def _number(v: Any) -> float:
    """A curve value; NaN where a behaviour has no such measure (or an older run did not record it)."""
    return float("nan") if v is None else float(v)


def _live(spec: CompareSpec) -> list[str]:
    return [r for r in spec.regimes if r != OFFLINE]


#: The Executive curve's steadier reading: each run's mean of the best over its last generations (the curve is one
#: generation's best on 12 epochs and swings by ~0.1 from one generation to the next).  Ours: a fifth of the report's
#: 50 generations.
TAIL_GENERATIONS = 10


def executive_curve(curves: list[list[float]]) -> dict[str, Any]:
    """The Executive curve of a group's runs (each run's generation's best, per generation): the mean of its last
    generation's best (the report's measure), and the mean of each run's last TAIL_GENERATIONS (all of them in a
    shorter run: ``tail_generations`` says how many were averaged), each with a 95 % interval over the runs."""
    curves = [c for c in curves if c]
    tail = min(TAIL_GENERATIONS, max((len(c) for c in curves), default=TAIL_GENERATIONS))
    fitness = bounds_of("executive_end")  # a payoff: 0 to 1
    return {"end": mean_interval([float(c[-1]) for c in curves], bounds=fitness).as_dict(),
            "last_generations": mean_interval([statistics.fmean(c[-tail:]) for c in curves], bounds=fitness).as_dict(),
            "tail_generations": tail}


def _executive_curves(records: list[dict[str, Any]], group: str) -> list[list[float]]:
    return [x["curves"].get(Behaviour.EXECUTIVE.value, {}).get("best_fitness", []) for x in records
            if x["group"] == group]


def tail_text(n: int) -> str:
    """'last 10 generations', or 'last 3 generations' of a 3-generation run: what was averaged."""
    return f"{plural(n, 'generation')}" if n != 1 else "generation"


RATE_MEASURES = ("final_executive_fitness", "successful_docking", "docking_success_rate")


def _rate_of(group: str) -> float:
    return float(group.rsplit(" ", 1)[-1])


def _rate_tests(offline: dict[str, list[dict[str, Any]]]) -> tuple[list[GroupComparison], list[GroupComparison]]:
    """Kruskal–Wallis across all rates, and across the rates >= 1 only.

    At a rate below 1 the Executive's 50 generations see only the first 50 x rate partner
    generations, so it ends learning (and is measured) with partly learned partners; from
    rate 1 on it keeps pace with the recorded history or runs ahead of it.  The second test
    asks the report's question where that confound is absent.
    """
    def tests(groups: dict[str, list[dict[str, Any]]]) -> list[GroupComparison]:
        if len(groups) < 2 or not all(groups.values()):
            return []
        return [compare_groups(m, {g: [_measure_of(x, m) for x in xs] for g, xs in groups.items()})
                for m in RATE_MEASURES]

    paced = {g: xs for g, xs in offline.items() if _rate_of(g) >= 1}
    every = tests(offline)
    return every, (tests(paced) if len(paced) < len(offline) else [])


def _rates_sentence(tests: list[GroupComparison], which: str) -> str:
    parts = []
    for t in tests:
        name = label(t.measure)
        meds = ", ".join(f"{_rate_of(g):g}: {m:.3g}" for g, m in zip(t.groups, t.medians, strict=True))
        floor = design_floor(t.min_p, f"{t.n} runs in {len(t.groups)} groups")
        said = ("differs appreciably" if t.appreciable else
                "may differ: its effect is large, but not established" if undecided(t.magnitude, t.p_value < 0.05)
                else "does not differ appreciably")
        parts.append(f"{name} {said} "
                     f"(medians by rate {meds}; Kruskal–Wallis H = {t.h:.2f}, p = {format_p(t.p_value)}, "
                     f"ε² = {t.epsilon2:.2f}, {t.magnitude}{'; ' + floor if floor else ''})")
    if any(t.appreciable for t in tests):
        held = "does not hold"
    elif any(undecided(t.magnitude, t.p_value < 0.05) for t in tests):
        held = "can be neither confirmed nor refuted with these runs"
    else:
        held = "holds"
    return (f" Across {which}: " + "; ".join(parts) + ": the report's \"no appreciable differences in the rate of "
            f"asynchrony\" {held} there.")


def _rates_verdict(every: list[GroupComparison], paced: list[GroupComparison]) -> str:
    """Does the rate of asynchrony matter? (the report: "We found no appreciable differences")."""
    if not every:
        return ""
    text = f" {OFFLINE} (the Executive learning on recorded Tracking/Docking histories)."
    text += _rates_sentence(every, "all rates")
    if paced:
        text += _rates_sentence(paced, "the rates >= 1 (below 1 the Executive's last generation still sees partly "
                                "learned partners)")
    return text


def _verdict(spec: CompareSpec, records: list[dict[str, Any]], tests: list[RankComparison]) -> str:
    by = {r: [x for x in records if x["group"] == r] for r in _live(spec)}
    parts = [test_sentence(t, label(t.measure)) for t in tests]
    text = "; ".join(parts) + "."
    text = text[0].upper() + text[1:]
    for r, runs in by.items():
        starved = sum(x["class"].startswith("No Docking") for x in runs)
        good = sum(x["class"].startswith("Good Docking") for x in runs)
        alone = [v for v in (x["docking_from_random_starts"] for x in runs) if not math.isnan(v)]
        text += (f" In {r}, the Executive starved Docking (picked it in under 5 % of episodes) in {starved} of "
                 f"{len(runs)} runs, and {good} of {len(runs)} runs docked well (≥ 20 % of the episodes it picked Docking "
                 "for)")
        text += (f"; its final Docking policy, alone from a fresh random start, docked in a median "
                 f"{statistics.median(alone):.1f} % of episodes (best run {max(alone):.1f} %)." if alone else ".")
    exp = []
    if "mutual" in by and "independent" in by and by["mutual"] and by["independent"]:
        exec_t = next((t for t in tests if t.measure == "final_executive_fitness"), None)
        dock_t = next((t for t in tests if t.measure == "successful_docking"), None)
        mutual_starved = sum(x["class"].startswith("No Docking") for x in by["mutual"])

        def independent_wins(t: RankComparison | None) -> bool:
            return t is not None and t.p_value < 0.05 and t.a12 != 0.5 and winner(t)[0] == "independent"

        checks = [
            (f"Independent beats Mutual on {label('final_executive_fitness')}", independent_wins(exec_t)),
            (f"Independent beats Mutual on {label('successful_docking')}", independent_wins(dock_t)),
            ("in most Mutual runs the Executive stops picking Docking", mutual_starved > len(by["mutual"]) / 2),
            ("Independent runs dock well", sum(x["class"].startswith("Good Docking") for x in by["independent"])
             > len(by["independent"]) / 2),
        ]
        # a rank test whose design cannot reach p < 0.05 neither reproduces nor fails to reproduce its finding
        untestable = {c for c, t in zip((checks[0][0], checks[1][0]), (exec_t, dock_t), strict=True)
                      if t is not None and t.min_p >= 0.05}
        held = [c for c, ok in checks if ok]
        missed = [c for c, ok in checks if not ok and c not in untestable]
        cannot = [c for c, ok in checks if not ok and c in untestable]
        exp.append(f" Against the report: {len(held)} of {len(checks)} of its findings hold here"
                   + (f" ({'; '.join(held)})" if held else "")
                   + (f"; not reproduced: {'; '.join(missed)}" if missed else "")
                   + (f"; too few runs to test: {'; '.join(cannot)}" if cannot else "") + ".")
    return text + "".join(exp)


def write_report(out: Path, spec: CompareSpec, *, elapsed: float | None = None) -> dict[str, Any]:
    """Write results.json, runs.csv, curves.csv, the PNG figures and report.md; returns the results."""
    out = Path(out)
    records = collect(out, spec)
    if not records:
        raise RunDirError(f"{out} holds no finished runs to report on")
    table = {g: count(x["class"] for x in records if x["group"] == g) for g in groups(spec)}
    tests: list[RankComparison] = []
    live = _live(spec)
    if len(live) == 2:
        a, b = live
        ra = [x for x in records if x["group"] == a]
        rb = [x for x in records if x["group"] == b]
        if ra and rb:
            tests.append(compare_samples("final_executive_fitness", a, [x["final_best_so_far"]["executive"] for x in ra],
                                         b, [x["final_best_so_far"]["executive"] for x in rb]))
            tests.append(compare_samples("successful_docking", a, [x["measures"]["successful_docking"] for x in ra],
                                         b, [x["measures"]["successful_docking"] for x in rb]))
    offline = {g: [x for x in records if x["group"] == g] for g in groups(spec) if g not in live}
    rate_tests, paced_tests = _rate_tests(offline)
    verdict = _verdict(spec, records, tests) + _rates_verdict(rate_tests, paced_tests)
    caveat = below_report({"generations": spec.ga.generations, "population": spec.ga.population,
                           "episodes": spec.ga.episodes, "runs a regime": spec.runs})
    verdict = f"{caveat}\n\n{verdict}" if caveat else verdict
    expected = len(replicates(spec))

    curves_by_group = {g: {x["run"]: x["curves"] for x in records if x["group"] == g} for g in groups(spec)}
    figures = []
    for r in live:
        if curves_by_group[r]:
            plots.figure_for_regime(curves_by_group[r], r, out / f"figure-{r}.png", PANELS)
            figures.append(f"figure-{r}.png")
    plots.figure_regimes({r: curves_by_group[r] for r in live}, out / "regimes.png", PANELS)
    figures.append("regimes.png")
    if offline:
        plots.figure_rates(curves_by_group, out / f"figure-{OFFLINE}.png")
        figures.append(f"figure-{OFFLINE}.png")
    robots = _robot_pictures(out, spec, records)

    results = {
        "spec": json.loads(spec.model_dump_json()), "runs_expected": expected, "runs_finished": len(records),
        "elapsed_seconds": elapsed, "table1": table, "table1_report": REPORT_COUNTS,
        "executive_curve": {g: executive_curve(_executive_curves(records, g)) for g in groups(spec)},
        "tests": [t.as_dict() for t in tests], "rate_tests": [t.as_dict() for t in rate_tests],
        "rate_tests_paced": [t.as_dict() for t in paced_tests],
        "verdict": verdict, "figures": figures, "robots": robots,
        "runs": [{k: v for k, v in x.items() if k != "curves"} for x in records],
    }
    write_json(out / "results.json", results)
    write_csv(out / "runs.csv", [
        {"run": x["run"], "regime": x["regime"], "rate": x["rate"], "seed": x["seed"], "class": x["class"],
         "seconds": round(x["seconds"], 1),
         **{k: x["measures"][k] for k in MEASURES}, "docking_from_random_starts": x["docking_from_random_starts"],
         **{f"final_{b}_fitness": x["final_best_so_far"][b] for b in (bb.value for bb in Behaviour)}}
        for x in records
    ])
    curve_rows = []
    for x in records:
        for beh, cols in x["curves"].items():
            for i in range(len(cols["best_fitness"])):
                curve_rows.append({"run": x["run"], "regime": x["regime"], "rate": x["rate"], "behaviour": beh,
                                   "generation": i + 1,
                                   **{c: cols[c][i] for c in CURVE_COLUMNS}})
    write_csv(out / "curves.csv", curve_rows)
    write_text(out / "report.md", _markdown(spec, records, table, tests, rate_tests + paced_tests, verdict, figures, expected, elapsed,
                                            robots, results["executive_curve"]))
    return results


def _final_robot(d: Path) -> Any:
    """A finished fuel run's combined robot: its workers' final best.rules, in the world of its run.json."""
    from coevo.rundir.settings import RunSettings
    from coevo.tasks.fuel.pictures import robot_from_rules

    paths = RunPaths(d)
    world = RunSettings.load(paths.run_json).world_config()
    return robot_from_rules(d.name, world, paths.final_rules(list(Behaviour)))  # type: ignore[arg-type]


def _robot_pictures(out: Path, spec: CompareSpec, records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per live regime, the combined robots of its best and worst run (by executive payoff) playing one epoch."""
    from coevo.tasks.fuel.pictures import picture

    reps = {r.run_id: r for r in replicates(spec)}
    shown = []
    for regime in _live(spec):
        runs = [x for x in records if x["group"] == regime and not math.isnan(x["measures"]["executive_payoff"])]
        if not runs:
            continue
        ranked = sorted(runs, key=lambda x: (x["measures"]["executive_payoff"], x["run"]))
        picks = [("best", ranked[-1])] + ([("worst", ranked[0])] if len(ranked) > 1 else [])
        for which, x in picks:
            name = f"robot-{regime}-{which}.png"
            entry = {"regime": regime, "which": which, "run": x["run"], "seed": x["seed"],
                     "executive_payoff": x["measures"]["executive_payoff"], "file": name, "problem": None}
            try:
                robot = _final_robot(run_dir(out, reps[x["run"]]))
                picture(robot, out / name, seed=x["seed"], title=f"{regime}, {which} run {x['run']} "
                        f"(executive payoff {entry['executive_payoff']:.3f}): one epoch, seed {x['seed']}")
            except CoevoError as exc:
                entry["file"], entry["problem"] = None, str(exc)
            shown.append(entry)
    return shown


def _measure_of(x: dict[str, Any], measure: str) -> float:
    if measure == "final_executive_fitness":
        return float(x["final_best_so_far"]["executive"])
    return float(x["measures"][measure])


def _executive_curve_lines(exec_curve: dict[str, dict[str, Any]]) -> list[str]:
    """report.md's section on the Executive's curve: its end and its steadier reading, per group."""
    tail = next(iter(exec_curve.values()))["tail_generations"]
    lines = ["## The Executive's curve", "",
             "*Generation's best*: the fitness of the best Executive of one generation, re-evaluated on "
             "best_episodes (the report's learning curve). Means over the runs with 95 % t intervals (none below "
             f"3 runs): at the last generation, and each run's mean of its last {tail_text(tail)} (steadier: one "
             "generation's best swings by ~0.1). The report: \"the maximum fitness for these should be roughly "
             "80%\". Not the *best so far* of the tests below, the highest such re-evaluation of any generation "
             "(the policy the worker publishes): a maximum over noisy re-evaluations, so higher.", "",
             f"| regime | generation's best at the last generation | generation's best, mean of its last "
             f"{tail_text(tail)} |", "|---|---|---|"]
    for g, c in exec_curve.items():
        lines.append(f"| {g} | {MeanInterval(**c['end']).text()} | {MeanInterval(**c['last_generations']).text()} |")
    return [*lines, ""]


def _rank_test_lines(tests: list[RankComparison]) -> list[str]:
    """report.md's rank tests of the two live regimes: a row per measure, then what p, its floor and A mean."""
    if not tests:
        return []
    a, b = tests[0].a, tests[0].b
    lines = ["## Statistical comparison", "",
             f"| measure | median {a} | median {b} | Mann–Whitney U | p | smallest p possible | A ({b} > {a}) | effect |",
             "|---|---|---|---|---|---|---|---|"]
    for t in tests:
        lines.append(f"| {label(t.measure)} | {t.median_a:.3g} | {t.median_b:.3g} | {t.u:.1f} | "
                     f"{format_p(t.p_value)} | {format_p(t.min_p)} | {t.a12:.2f} | {t.magnitude} |")
    lines += ["", f"p: exact (a permutation of the runs) when they split in at most {EXACT_ARRANGEMENTS:,} ways, else "
              "the normal approximation; *smallest p possible*: the lowest p any outcome of this many runs can give, "
              f"so a p near it is as strong as this design can show. A: the chance that a run of {b} scores above "
              f"one of {a} (ties half); 0.5 is no effect, beyond 0.71 or below 0.29 large.", ""]
    return lines


#: The runs table's measure columns, in its order (their names and units: :mod:`coevo.experiments.glossary`).
RUN_COLUMNS = ("quality_tracking", "dock_choice", "docking_success_rate", "successful_docking", "average_epoch_length",
               "executive_payoff", "docking_from_random_starts")


def _heading(field: str) -> str:
    """A table heading: the glossary's name and its unit ('Quality Tracking %', 'Average Epoch Length (episodes)')."""
    unit = TERMS[field].unit.strip()
    return label(field) + ("" if not unit else f" {unit}" if unit == "%" else f" ({unit})")


def _digits(field: str) -> int:
    return {"average_epoch_length": 2, "executive_payoff": 3}.get(field, 1)


def _markdown(spec: CompareSpec, records: list[dict[str, Any]], table: dict[str, dict[str, int]],
              tests: list[RankComparison], rate_tests: list[GroupComparison], verdict: str, figures: list[str],
              expected: int, elapsed: float | None, robots: list[dict[str, Any]] | None = None,
              exec_curve: dict[str, dict[str, Any]] | None = None) -> str:
    ga = spec.ga
    lines = [
        "# Regime comparison", "",
        f"{len(records)} of {expected} runs finished"
        + (f" in {elapsed / 60:.1f} min" if elapsed else "") + ". "
        f"Regimes: {', '.join(spec.regimes)}; {spec.runs} runs each; {ga.generations} generations, population "
        f"{ga.population}, {ga.episodes} episodes per evaluation, {ga.best_episodes} for the best; partner model "
        f"`{spec.model}`; pacing max lead {spec.max_lead if spec.max_lead is not None else 'off'}; base seed {spec.seed}; "
        f"measures on {spec.measure_epochs} fresh epochs.", "",
        "## Verdict", "", verdict, "",
        "## Table 1: runs per class (ours, then the report's)", "",
        "| regime | " + " | ".join(CLASSES) + " |",
        "|---|" + "---|" * len(CLASSES),
    ]
    for r in groups(spec):
        lines.append(f"| {r} (ours) | " + " | ".join(str(table[r][c] or "") for c in CLASSES) + " |")
        if r in REPORT_COUNTS:
            lines.append(f"| {r} (report) | " + " | ".join(str(REPORT_COUNTS[r].get(c, "")) for c in CLASSES) + " |")
    lines += ["", "Classes: Good Docking when docked of picked is ≥ 20 % (docs/spec.md §2's reading of the report's "
              "20 %: with the fuel as the report states it an ideal robot docks in only ~10 % of all its episodes), "
              "Poor Docking < 20 %, No Docking when Docking picked is < 5 % of episodes; Hi tracking when Quality "
              "Tracking is > 60 %, Med > 30 %, Lo otherwise. The runs table below shows both docking numbers, and "
              "Docking alone.", ""]
    if exec_curve:
        lines += _executive_curve_lines(exec_curve)
    lines += _rank_test_lines(tests)
    if rate_tests:
        lines += [f"## Rates of asynchrony ({OFFLINE})", "",
                  "Per replicate, the Executive learns on the Tracking and Docking best-so-far histories recorded by "
                  "the live independent run of the same seed, once per rate (partner generations per Executive "
                  "generation), with the live Executive's seed: the rate is the only difference. Below rate 1 its "
                  "last generation still sees partly learned partners, so the rates >= 1 are also compared alone.", "",
                  "| rates compared | measure | medians by rate | Kruskal–Wallis H | p | smallest p possible | ε² | effect |",
                  "|---|---|---|---|---|---|---|---|"]
        for g in rate_tests:
            rates = ", ".join(f"{_rate_of(x):g}" for x in g.groups)
            meds = ", ".join(f"{_rate_of(x):g}: {m:.3g}" for x, m in zip(g.groups, g.medians, strict=True))
            lines.append(f"| {rates} | {label(g.measure)} | {meds} | {g.h:.2f} | {format_p(g.p_value)} | "
                         f"{format_p(g.min_p)} | {g.epsilon2:.2f} | {g.magnitude} |")
        lines.append("")
    lines += ["## Runs", "",
              "| run | class | " + " | ".join(_heading(k) for k in RUN_COLUMNS) + " | final best so far E / D / T "
              "| minutes |", "|---|---|" + "---|" * (len(RUN_COLUMNS) + 2)]
    for x in records:
        m, f = x["measures"], x["final_best_so_far"]
        values = [x["docking_from_random_starts"] if k == "docking_from_random_starts" else m[k] for k in RUN_COLUMNS]
        lines.append(f"| {x['run']} | {x['class']} | "
                     + " | ".join(f"{v:.{_digits(k)}f}" for k, v in zip(RUN_COLUMNS, values, strict=True))
                     + f" | {f['executive']:.3f} / {f['docking']:.3f} / {f['tracking']:.3f} | {x['seconds'] / 60:.1f} |")
    lines += ["", "The columns (docs/glossary.md lists every measure once):", ""]
    lines += [f"- **{label(k)}**: {TERMS[k].definition}" for k in (*RUN_COLUMNS, "best_so_far")]
    lines += ["", "## Learning curves", ""]
    lines += [f"![{f}]({f})" for f in figures]
    if robots:
        lines += ["", "## The combined robots of the best and worst runs", "",
                  "Per regime, the final Executive, Tracking and Docking policies of its best and worst run by Executive "
                  "payoff, playing one epoch from the run's seed (`coevo show runs/RUN --seed SEED` draws it again): "
                  "the path is coloured by the Executive's choice, the green ring is the tracking range around the "
                  "Target, and markers show where each episode began and how it ended.", ""]
        for robot in robots:
            head = (f"**{robot['regime']}, {robot['which']}**: {robot['run']} (Executive payoff "
                    f"{robot['executive_payoff']:.3f})")
            lines += [head, "", f"![{robot['file']}]({robot['file']})" if robot["file"]
                      else f"(no picture: {robot['problem']})", ""]
    lines += ["", "Files: `results.json` (everything above), `runs.csv`, `curves.csv`, and each run under `runs/`.", ""]
    return "\n".join(lines)
