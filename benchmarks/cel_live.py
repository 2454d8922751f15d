"""Figure 3 with the live service (issue 17 items 6 and 8): ``coevo cel`` runs, each three processes on the bus.

    .venv/bin/python benchmarks/cel_live.py [--runs 10] [--first-seed 0] [--jobs 2] [--root /tmp/cel-live] [--out docs/cel]
                                            [--lockstep docs/cel/figure3.json] [--case-base] [--schedule figure3|cyclic]

Runs ``coevo cel --seed S`` for S = 0 .. runs-1 (``--jobs`` at a time; the default settings: 100
generations, front, front-right and right fail at generation 50, max-lead 0), then reports:

* the wall time of the whole experiment (the issue's target: under 10 minutes on 2 cores);
* the mean external performance per generation with its s.d., beside the report's 25 -> 63 -> 37 -> over 60 %;
* how many runs equal the lockstep run of the same seed exactly (``--lockstep``: the per-run curves
  ``benchmarks/cel.py`` wrote), the in-process reference of the same architecture;
* the monitor's detection delay (trials, decisions, learner generations on the wrong model);
* how long a new best took from the learner to the execution module: from the moment the learner made
  the message (before it logs it, fsynced, and checkpoints; then it puts it) to the moment the robot
  took it in, over every policy of every run (median, 90th percentile, max).

Writes ``live.json`` and ``live.png`` into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from coevo.rundir.layout import read_jsonl

REPORT = {"default": 25.0, "all_sonars": 63.0, "drop": 37.0, "adapted": 60.0}


def one(seed: int, root: Path, extra: list[str]) -> dict[str, Any]:
    run = f"live-{seed}"
    t0 = time.time()
    r = subprocess.run([sys.executable, "-m", "coevo", "cel", "--run", run, "--root", str(root), "--seed", str(seed),
                        "--quiet", *extra], capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"run {run} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    d = root / run
    report = json.loads((d / "cel.json").read_text())
    return {"seed": seed, "seconds": time.time() - t0,
            "external": [p["external"] for p in read_jsonl(d / "execution" / "performance.jsonl")],
            "detections": report["detections"],
            "latency_ms": [p["latency_ms"] for p in read_jsonl(d / "execution" / "policies.jsonl")]}


def ms(a: Any) -> str:
    a = np.asarray(a, dtype=float)
    return f"{a.mean():5.1f} ± {a.std(ddof=1) if len(a) > 1 else 0.0:4.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=0, help="seeds first-seed .. first-seed + runs - 1")
    ap.add_argument("--jobs", type=int, default=2, help="runs at a time (each is a broker, a learner and a robot)")
    ap.add_argument("--root", default="/tmp/cel-live", help="where the run directories go (not the repository)")
    ap.add_argument("--out", default="docs/cel")
    ap.add_argument("--lockstep", default="docs/cel/figure3.json",
                    help="benchmarks/cel.py's per-run curves (for --schedule cyclic: cyclic.json beside it)")
    ap.add_argument("--schedule", default="figure3")
    ap.add_argument("--case-base", action="store_true")
    a = ap.parse_args()
    root = Path(a.root) / time.strftime("%Y%m%d-%H%M%S")
    root.mkdir(parents=True)
    extra = ["--schedule", a.schedule] + (["--case-base"] if a.case_base else [])
    t0 = time.time()
    with ThreadPoolExecutor(a.jobs) as pool:
        runs = list(pool.map(lambda s: one(s, root, extra), range(a.first_seed, a.first_seed + a.runs)))
    wall = time.time() - t0
    ext = np.array([r["external"] for r in runs])
    event = 50 if a.schedule == "figure3" else None
    print(f"{a.runs} live runs, {a.jobs} at a time: {wall:.0f} s wall ({wall / 60:.1f} min); per run "
          f"{ms([r['seconds'] for r in runs])} s; {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    table: dict[str, Any] = {}
    if event is not None:
        for name, g in (("default", 0), ("all_sonars", event - 1), ("drop", event), ("adapted", ext.shape[1] - 1)):
            table[name] = {"generation": g, "ours": ext[:, g].tolist(), "report": REPORT[name]}
            print(f"  {name:10s} generation {g:3d}: {ms(ext[:, g])} %   (report {REPORT[name]:.0f} %)")
    same = None
    lock = Path(a.lockstep if a.schedule == "figure3" else Path(a.lockstep).with_name(f"{a.schedule}.json"))
    if lock.exists() and (a.schedule == "figure3" and not a.case_base or a.schedule == "cyclic"):
        held = json.loads(lock.read_text())["runs"]
        if a.schedule == "cyclic":
            held = held["case_base" if a.case_base else "restart"]
        by_seed = {r["seed"]: r["external"] for r in held}
        held_seeds = [r["seed"] for r in runs if r["seed"] in by_seed]
        same = [r["seed"] for r in runs if r["seed"] in by_seed and by_seed[r["seed"]] == r["external"]]
        if held_seeds:
            print(f"  equal to the lockstep run of the same seed: {len(same)} of {len(held_seeds)} (seeds {same})")
        else:
            same = None
            print(f"  no lockstep runs of these seeds in {lock}: not compared")
    det = [d for r in runs for d in r["detections"]]
    found = [d for d in det if d["detected"]]
    print(f"  detected {len(found)}/{len(det)}: trials {[d['trials'] for d in found]}, decisions "
          f"{[d['decisions'] for d in found]}, learner generations on the wrong model {[d.get('generations') for d in found]}")
    lat = np.array([x for r in runs for x in r["latency_ms"]])
    print(f"  new best, learner -> robot: median {np.median(lat):.2f} ms, 90th percentile {np.percentile(lat, 90):.2f} ms, "
          f"max {lat.max():.2f} ms over {len(lat)} policies")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    data = {"runs": runs, "table": table, "lockstep_equal": same, "wall_seconds": wall, "jobs": a.jobs,
            "latency_ms": {"median": float(np.median(lat)), "p90": float(np.percentile(lat, 90)), "max": float(lat.max()),
                           "n": int(len(lat))},
            "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "load_average": os.getloadavg()[0]},
            "external_mean": ext.mean(axis=0).round(2).tolist(),
            "external_sd": ext.std(axis=0, ddof=1 if len(runs) > 1 else 0).round(2).tolist()}
    name = "live" if a.schedule == "figure3" and not a.case_base else f"live-{a.schedule}{'-cases' if a.case_base else ''}"
    name += f"-seeds{a.first_seed}" if a.first_seed else ""
    (out / f"{name}.json").write_text(json.dumps(data, indent=1) + "\n")
    if a.schedule == "cyclic":
        _plot(out / f"{name}.png", data, None, f"cyclic schedule, live service{', case base' if a.case_base else ''}",
              ((25, "fail"), (50, "repair"), (75, "fail")))
    else:
        _plot(out / f"{name}.png", data, event)
    print(f"wrote {out / (name + '.json')} and {out / (name + '.png')}")


def _plot(path: Path, data: dict[str, Any], event: int | None, title: str = "Figure 3 counterpart, live service (coevo cel)",
          marks: tuple[tuple[int, str], ...] = ()) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m, s = np.array(data["external_mean"]), np.array(data["external_sd"])
    g = np.arange(len(m))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.fill_between(g, m - s, m + s, alpha=0.25, label="± 1 s.d.")
    ax.plot(g, m, label=f"mean of {len(data['runs'])} live runs")
    if event is not None:
        ax.axvline(event, color="k", linestyle="--", linewidth=1, label="front, front-right, right fail")
        gens = [0, event - 1, event, len(m) - 1]
        ax.plot(gens, [REPORT[k] for k in ("default", "all_sonars", "drop", "adapted")], "o", color="C3",
                label="the report's numbers (end: 'over 60')")
    ax.set_xlabel("generation")
    ax.set_ylabel("external performance (% of 100 trials)")
    ax.set_ylim(0, 100)
    for g, what in marks:
        ax.axvline(g, color="k", linestyle=":" if what == "repair" else "--", linewidth=1)
        ax.text(g + 0.5, 3, what, fontsize=8)
    ax.set_title(title)
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
