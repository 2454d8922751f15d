"""The report of ``coevo seeds --task door``: Figure 3's four numbers over seeds beside the report's.

``report.md``, ``summary.json`` (the summary and every seed's result), ``seeds.csv`` (one row per seed),
``figure3.png`` (the external-performance curves) and, from the first seed, ``figure4.png`` and ``figure5.png``
(its best rules' paths with all sonars and after adapting).
"""

from __future__ import annotations

import csv
import json
import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from coevo.experiments.common import plural
from coevo.experiments.seeds.door import result_file, rounded

__all__ = ["REPORT", "write_report"]

#: Figure 3's numbers in the report's text (success %); "adapted" is "over 60".
REPORT = {"default": 25.0, "all_sonars": 63.0, "drop": 37.0, "adapted": 60.0}
KEYS = ("default", "all_sonars", "drop", "adapted")
TARGET_SECONDS = 60  # the GA's time per phase of 50 generations, on one core


def _summary(runs: list[dict[str, Any]], spec: dict[str, Any], elapsed: float | None) -> dict[str, Any]:
    g = spec["generations"]
    sd = {k: float(np.std([r[k] for r in runs], ddof=1)) if len(runs) > 1 else 0.0 for k in KEYS}
    per_phase = [x for r in runs for x in r["ga_seconds"]]
    return {
        "spec": spec, "runs_expected": spec["seeds"], "runs_finished": len(runs), "report": REPORT,
        "mean_success_1000_trials": {k: float(np.mean([r[k] for r in runs])) for k in KEYS}, "sd_over_seeds": sd,
        "mean_external_100": np.mean([r["external_100"] for r in runs], axis=0).round(2).tolist(),
        "seeds_all_sonars_at_least_60": sum(r["all_sonars"] >= 60 for r in runs),
        "seeds_adapted_over_60": sum(r["adapted"] > 60 for r in runs),
        "ga_seconds_per_generations": {"generations": g, "mean": float(np.mean(per_phase)),
                                       "max": float(np.max(per_phase)), "phases": len(per_phase)},
        "behaviour_means": {k: {q: float(np.mean([r["behaviour"][k][q] for r in runs])) for q in runs[0]["behaviour"][k]}
                            for k in ("all_sonars", "just_failed", "adapted")},
        "seconds": elapsed, "cpus": os.cpu_count(), "load_average_at_end": [round(x, 2) for x in os.getloadavg()],
        "python": platform.python_version(),
    }


