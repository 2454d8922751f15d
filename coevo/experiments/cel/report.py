"""The report of ``coevo cel-experiment``: Figure 3's curve over live runs beside the report's numbers.

``report.md``, ``summary.json``, ``curve.csv`` (mean and s.d. per generation), ``runs.csv`` (one row per run)
and ``figure3.png``.  The report's numbers (25 -> 63 -> 37 -> over 60 %, Figure 3's text) are set beside ours
when the schedule is Figure 3's failure (front, front-right and right, at any generation).
"""

from __future__ import annotations

import csv
import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from coevo.experiments.cel.experiment import FIGURE3_FAILURE

__all__ = ["REPORT", "key_points", "write_report"]

#: Figure 3's numbers in the report's text (% of 100 trials); the last is "over 60".
REPORT = {"default": 25.0, "before": 63.0, "at": 37.0, "end": 60.0}


def key_points(schedule: list[tuple[int, list[str]]], generations: int) -> list[dict[str, Any]]:
    """The generations the table shows: the default rules, each event's generation and the one before, the end;
    with the report's number where it has one."""
    figure3 = len(schedule) == 1 and tuple(schedule[0][1]) == FIGURE3_FAILURE
    rows: list[dict[str, Any]] = [{"key": "default", "label": "default rules (generation 0)", "generation": 0}]
    for g, failed in schedule:
        if not 0 < g <= generations:
            continue  # the run ends before it
        what = f"{', '.join(failed)} fail" if failed else "every sonar repaired"
        rows.append({"key": "before", "label": f"best before generation {g}", "generation": g - 1})
        rows.append({"key": "at", "label": f"generation {g}: {what}", "generation": g})
    rows.append({"key": "end", "label": f"end (generation {generations})", "generation": generations})
    for r in rows:
        r["report"] = REPORT[r["key"]] if figure3 else None
    return rows


def _mean_sd(values: Any) -> tuple[float, float]:
    a = np.asarray(values, dtype=float)
    return float(a.mean()), float(a.std(ddof=1)) if len(a) > 1 else 0.0


def summarise(runs: list[dict[str, Any]], spec: dict[str, Any], *, wall: float | None,
              lockstep: dict[str, Any] | None) -> dict[str, Any]:
    """Everything the report shows, as plain data (``summary.json``)."""
    n = min(len(r["external"]) for r in runs)
    ext = np.array([r["external"][:n] for r in runs])
    table = []
    for k in key_points(spec["schedule"], n - 1):
        m, s = _mean_sd(ext[:, k["generation"]])
        table.append({**k, "mean": m, "sd": s, "ours": ext[:, k["generation"]].tolist()})
    det = [d for r in runs for d in r["detections"]]
    found = [d for d in det if d["detected"]]
    lat = np.array([x for r in runs for x in r["latency_ms"]])
    return {
        "spec": spec, "runs_expected": spec["runs"], "runs_finished": len(runs), "wall_seconds": wall,
        "table": table, "external_mean": ext.mean(axis=0).round(2).tolist(),
        "external_sd": (ext.std(axis=0, ddof=1) if len(runs) > 1 else 0 * ext[0]).round(2).tolist(),
        "runs_over_60_at_end": int((ext[:, -1] > 60).sum()),
        "detections": {"events": len(det), "detected": len(found), "trials": [d["trials"] for d in found],
                       "decisions": [d["decisions"] for d in found],
                       "learner_generations_on_the_wrong_model": [d.get("generations") for d in found]},
        "latency_ms": ({"median": float(np.median(lat)), "p90": float(np.percentile(lat, 90)), "max": float(lat.max()),
                        "n": int(len(lat))} if len(lat) else None),
        "run_seconds": dict(zip(("mean", "sd"), _mean_sd([r["seconds"] for r in runs]))),
        "lockstep": lockstep,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "load_average": os.getloadavg()[0]},
        "runs": runs,
    }


