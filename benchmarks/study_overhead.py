"""What a study costs beyond the comparisons it runs, and how its wall time scales with ``--jobs`` here.

1. Overhead per cell: the same cell (mutual and independent, ``--runs`` each, the same seeds) run as a plain
   comparison (``coevo.experiments.compare``: prepare, then its replicates on the runner) and as a one-cell study
   (``coevo.experiments.study``: the declaration checked, study.json and the cell's folder, its replicates renamed
   and interleaved, then the same runner), alternately, ``--repeats`` times each, side by side in this one process
   run, ``--jobs 1`` both.  Reports are left out: a comparison's and a study's are different reports.
   Also, without running anything, what each adds around the runs, timed ``--repeats`` x 20 times: a comparison's
   prepare and replicate list against a study's declaration, checks, folders and renamed, interleaved list.
2. Scaling: ``coevo study`` (the command, report included) on a study of ``--cells`` cells with ``--jobs 1`` and
   ``--jobs 2``.

    python benchmarks/study_overhead.py [--runs 2] [--repeats 2] [--generations 5] [--cells 2] [--bookkeeping-only]

Figures: docs/studies.md.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from coevo.experiments.compare.experiment import jobs_of, prepare, run_all
from coevo.experiments.study.declaration import cells, declare
from coevo.experiments.study.experiment import prepare_study, run_study, study_jobs
from coevo.replicates.backends import LocalBackend

GA = ["--population", "6", "--episodes", "10", "--ga", "best_episodes=10", "--ga", "initial_rules=8",
      "--measure-epochs", "5"]


def _settings(generations: int, runs: int) -> dict[str, object]:
    return {"runs": runs, "ga.generations": generations, "ga.population": 6, "ga.episodes": 10,
            "ga.best_episodes": 10, "ga.initial_rules": 8, "measure_epochs": 5}


def one_cell(kind: str, generations: int, runs: int, seed: int) -> float:
    """Seconds from nothing to every run of the cell finished, as a comparison or as a one-cell study."""
    spec = declare(settings=_settings(generations, runs), seed=seed)
    (cell,) = cells(spec)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / kind
        t0 = time.perf_counter()
        if kind == "compare":
            todo = prepare(out, cell.spec, resume=False)
            prog = run_all(out, cell.spec, todo, backend=LocalBackend(1))
        else:
            the_cells = prepare_study(out, declare(settings=_settings(generations, runs), seed=seed), resume=False)
            prog = run_study(out, the_cells, backend=LocalBackend(1))
        seconds = time.perf_counter() - t0
    if prog.failed:
        raise SystemExit(f"{kind}: runs failed: {prog.failed}")
    return seconds


def bookkeeping(kind: str, generations: int, runs: int, seed: int) -> float:
    """Seconds a comparison or a one-cell study spends setting its runs up (nothing run)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / kind
        t0 = time.perf_counter()
        if kind == "compare":
            spec = cells(declare(settings=_settings(generations, runs), seed=seed))[0].spec  # compare's flags, untimed
            t0 = time.perf_counter()
            prepare(out, spec, resume=False)
            jobs_of(out, spec)
        else:
            the_cells = prepare_study(out, declare(settings=_settings(generations, runs), seed=seed), resume=False)
            study_jobs(out, the_cells)
        return time.perf_counter() - t0


def study_command(jobs: int, generations: int, cells_n: int, runs: int) -> float:
    levels = ",".join(str(i + 1) for i in range(cells_n))
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-m", "coevo", "study", "--out", str(Path(tmp) / "s"), "--quiet", "--jobs", str(jobs),
                "--factor", f"max_lead={levels}", "--runs", str(runs), "--generations", str(generations), *GA]
        t0 = time.perf_counter()
        r = subprocess.run(argv, capture_output=True, text=True, check=False)
        seconds = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"coevo study --jobs {jobs} failed: {r.stderr[-500:]}")
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=2, help="runs per regime in a cell")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--generations", type=int, default=5)
    ap.add_argument("--cells", type=int, default=2, help="cells of the scaling study (max_lead 1..N)")
    ap.add_argument("--seed", type=int, default=9100)
    ap.add_argument("--bookkeeping-only", action="store_true", help="only the set-up, no runs")
    args = ap.parse_args()

    setup = {k: statistics.median(bookkeeping(k, args.generations, args.runs, args.seed) for _ in range(20 * args.repeats))
             for k in ("compare", "study")}
    print(f"set-up of one cell ({2 * args.runs} runs), median of {20 * args.repeats}: compare {1000 * setup['compare']:.1f} ms, "
          f"study {1000 * setup['study']:.1f} ms (+{1000 * (setup['study'] - setup['compare']):.1f} ms per cell)")
    if args.bookkeeping_only:
        return
    times: dict[str, list[float]] = {"compare": [], "study": []}
    for i in range(args.repeats):
        order = ("compare", "study") if i % 2 == 0 else ("study", "compare")  # neither always first
        for kind in order:
            times[kind].append(one_cell(kind, args.generations, args.runs, args.seed + i))
            print(f"repeat {i}: {kind} {times[kind][-1]:.1f} s", flush=True)
    c, s = statistics.median(times["compare"]), statistics.median(times["study"])
    print(f"one cell ({2 * args.runs} live runs, {args.generations} generations), median of {args.repeats}: "
          f"compare {c:.1f} s, study {s:.1f} s, overhead {100 * (s - c) / c:+.1f} %")
    print(f"  every repeat: compare {[round(x, 1) for x in times['compare']]}, "
          f"study {[round(x, 1) for x in times['study']]}")

    scaling = {jobs: study_command(jobs, args.generations, args.cells, args.runs) for jobs in (1, 2)}
    n = 2 * args.runs * args.cells
    print(f"coevo study, {args.cells} cells x {2 * args.runs} live runs = {n} runs: "
          + ", ".join(f"--jobs {j} {t:.1f} s" for j, t in scaling.items())
          + f", speed-up {scaling[1] / scaling[2]:.2f}x")


if __name__ == "__main__":
    main()
