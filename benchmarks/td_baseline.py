"""Time the TD baseline against the GA on Tracking, Docking and the door task (issue 19, item 3).

    .venv/bin/python benchmarks/td_baseline.py [--out docs/td] [--tasks tracking docking door] [any td option]
    .venv/bin/python benchmarks/td_baseline.py --combine docs/td/door docs/td/docking ... --out docs/td

Runs the same code as the future ``coevo td-baseline`` (:mod:`coevo.experiments.earl.td_command`) in this
process, task by task, writes the report (results.json, curves.csv, fig-TASK.png, report.md) and
``timing.json`` into OUT, and prints the timing as JSON. The issue's target: one task under 5 minutes
(the GA's runs and the main TD runs; the variants are timed apart).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from coevo.experiments.earl.td_command import add_td_arguments, specs_from_args
from coevo.experiments.earl.td_report import read_results, summarise, write_report
from coevo.experiments.earl.td_tasks import run_task
from coevo.rundir.layout import staged_dir

TARGET_SECONDS = 300


def main() -> None:
    ap = argparse.ArgumentParser()
    add_td_arguments(ap)
    ap.set_defaults(out="docs/td")
    for a in ap._actions:  # --out has a default here
        if a.dest == "out":
            a.required = False
    ap.add_argument("--combine", nargs="+", metavar="DIR",
                    help="write one report into --out from these runs' results.json and timing.json (no runs)")
    args = ap.parse_args()
    if args.combine:
        combine([Path(d) for d in args.combine], Path(args.out))
        return
    specs = specs_from_args(args)
    results, timing = {}, {}
    with staged_dir(Path(args.out)) as tmp:
        for spec, variants in specs:
            t0 = time.perf_counter()
            res = run_task(spec, variants=variants)
            results[spec.task] = res
            main_s = res["seconds"]["ga"] + res["seconds"]["td"]
            last = summarise(res)["rows"][-1]
            timing[spec.task] = {
                "seconds_ga_and_td": round(main_s, 1), "seconds_variants": round(res["seconds"]["variants"], 1),
                "seconds_total": round(time.perf_counter() - t0, 1), "under_target": main_s < TARGET_SECONDS,
                "robot_steps": last["robot_steps"], "ga": round(last["ga"]["mean"], 1), "td": round(last["td"]["mean"], 1),
                **{f"td_{v}": round(last[f"td_{v}"]["mean"], 1) for v in variants},
                "td_table_observations": summarise(res)["table"]["observations"],
            }
            print(json.dumps({spec.task: timing[spec.task]}), flush=True)
        data = write_report(tmp, results)
        summary = {"tasks": timing, "target_seconds_one_task": TARGET_SECONDS,
                   "verdicts": {c["claim"].split(":")[0]: c["verdict"] for c in data["claims"]},
                   "cpus": os.cpu_count(), "load_average_at_end": [round(x, 2) for x in os.getloadavg()],
                   "python": platform.python_version()}
        (tmp / "timing.json").write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(summary))


def combine(dirs: list[Path], out: Path) -> None:
    """One report over several benchmark runs (e.g. one per task, run one after another)."""
    results, timing = {}, {}
    for d in dirs:
        results.update(read_results(d / "results.json"))
        timing.update(json.loads((d / "timing.json").read_text(encoding="utf-8"))["tasks"])
    out.mkdir(parents=True, exist_ok=True)
    data = write_report(out, results)
    summary = {"tasks": timing, "target_seconds_one_task": TARGET_SECONDS, "combined_from": [str(d) for d in dirs],
               "verdicts": {c["claim"].split(":")[0]: c["verdict"] for c in data["claims"]}}
    (out / "timing.json").write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