def write_report(out: Path, runs: list[dict[str, Any]], spec: dict[str, Any], *, wall: float | None,
                 lockstep: dict[str, Any] | None = None) -> dict[str, Any]:
    """The report files in ``out`` from the finished ``runs``; returns the summary (None if no run finished)."""
    from coevo.rundir.layout import write_json

    if not runs:
        (out / "report.md").write_text("# Figure 3, live service\n\nNo run finished.\n")
        return {"runs_finished": 0, "runs_expected": spec["runs"], "table": []}
    data = summarise(runs, spec, wall=wall, lockstep=lockstep)
    write_json(out / "summary.json", data)
    with open(out / "curve.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["generation", "mean", "sd", "runs"])
        for g, (m, s) in enumerate(zip(data["external_mean"], data["external_sd"])):
            w.writerow([g, m, s, len(runs)])
    with open(out / "runs.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["seed", "seconds", "external_end", "detected", "events", "latency_median_ms"])
        for r in runs:
            w.writerow([r["seed"], round(r["seconds"], 2), r["external"][-1], sum(d["detected"] for d in r["detections"]),
                        len(r["detections"]), float(np.median(r["latency_ms"])) if r["latency_ms"] else ""])
    _plot(out / "figure3.png", data)
    (out / "report.md").write_text(_markdown(data))
    return data


def _markdown(data: dict[str, Any]) -> str:
    spec, n = data["spec"], data["runs_finished"]
    events = "; ".join(f"generation {g}: {', '.join(f) or 'repair'}" for g, f in spec["schedule"]) or "no failures"
    lines = ["# Figure 3, live service (`coevo cel-experiment`)", "",
             f"{n} of {data['runs_expected']} live `coevo cel` runs finished (seeds {spec['first_seed']} .. "
             f"{spec['first_seed'] + spec['runs'] - 1}); {spec['generations']} generations of "
             f"{spec['trials_per_generation']} trials; {events}" + (", case base" if spec["case_base"] else "") + "."
             + (f" Wall time {data['wall_seconds']:.0f} s." if data["wall_seconds"] else ""), "",
             "## External performance (% of the generation's trials; mean ± s.d. over runs)", "",
             "| generation | what | ours | the report |", "|---|---|---|---|"]
    for r in data["table"]:
        rep = "" if r["report"] is None else ("over " if r["key"] == "end" else "") + f"{r['report']:.0f}"
        lines.append(f"| {r['generation']} | {r['label']} | {r['mean']:.1f} ± {r['sd']:.1f} | {rep} |")
    d, lat = data["detections"], data["latency_ms"]
    lines += ["", f"Runs over 60 % at the end: {data['runs_over_60_at_end']} of {n}.", "", "![figure3.png](figure3.png)",
              "", "## The monitor and the bus", "",
              f"- failures detected: {d['detected']} of {d['events']}; trials to detect {d['trials']}, decisions "
              f"{d['decisions']}, learner generations on the wrong model {d['learner_generations_on_the_wrong_model']}"]
    if lat:
        lines.append(f"- a new best from the learner to the robot: median {lat['median']:.2f} ms, 90th percentile "
                     f"{lat['p90']:.2f} ms, max {lat['max']:.2f} ms over {lat['n']} policies")
    lines.append(f"- a run took {data['run_seconds']['mean']:.1f} ± {data['run_seconds']['sd']:.1f} s")
    if data["lockstep"] is not None:
        ls = data["lockstep"]
        lines.append(f"- equal to the lockstep run of the same seed: {len(ls['equal'])} of {len(ls['compared'])} "
                     f"(seeds {ls['equal']})")
    m = data["machine"]
    lines += ["", f"Machine: {m['cpus']} cores, load average {m['load_average']:.1f}, Python {m['python']}. Per-run "
              "numbers: `runs.csv`; the curve: `curve.csv`; everything: `summary.json`."]
    return "\n".join(lines) + "\n"


def _plot(path: Path, data: dict[str, Any]) -> None:
    import matplotlib

    matplotlib.use("Agg")  # files only, no display needed
    import matplotlib.pyplot as plt

    m, s = np.array(data["external_mean"]), np.array(data["external_sd"])
    g = np.arange(len(m))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.fill_between(g, m - s, m + s, alpha=0.25, label="± 1 s.d.")
    ax.plot(g, m, label=f"mean of {data['runs_finished']} live runs (ours)")
    for gen, failed in data["spec"]["schedule"]:
        ax.axvline(gen, color="k", linestyle="--" if failed else ":", linewidth=1)
        ax.text(gen + 0.5, 3, "fail" if failed else "repair", fontsize=8)
    rep = [r for r in data["table"] if r["report"] is not None]
    if rep:
        ax.plot([r["generation"] for r in rep], [r["report"] for r in rep], "s", color="C3",
                label="the report's numbers (end: 'over 60')")
    ax.set(xlabel="generation", ylabel="external performance (% of trials)", ylim=(0, 100),
           title="Figure 3 counterpart, live service (coevo cel-experiment)")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
