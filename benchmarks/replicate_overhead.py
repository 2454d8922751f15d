"""What running a replicate on Dask costs beyond running it here: per replicate, the wall time from submission to
its run folder back in the experiment's folder, minus the time the replicate itself ran (``coevo run`` inside
``execute``), on this machine (``--jobs 1``) and on a local Dask cluster of one worker (one at a time in both, so
nothing queues).  Also the time to start a local Dask cluster (once per experiment).

    python benchmarks/replicate_overhead.py [--runs 2] [--repeats 3] [--generations 3]

Figures: docs/cluster.md.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from coevo.config import GAConfig
from coevo.experiments.compare.experiment import CompareSpec, jobs_of, prepare
from coevo.replicates.backends import open_backend
from coevo.replicates.runner import run_replicates


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=2, help="runs per regime (mutual, independent)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--generations", type=int, default=3)
    args = ap.parse_args()
    spec = CompareSpec.make(runs=args.runs, measure_epochs=2,
                            ga=GAConfig(generations=args.generations, population=6, episodes=6))
    rows: dict[str, list[tuple[float, float]]] = {"jobs 1": [], "local:1": []}
    starts = []
    for _ in range(args.repeats):
        for where in rows:
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "cmp"
                prepare(out, spec, resume=False)
                t0 = time.perf_counter()
                backend = open_backend(jobs=1, cluster=None if where == "jobs 1" else "local:1")
                if where != "jobs 1":
                    backend.client.wait_for_workers(1)
                    starts.append(time.perf_counter() - t0)
                prog = run_replicates(jobs_of(out, spec), out, backend, poll=0.05)
                assert not prog.failed, prog.failed
                rows[where] += [(o.wall, o.seconds) for o in prog.outcomes]
    for where, xs in rows.items():
        over = [w - s for w, s in xs]
        print(f"{where}: {len(xs)} replicates; run itself median {statistics.median(s for _, s in xs):.2f} s "
              f"(min {min(s for _, s in xs):.2f}, max {max(s for _, s in xs):.2f}); wall minus run: median "
              f"{statistics.median(over):.3f} s (min {min(over):.3f}, max {max(over):.3f})")
    print(f"starting a local Dask cluster of 1 worker: median {statistics.median(starts):.2f} s "
          f"(min {min(starts):.2f}, max {max(starts):.2f})")


if __name__ == "__main__":
    main()
