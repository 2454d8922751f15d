"""Time the full Appendix D grid (2 classes x 8 rates x 4 models x 10 landscapes x 10 runs).

    python benchmarks/evolvability.py --out runs/evolvability-bench

Runs the grid in this process (the same code as ``coevo evolvability``), writes the
full report to OUT and prints the wall time per stage as JSON (also OUT/timing.json).
Target: under 10 minutes on a 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from coevo.experiments.evolvability.experiment import GridSpec, run_grid
from coevo.experiments.evolvability.report import write_report


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="runs/evolvability-bench")
    ap.add_argument("--landscapes", type=int, default=10)
    ap.add_argument("--runs", type=int, default=10)
    args = ap.parse_args()
    spec = GridSpec.make(landscapes=args.landscapes, runs=args.runs)
    t0 = time.perf_counter()
    res = run_grid(spec)
    t1 = time.perf_counter()
    write_report(res, Path(args.out), elapsed=t1 - t0)
    t2 = time.perf_counter()
    timing = {"runs": spec.total_runs, "grid_seconds": round(t1 - t0, 1), "report_seconds": round(t2 - t1, 1),
              "total_seconds": round(t2 - t0, 1), "cpus": os.cpu_count(), "load_average_at_end": os.getloadavg(),
              "python": platform.python_version()}
    (Path(args.out) / "timing.json").write_text(json.dumps(timing, indent=1))
    print(json.dumps(timing))


if __name__ == "__main__":
    main()
