"""``coevo compare``: many real runs per regime, then Table 1, the curves, the rank tests and a verdict.

Registered by :mod:`coevo.cli`; the experiment itself is :mod:`.experiment`, its report :mod:`.report`.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from coevo.console import (
    ProgressBar,
    given_settings,
    add_max_lead,
    max_lead_of,
    add_settings,
    count_arg,
    positive_float_arg,
    seed_arg,
    task_arg,
)
from coevo.config import DEFAULT_MAX_LEAD, MODELS
from coevo.errors import ConfigError
from coevo.replicates.flags import add_backend_flags, backend_of, check_backend_flags

__all__ = ["configure_compare", "cmd_compare"]

def cmd_compare(args: argparse.Namespace) -> int:
    from coevo.experiments.compare.experiment import CompareSpec, held_spec, prepare, run_all
    from coevo.experiments.compare.reading import write_report
    from coevo.experiments.compare.experiment import default_jobs, replicates
    from coevo.replicates.backends import ClusterLost
    from coevo.tasks import DEFAULT_TASK, get_task

    if (args.resume or args.report_only) and args.out is None:
        raise ConfigError("--resume and --report-only need --out: the comparison's folder")
    if args.force and not args.resume:
        raise ConfigError("--force goes with --resume (continue a comparison that ran on other code)")
    out = Path(args.out) if args.out else Path("runs") / f"compare-{time.strftime('%Y%m%d-%H%M%S')}"
    held = held_spec(out) if (args.resume or args.report_only) and out.is_dir() else None
    # the settings as given, checked once, by the comparison's own model (its task's world and GA rules)
    if args.resume and held is None and not _given(args) and given_settings(args, args.task or DEFAULT_TASK) == ({}, {}):
        raise ConfigError(f"--resume: {out} holds no comparison (no compare.json) and no settings were given, so "
                          "there is nothing to continue; to start a comparison there, drop --resume")
    if held is not None:  # its own settings, as it ran, but for those given: a resume need not repeat them
        world, ga = given_settings(args, held.task)
        spec = CompareSpec.make(**{**held.model_dump(mode="json"), **_given(args),
                                   "world": {**held.world.model_dump(mode="json"), **world},
                                   "ga": {**held.ga.model_dump(mode="json"), **ga}})
    else:
        task = get_task(args.task or DEFAULT_TASK)
        world, ga = given_settings(args, task.name)
        spec = CompareSpec.make(**{"task": task.name, "regimes": task.regimes, "max_lead": DEFAULT_MAX_LEAD,
                                   **_given(args), "world": world, "ga": ga})
    check_backend_flags(args)  # before anything is written into --out
    t0 = time.time()
    if args.report_only:
        if held is None:
            raise ConfigError(f"--report-only: {out} holds no comparison (no compare.json)")
        todo = prepare(out, spec, resume=True, report_only=True)
        print(f"{len(todo)} runs unfinished; reporting on the rest")
    else:
        todo = prepare(out, spec, resume=args.resume, force=args.force)
        backend = backend_of(args, default_jobs=default_jobs())
        total = len(replicates(spec))
        print(f"comparison in {out}: {total - len(todo)} of {total} runs already done, {len(todo)} to run, "
              f"{backend.description}", flush=True)
        with ProgressBar("compare", total=1, unit="worker generations", quiet=args.quiet) as bar:
            try:
                prog = run_all(out, spec, todo, backend=backend, on_progress=lambda p: bar.update(p.done, p.total, info=p.info))
            except KeyboardInterrupt:
                print(f"interrupted; finished runs are kept: continue with the same command and --resume --out {out}",
                      file=sys.stderr)
                return 130
            except ClusterLost as exc:
                print(f"{exc}; finished runs are kept: continue with the same command and --resume --out {out}",
                      file=sys.stderr)
                return 3
        if prog.failed:
            print(f"{len(prog.failed)} runs failed; their logs are in {out / 'logs'}. Run again with --resume to retry them.",
                  file=sys.stderr)
            for name, why in prog.failed.items():
                print(f"  {name}: {why}", file=sys.stderr)
    results = write_report(out, spec, elapsed=None if args.report_only else time.time() - t0)
    print(f"report: {out / 'report.md'}")
    for line in _summary(results):
        print(line)
    print(results["verdict"])
    return 1 if results["runs_finished"] < results["runs_expected"] and not args.report_only else 0


def _summary(results: dict[str, Any]) -> list[str]:
    """The report's lines for the terminal: Table 1 and the Executive's curve (the fuel task's reading), or each
    regime's means (any other task's)."""
    from coevo.experiments.compare.stats import MeanInterval

    if "table1" not in results:
        from coevo.experiments.compare.any_task import summary_lines

        return summary_lines(results)
    from coevo.experiments.compare.report import tail_text

    lines = [f"  {r}: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v) for r, counts in results["table1"].items()]
    for r, c in results["executive_curve"].items():
        lines.append(f"  {r}: Executive's generation's best at the last generation {MeanInterval(**c['end']).text()}, "
                     f"mean of its last {tail_text(c['tail_generations'])} {MeanInterval(**c['last_generations']).text()}")
    return lines


def _given(args: argparse.Namespace) -> dict[str, Any]:
    """The comparison's settings the command line gives (beside the world and GA ones), by their names in it."""
    given: dict[str, Any] = {f: getattr(args, f) for f in ("task", "runs", "seed", "model", "measure_epochs")
                             if getattr(args, f) is not None}
    if args.regimes is not None:
        given["regimes"] = tuple(args.regimes)
    if args.rates is not None:
        given["rates"] = tuple(args.rates)
    if args.max_lead is not None:
        given["max_lead"] = max_lead_of(args.max_lead, DEFAULT_MAX_LEAD)
    return given


