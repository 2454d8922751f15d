"""``coevo evolvability``: the Appendix D grid from the command line (registered by :mod:`coevo.cli`).

Kept here rather than in ``cli.py`` so the experiment's options live next to it; errors
are :class:`~coevo.errors.ConfigError` and reach the user through ``coevo.cli.main``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from coevo.console import ProgressBar, count_arg, positive_float_arg, seed_arg
from coevo.errors import ConfigError
from coevo.replicates.flags import add_backend_flags, backend_of, check_backend_flags

__all__ = ["configure_evolvability", "cmd_evolvability"]


def cmd_evolvability(args: argparse.Namespace) -> int:
    """Run the grid (or only rewrite the report of a finished one) and print the claims' verdicts."""
    from coevo.experiments.evolvability.experiment import GridResults, GridSpec, run_grid
    from coevo.replicates.backends import ClusterLost

    if args.report_only:
        if not args.out:
            raise ConfigError("--report-only needs --out DIR (a finished grid)")
        res = GridResults.load(Path(args.out))
        from coevo.experiments.evolvability.report import write_report  # scipy.stats: not before a refusal

        write_report(res, Path(args.out), elapsed=res.seconds)
        print(f"report: {Path(args.out) / 'report.md'}")
        return 0
    spec = GridSpec.make(classes=_tuple(args.classes), rates=_tuple(args.rates), models=_tuple(args.models),
                         landscapes=args.landscapes, runs=args.runs, generations=args.generations,
                         population=args.population, seed=args.seed)
    out = Path(args.out) if args.out else Path("runs") / f"evolvability-{time.strftime('%Y%m%d-%H%M%S')}"
    check_backend_flags(args)
    _prepare(out, spec, resume=args.resume)  # before the grid runs, not after
    backend = backend_of(args, default_jobs=1)
    print(f"evolvability grid: {spec.total_runs} runs of {spec.generations} generations; output in {out}; "
          f"{len(spec.classes) * spec.landscapes} landscapes {backend.description}", flush=True)
    with ProgressBar("evolvability", total=1, unit="batch-generations", quiet=args.quiet) as bar:
        try:
            res = run_grid(spec, out=out, backend=backend, on_progress=lambda done, total: bar.update(done, total))
        except ClusterLost as exc:
            print(f"{exc}; finished landscapes are kept: continue with the same command and --resume --out {out}",
                  file=sys.stderr)
            return 3
    from coevo.experiments.evolvability.report import write_report

    results = write_report(res, out, elapsed=res.seconds)
    print(f"{res.seconds:.1f} s; report: {out / 'report.md'}")
    for c in results["claims"]:
        print(f"  {c['verdict']}: {c['claim']}")
    return 0


def _prepare(out: Path, spec: Any, *, resume: bool) -> None:
    """A fresh grid needs an --out without one; ``resume`` needs this very grid there (its finished landscapes are
    kept)."""
    import json

    from coevo.errors import RunDirError
    from coevo.experiments.common import held_spec
    from coevo.rundir.layout import ensure_dir, write_json

    mine = json.loads(json.dumps(spec.as_dict()))
    held = held_spec(out, "evolvability.json", mine, what="grid")
    if held is not None and not resume and (out / "landscapes").exists():
        raise RunDirError(f"--out {str(out)!r} already holds this grid; add --resume to continue it")
    if resume and held is None:
        raise RunDirError(f"--resume: {str(out)!r} holds no grid (no evolvability.json)")
    ensure_dir(out, what="--out")
    if held is None:
        write_json(out / "evolvability.json", {"spec": mine, "created": time.time()})


def _tuple(values: list[Any] | None) -> tuple[Any, ...] | None:
    return None if values is None else tuple(values)


def configure_evolvability(p: argparse.ArgumentParser) -> None:
    """``coevo evolvability``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    p.add_argument("--out", help="output directory (default runs/evolvability-TIME)")
    p.add_argument("--classes", nargs="+", metavar="CLASS", help="landscape classes (default: gradual abrupt)")
    p.add_argument("--rates", nargs="+", type=positive_float_arg(allow_zero=True, maximum=1), metavar="MR", help="base mutation rates (default: the report's 8)")
    p.add_argument("--models", nargs="+", metavar="MODEL", help="mutation models (default: fm gm fh gh)")
    p.add_argument("--landscapes", type=count_arg(1, 100), help="landscapes per class (default 10)")
    p.add_argument("--runs", type=count_arg(1, 100), help="runs per landscape and condition (default 10)")
    p.add_argument("--generations", type=count_arg(1, 10_000), help="generations per run (default 200)")
    p.add_argument("--population", type=count_arg(2, 1000), help="population size (default 100)")
    p.add_argument("--seed", type=seed_arg, default=0, help="seeds the landscapes and the runs (default 0)")
    p.add_argument("--report-only", action="store_true", help="only rewrite the report from the grid finished in --out")
    p.add_argument("--resume", action="store_true", help="continue the grid in --out, keeping its finished landscapes")
    add_backend_flags(p, jobs_help="landscapes at once on this machine (default 1: all its runs advance together "
                                   "as one batch, which keeps a core busy)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.set_defaults(func=cmd_evolvability)