def write_report(out: Path, seeds: list[int], spec: dict[str, Any], *, elapsed: float | None) -> dict[str, Any]:
    """The report files in ``out`` from the finished seeds; returns the summary."""
    from coevo.rundir.layout import write_json

    runs = [json.loads(result_file(out, s).read_text()) for s in seeds if result_file(out, s).exists()]
    if not runs:
        (out / "report.md").write_text("# The door task over seeds\n\nNo seed finished.\n")
        return {"runs_finished": 0, "runs_expected": len(seeds), "verdicts": []}
    data = _summary(runs, spec, elapsed)
    write_json(out / "summary.json", rounded({"summary": data, "runs": runs}))
    with open(out / "seeds.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["seed", *KEYS, "ga_seconds_all_sonars", "ga_seconds_failed"])
        for r in runs:
            w.writerow([r["seed"], *(r[k] for k in KEYS), *r["ga_seconds"]])
    _figures(out, runs, spec)
    (out / "report.md").write_text(_markdown(data))
    return data


def _markdown(data: dict[str, Any]) -> str:
    spec, g, n = data["spec"], data["spec"]["generations"], data["runs_finished"]
    mean, sd = data["mean_success_1000_trials"], data["sd_over_seeds"]
    failed = ", ".join(spec["failed"])
    names = {"default": "default rules, all sonars", "all_sonars": f"best after {g} generations, all sonars",
             "drop": f"that best with {failed} failed", "adapted": f"best after {g} more generations, failed"}
    lines = ["# The door task over seeds (`coevo seeds --task door`)", "",
             f"{n} of {data['runs_expected']} seeds finished (first seed {spec['first_seed']}); {g} generations with "
             f"all sonars, then {failed} fail and {g} more." + (f" {data['seconds']:.0f} s." if data["seconds"] else ""),
             "", f"| success % (1000 fresh trials; mean ± s.d. over {n} seeds) | ours | the report |", "|---|---|---|"]
    for k in KEYS:
        lines.append(f"| {names[k]} | {mean[k]:.1f} ± {sd[k]:.1f} | {'over ' if k == 'adapted' else ''}{REPORT[k]:.0f} |")
    lines += ["", f"Seeds whose all-sonar best reaches 60 %: {data['seeds_all_sonars_at_least_60']} of {n}; seeds over "
              f"60 % after adapting: {data['seeds_adapted_over_60']} of {n}.", "", "![figure3.png](figure3.png)", "",
              "| how the rules drive (200 trials; mean over seeds) | mean abs turn (deg/s) | turn reversals per 10 "
              "decisions | decisions not moving forward (%) | collisions (%) | timeouts (%) |", "|---|---|---|---|---|---|"]
    for k, label in (("all_sonars", "best, all sonars"), ("just_failed", "that best, just after the failure"),
                     ("adapted", "best after adapting")):
        m = data["behaviour_means"][k]
        lines.append(f"| {label} | {m['mean_abs_turn']:.1f} | {m['reversals_per_10']:.2f} | {m['not_forward']:.1f} | "
                     f"{m['collision']:.1f} | {m['timeout']:.1f} |")
    t = data["ga_seconds_per_generations"]
    ok = "met" if t["max"] < TARGET_SECONDS else "MISSED"
    lines += ["", f"The GA's time per {g} generations (one process, one core; measurements apart): mean {t['mean']:.1f} s, "
              f"max {t['max']:.1f} s (target < {TARGET_SECONDS} s for 50: {ok}); {data['cpus']} cores, load average "
              f"{data['load_average_at_end'][0]}.", "", "The first seed's best rules: ![figure4.png](figure4.png) "
              "![figure5.png](figure5.png)", ""]
    return "\n".join(lines)


def _figures(out: Path, runs: list[dict[str, Any]], spec: dict[str, Any]) -> None:
    """figure3.png (every seed's curve, their mean, the report's numbers); figure4/5.png (the first seed's paths)."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no display needed
    import matplotlib.pyplot as plt

    from coevo.config import build
    from coevo.policy.text import parse_ruleset
    from coevo.tasks.door import DoorConfig, capability_label
    from coevo.tasks.door.pictures import path_figure

    g = spec["generations"]
    intact = build(DoorConfig, spec["world"])
    blind = build(DoorConfig, {**spec["world"], "failed": spec["failed"]})
    c = np.array([r["external_100"] for r in runs])  # (seeds, 2G + 2)
    x = np.r_[np.arange(g + 1), g, np.arange(g + 1, 2 * g + 1)]
    fig, ax = plt.subplots(figsize=(7, 4))
    for row in c:
        ax.plot(x, row, color="0.8", lw=0.6)
    ax.plot(x, c.mean(axis=0), color="tab:blue", lw=2, label=f"mean of {plural(len(runs), 'seed')} (ours)")
    ax.axvline(g, color="black", ls=":", lw=1)
    ax.plot([0, g, g, 2 * g], [REPORT[k] for k in KEYS], "s", color="tab:red", label="the report's numbers (Figure 3 text)")
    ax.set(xlabel="generation", ylabel="successes out of 100 trials", ylim=(0, 100))
    ax.set_title(f"door traversal: all sonars, then {capability_label(blind)}", fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "figure3.png", dpi=90)
    plt.close(fig)
    first = runs[0]
    path_figure(out / "figure4.png", parse_ruleset(first["best_all_sonars"]), intact, seed=0,
                title=f"seed {first['seed']}, best after {g} generations, all sonars")
    path_figure(out / "figure5.png", parse_ruleset(first["best_adapted"]), blind, seed=0,
                title=f"seed {first['seed']}, best after {g} more generations, {capability_label(blind)}")
