"""Time the two Appendix C experiments at 100 runs each (the issue's target: under a minute each).

    .venv/bin/python benchmarks/earl.py [--runs 100] [--seed 0] [--out runs/earl-bench]

Runs the same code as ``coevo earl`` in this process, writes its report to OUT (when given) and
prints the wall time of each experiment as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

from coevo.experiments.earl.experiment import EarlSpec, run_grid, run_hidden
from coevo.experiments.earl.report import write_report
from coevo.rundir.layout import staged_dir


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", help="keep the report here (default: a temporary directory, removed)")
    args = ap.parse_args()
    spec = EarlSpec(runs=args.runs, seed=args.seed)
    t0 = time.perf_counter()
    grid = run_grid(spec)
    t1 = time.perf_counter()
    hid = run_hidden(spec)
    t2 = time.perf_counter()
    seconds = {"grid": t1 - t0, "hidden": t2 - t1}
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(args.out) if args.out else Path(scratch) / "earl"
        with staged_dir(out) as tmp:
            results = write_report(tmp, spec, grid, hid, seconds=seconds)
        t3 = time.perf_counter()
    timing = {"runs": spec.runs, "grid_seconds": round(t1 - t0, 2), "hidden_seconds": round(t2 - t1, 2),
              "report_seconds": round(t3 - t2, 2), "target_seconds_each": 60,
              "verdicts": [c["verdict"] for c in results["claims"]],
              "cpus": os.cpu_count(), "load_average_at_end": [round(x, 2) for x in os.getloadavg()],
              "python": platform.python_version()}
    print(json.dumps(timing))


if __name__ == "__main__":
    main()