def configure_compare(p: argparse.ArgumentParser) -> None:
    """``coevo compare``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    p.add_argument("--task", type=task_arg, help="the task whose regimes are compared (default fuel, the report's; "
                   "coevo plugins lists those installed); a resume takes its comparison's")
    p.add_argument("--regimes", nargs="+", metavar="REGIME",
                   help="regimes to compare (default: every regime of the task; the fuel task's mutual independent); "
                        "independent-offline: a task's offline learner (the fuel task's Executive) learns on the "
                        "independent runs' recorded partner histories, at each --rates")
    p.add_argument("--rates", nargs="+", type=positive_float_arg(maximum=1e6), metavar="R",
                   help="independent-offline: rates of asynchrony, partner generations per Executive generation "
                        "(default 0.25 0.5 1 2 4)")
    p.add_argument("--runs", type=count_arg(1, 1000), help="runs per regime (default 10, as in the report)")
    p.add_argument("--out", help="comparison directory (default runs/compare-TIME)")
    p.add_argument("--resume", action="store_true", help="continue the comparison in --out, keeping its finished runs "
                   "(given none of its settings, with its own)")
    p.add_argument("--report-only", action="store_true", help="only (re)write the report from the finished runs in --out "
                   "(given none of its settings, with its own)")
    p.add_argument("--force", action="store_true",
                   help="with --resume: continue a comparison that ran on other code (its code.json names it) all the same")
    add_backend_flags(p, jobs_help="runs at once on this machine (default: one per two cores; an offline Executive "
                                   "counts half)")
    p.add_argument("--seed", type=seed_arg, help="base seed; run i of every regime uses seed + 1000 i (default 0)")
    p.add_argument("--model", choices=MODELS,
                   help="how a worker models its partners: best, their newest published best so far (the report's "
                        "choice, default); current, the best individual of their latest generation; recent, each "
                        "generation one of their last 5 bests so far at random")
    p.add_argument("--measure-epochs", type=count_arg(1, 100_000), help="fresh epochs measuring each final robot "
                   "(default 100)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_max_lead(p)
    add_settings(p)
    p.set_defaults(func=cmd_compare)
