"""``coevo earl``: both Appendix C experiments and their report, for the command line.

``add_parser`` registers the sub-command (``add_arguments`` fills its parser) and ``main`` runs it.
Bad values raise :class:`~coevo.errors.ConfigError` (settings) or :class:`~coevo.errors.RunDirError`
(the output directory) before anything runs; the CLI prints them as one ``Type: message`` line.
The output directory is written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from coevo.console import ProgressBar, count_arg, seed_arg

__all__ = ["add_arguments", "configure_earl", "main"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``coevo earl``."""
    parser.add_argument("--out", required=True, help="output directory (must not exist, or be empty)")
    parser.add_argument("--runs", type=count_arg(1, 1000), default=100, help="independent runs per learner and experiment (default 100)")
    parser.add_argument("--seed", type=seed_arg, default=0, help="seed of every run's generator (default 0)")
    parser.add_argument("--generations", type=count_arg(0, 1000), default=100, help="EARL1 generations (default 100)")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


def main(args: argparse.Namespace) -> int:
    """Run the grid and hidden-state experiments, write the report into ``args.out``, print the verdicts."""
    from coevo.experiments.earl.experiment import EarlSpec, run_grid, run_hidden
    from coevo.experiments.earl.report import write_report
    from coevo.rundir.layout import staged_dir

    spec = EarlSpec(runs=args.runs, seed=args.seed, generations=args.generations)
    out = Path(args.out)
    with staged_dir(out) as tmp, ProgressBar("earl", quiet=args.quiet) as bar:
        seconds = {}
        t0 = time.perf_counter()
        grid = run_grid(spec, bar.stage)
        seconds["grid"] = time.perf_counter() - t0
        t1 = time.perf_counter()
        hid = run_hidden(spec, bar.stage)
        seconds["hidden"] = time.perf_counter() - t1
        results = write_report(tmp, spec, grid, hid, seconds=seconds)
    print(f"grid {seconds['grid']:.1f} s, hidden state {seconds['hidden']:.1f} s; report: {out / 'report.md'}")
    for c in results["claims"]:
        print(f"  {c['verdict']}: {c['claim']}")
    return 0


def configure_earl(p: argparse.ArgumentParser) -> None:
    """``coevo earl``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    add_arguments(p)
    p.set_defaults(func=main)
