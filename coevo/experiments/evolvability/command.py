"""``coevo evolvability``: the Appendix D grid from the command line (registered by :mod:`coevo.cli`).

Kept here rather than in ``cli.py`` so the experiment's options live next to it; errors
are :class:`~coevo.errors.ConfigError` and reach the user through ``coevo.cli.main``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from coevo.console import ProgressBar, seed_arg
from coevo.errors import ConfigError

__all__ = ["configure_evolvability", "cmd_evolvability"]


def cmd_evolvability(args: argparse.Namespace) -> int:
    """Run the grid (or only rewrite the report of a finished one) and print the claims' verdicts."""
    from coevo.experiments.evolvability.experiment import GridResults, GridSpec, run_grid
    from coevo.experiments.evolvability.report import write_report
    from coevo.rundir.layout import ensure_dir

    if args.report_only:
        if not args.out:
            raise ConfigError("--report-only needs --out DIR (a finished grid)")
        res = GridResults.load(Path(args.out))
        write_report(res, Path(args.out), elapsed=res.seconds)
        print(f"report: {Path(args.out) / 'report.md'}")
        return 0
    spec = GridSpec.make(classes=_tuple(args.classes), rates=_tuple(args.rates), models=_tuple(args.models),
                         landscapes=args.landscapes, runs=args.runs, generations=args.generations,
                         population=args.population, seed=args.seed)
    out = Path(args.out) if args.out else Path("runs") / f"evolvability-{time.strftime('%Y%m%d-%H%M%S')}"
    ensure_dir(out, what="--out")  # before the grid runs, not after
    print(f"evolvability grid: {spec.total_runs} runs of {spec.generations} generations; output in {out}", flush=True)
    with ProgressBar("evolvability", total=1, unit="batch-generations", quiet=args.quiet) as bar:
        res = run_grid(spec, on_progress=lambda done, total: bar.update(done, total))
    results = write_report(res, out, elapsed=res.seconds)
    print(f"{res.seconds:.1f} s; report: {out / 'report.md'}")
    for c in results["claims"]:
        print(f"  {c['verdict']}: {c['claim']}")
    return 0


def _number(text: str) -> float | str:
    """A float, or the text itself so that the settings check can name it."""
    try:
        return float(text)
    except ValueError:
        return text


def _tuple(values: list[Any] | None) -> tuple[Any, ...] | None:
    return None if values is None else tuple(values)


def configure_evolvability(p: argparse.ArgumentParser) -> None:
    """``coevo evolvability``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    p.add_argument("--out", help="output directory (default runs/evolvability-TIME)")
    p.add_argument("--classes", nargs="+", metavar="CLASS", help="landscape classes (default: gradual abrupt)")
    p.add_argument("--rates", nargs="+", type=_number, metavar="MR", help="base mutation rates (default: the report's 8)")
    p.add_argument("--models", nargs="+", metavar="MODEL", help="mutation models (default: fm gm fh gh)")
    p.add_argument("--landscapes", type=int, help="landscapes per class (default 10)")
    p.add_argument("--runs", type=int, help="runs per landscape and condition (default 10)")
    p.add_argument("--generations", type=int, help="generations per run (default 200)")
    p.add_argument("--population", type=int, help="population size (default 100)")
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--report-only", action="store_true", help="only rewrite the report from the grid finished in --out")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.set_defaults(func=cmd_evolvability)
