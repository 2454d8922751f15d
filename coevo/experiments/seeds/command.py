"""``coevo seeds``: Tracking and Docking learned over seeds against the learning targets (registered by
:mod:`coevo.cli`; the experiment is :mod:`.experiment`)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from coevo.console import ProgressBar, count_arg, seed_arg
from coevo.errors import RunDirError
from coevo.replicates.flags import add_backend_flags, backend_of

__all__ = ["configure_seeds", "cmd_seeds"]


def cmd_seeds(args: argparse.Namespace) -> int:
    from coevo.experiments.seeds.experiment import replicates, write_report
    from coevo.replicates.backends import ClusterLost
    from coevo.replicates.runner import run_replicates

    out = Path(args.out) if args.out else Path("runs") / f"seeds-{time.strftime('%Y%m%d-%H%M%S')}"
    from coevo.rundir.layout import ensure_dir

    if out.is_dir() and any(out.iterdir()) and not args.resume:
        raise RunDirError(f"--out {str(out)!r} is not empty; add --resume to continue the runs there")
    ensure_dir(out, what="--out")
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    extra = list(args.learn_args or [])
    reps = replicates(args.behaviours, seeds, extra)
    backend = backend_of(args, default_jobs=1)
    print(f"learning over seeds in {out}: {len(reps)} runs, {backend.description}", flush=True)
    t0 = time.time()
    with ProgressBar("seeds", total=len(reps), unit="runs", quiet=args.quiet) as bar:
        try:
            prog = run_replicates(reps, out, backend, on_progress=lambda p: bar.update(p.runs_done, p.runs_total, p.info))
        except ClusterLost as exc:
            print(f"{exc}; finished runs are kept: continue with the same command and --resume --out {out}",
                  file=sys.stderr)
            return 3
    for name, why in prog.failed.items():
        print(f"  {name} failed: {why} (log: {out / 'logs' / (name + '.log')})", file=sys.stderr)
    results = write_report(out, args.behaviours, seeds, elapsed=time.time() - t0)
    print(f"report: {out / 'report.md'}")
    for v in results["verdicts"]:
        print(v["text"])
    return 1 if prog.failed else 0


def configure_seeds(p: argparse.ArgumentParser) -> None:
    """``coevo seeds``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    p.add_argument("--seeds", type=count_arg(1, 10_000), default=5, help="seeds per behaviour (default 5)")
    p.add_argument("--first-seed", type=seed_arg, default=0)
    p.add_argument("--behaviours", nargs="+", default=["docking", "tracking"], choices=["docking", "tracking"])
    p.add_argument("--out", help="output directory (default runs/seeds-TIME)")
    p.add_argument("--resume", action="store_true", help="keep the finished runs in --out and run the rest")
    p.add_argument("--learn-arg", dest="learn_args", action="append", metavar="ARG",
                   help="an argument passed on to every coevo learn (repeatable), e.g. --learn-arg=--generations=5")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_backend_flags(p, jobs_help="runs at once on this machine (default 1: the timing target is per core)")
    p.set_defaults(func=cmd_seeds)
