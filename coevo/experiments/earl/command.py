"""``coevo earl``: both Appendix C experiments and their report, for the command line.

``add_arguments`` fills a parser and ``main`` runs it; the CLI registers them as a sub-command.
Bad values raise :class:`~coevo.errors.ConfigError` (settings) or :class:`~coevo.errors.RunDirError`
(the output directory) before anything runs; the CLI prints them as one ``Type: message`` line.
The output directory is written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from coevo.errors import ConfigError

__all__ = ["add_arguments", "main"]


def _seed(text: str) -> int:
    """A seed: a whole number from 0 to 2**63 - 1 (numpy's generators refuse negative seeds)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid seed {text!r}: give a whole number >= 0") from None
    if not 0 <= v < 2**63:
        raise argparse.ArgumentTypeError(f"invalid seed {v}: give a whole number from 0 to 2**63 - 1")
    return v


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``coevo earl``."""
    parser.add_argument("--out", required=True, help="output directory (must not exist, or be empty)")
    parser.add_argument("--runs", type=int, default=100, help="independent runs per learner and experiment (default 100)")
    parser.add_argument("--seed", type=_seed, default=0, help="seed of every run's generator (default 0)")
    parser.add_argument("--generations", type=int, default=100, help="EARL1 generations (default 100)")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


def main(args: argparse.Namespace) -> int:
    """Run the grid and hidden-state experiments, write the report into ``args.out``, print the verdicts."""
    from coevo.experiments.earl.experiment import EarlSpec, run_grid, run_hidden
    from coevo.experiments.earl.report import write_report
    from coevo.runs.layout import staged_dir

    if args.runs < 1:
        raise ConfigError(f"--runs {args.runs}: give a whole number >= 1")
    if args.generations < 0:
        raise ConfigError(f"--generations {args.generations}: give a whole number >= 0")
    spec = EarlSpec(runs=args.runs, seed=args.seed, generations=args.generations)
    out = Path(args.out)
    with staged_dir(out) as tmp, _progress(args.quiet) as progress:
        seconds = {}
        t0 = time.perf_counter()
        grid = run_grid(spec, progress)
        seconds["grid"] = time.perf_counter() - t0
        t1 = time.perf_counter()
        hid = run_hidden(spec, progress)
        seconds["hidden"] = time.perf_counter() - t1
        results = write_report(tmp, spec, grid, hid, seconds=seconds)
    print(f"grid {seconds['grid']:.1f} s, hidden state {seconds['hidden']:.1f} s; report: {out / 'report.md'}")
    for c in results["claims"]:
        print(f"  {c['verdict']}: {c['claim']}")
    return 0


class _progress:
    """A rich progress bar on stderr, one task per stage; a no-op when quiet."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self._bar = None
        self._tasks: dict[str, int] = {}

    def __enter__(self):  # type: ignore[no-untyped-def]
        if not self.quiet:
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self._bar = Progress(TextColumn("{task.description:<28}"), BarColumn(),
                                 TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                                 console=Console(file=sys.stderr))
            self._bar.start()
        return self

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self._bar is None:
            return
        if stage not in self._tasks:
            self._tasks[stage] = self._bar.add_task(stage, total=total)
        self._bar.update(self._tasks[stage], completed=done, total=total)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()
