"""``coevo td-baseline``: Q-learning against the GA on the robot tasks, at equal experience.

``add_td_arguments`` fills a parser and ``td_main`` runs it: for each task the GA's runs, then the TD runs
at the GA's robot-steps and the variants, each a replicate of :mod:`coevo.replicates`
(:mod:`.replicates`: ``--jobs`` here, or ``--cluster``; ``--resume`` keeps the finished ones), then the
report in ``--out``. Bad values raise :class:`~coevo.errors.ConfigError` naming them (a bad ``--out``:
:class:`~coevo.errors.RunDirError`) before anything runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from coevo.config import GAConfig
from coevo.console import Bounded, count_arg, positive_float_arg, seed_arg
from coevo.errors import ConfigError
from coevo.experiments.earl.td.spec import TDSpec
from coevo.replicates.flags import add_backend_flags, check_backend_flags

__all__ = ["configure_td_baseline", "add_td_arguments", "td_main", "specs_from_args"]


def configure_td_baseline(p: argparse.ArgumentParser) -> None:
    """``coevo td-baseline``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    add_td_arguments(p)
    add_backend_flags(p, jobs_help="runs at once on this machine (default 1: the timing target is per core)")
    p.set_defaults(func=td_main)


def add_td_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the TD baseline."""
    from coevo.experiments.earl.td.encoders import ENCODERS
    from coevo.experiments.earl.td.spec import TASKS, VARIANTS

    parser.add_argument("--out", required=True, help="output directory (must not exist, or be empty; with --resume "
                                                     "the same experiment's)")
    parser.add_argument("--resume", action="store_true", help="keep the finished runs in --out and run the rest")
    parser.add_argument("--tasks", nargs="+", default=list(TASKS), metavar="TASK",
                        help=f"tasks to compare on ({', '.join(TASKS)}; default all)")
    parser.add_argument("--seeds", type=count_arg(1, 1000), default=3, help="runs of each learner per task (default 3)")
    parser.add_argument("--seed", type=seed_arg, default=0, help="first GA seed and the TD runs' seed (default 0)")
    parser.add_argument("--generations", type=Bounded.setting(GAConfig, "generations"), default=50, help="GA generations; sets the TD budget (default 50)")
    parser.add_argument("--population", type=Bounded.setting(GAConfig, "population"), default=50, help="GA population (default 50)")
    parser.add_argument("--episodes", type=Bounded.setting(GAConfig, "episodes"), default=90, help="GA evaluation episodes per individual (default 90)")
    parser.add_argument("--lanes", type=count_arg(1, 100_000), default=256, help="robots feeding each TD table at once (default 256)")
    parser.add_argument("--trials", type=count_arg(1, 10_000), default=100,
                        help="fresh trials per measurement: epochs (Tracking) or x5 trials (default 100)")
    parser.add_argument("--alpha", type=positive_float_arg(maximum=1), default=0.1, help="Q-learning rate (default 0.1)")
    parser.add_argument("--gamma", type=positive_float_arg(allow_zero=True, maximum=1), default=1.0, help="discount (default 1: the payoff is the return)")
    parser.add_argument("--epsilon", type=positive_float_arg(allow_zero=True, maximum=1), default=0.1, help="exploration rate (default 0.1)")
    parser.add_argument("--encoder", default="reduced", choices=sorted({e for _, e in ENCODERS}),
                        help="TD observation: the reduced sensors (default) or every sensor at the schema's bins")
    parser.add_argument("--variants", nargs="*", default=["shaped", "default-rules"], metavar="VARIANT",
                        help=f"extra TD runs ({', '.join(VARIANTS)}; each where the task has it; default both)")
    parser.add_argument("--td-steps", type=count_arg(1, 10**10), default=None, help="TD robot-steps per run (default: the GA's)")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


def specs_from_args(args: argparse.Namespace) -> list[tuple[TDSpec, tuple[str, ...]]]:
    """(TDSpec, variants) per task from the parsed options; raises ConfigError naming a bad one."""
    from coevo.experiments.earl.td.spec import TASKS, VARIANTS, TDSpec

    tasks = list(dict.fromkeys(args.tasks))
    for t in tasks:
        if t not in TASKS:
            raise ConfigError(f"--tasks {t}: choose from {', '.join(TASKS)}")
    for v in args.variants:
        if v not in VARIANTS:
            raise ConfigError(f"--variants {v}: choose from {', '.join(VARIANTS)}")
    out = []
    for t in tasks:
        spec = TDSpec(task=t, seeds=args.seeds, seed=args.seed, generations=args.generations,
                      population=args.population, episodes=args.episodes, lanes=args.lanes, trials=args.trials,
                      alpha=args.alpha, gamma=args.gamma, epsilon=args.epsilon, encoder=args.encoder,
                      td_steps=args.td_steps)  # its ConfigError names the option (seeds=0: ...)
        variants = tuple(v for v in args.variants if t == "tracking" or v != "shaped")
        out.append((spec, variants))
    return out


def td_main(args: argparse.Namespace) -> int:
    """Run the pieces of the TD baseline not finished in ``--out`` (each GA run, each task's TD runs) on the
    replicate runner, then write the report and print the verdicts."""
    import os
    import platform

    from coevo.experiments.common import open_out, run_with_progress
    from coevo.experiments.earl.td.replicates import collect, replicates, timing
    from coevo.experiments.earl.td.report import summarise, write_report
    from coevo.rundir.layout import write_json

    specs = specs_from_args(args)
    check_backend_flags(args)
    out = Path(args.out)
    backend = open_out(args, out, "td-baseline.json",
                       {"tasks": [{"spec": s.as_dict(), "variants": list(v)} for s, v in specs]}, default_jobs=1)
    reps = replicates(specs)
    print(f"TD baseline in {out}: {len(reps)} runs ({', '.join(s.task for s, _ in specs)}), {backend.description}",
          flush=True)
    prog = run_with_progress(reps, out, backend, label="td", quiet=args.quiet)
    if prog is None:
        return 3
    results = collect(out, specs)
    if not results:
        print("no task finished: no report", file=sys.stderr)
        return 1
    data = write_report(out, results)
    write_json(out / "timing.json", {**timing(results), "cpus": os.cpu_count(), "python": platform.python_version(),
                                     "load_average_at_end": [round(x, 2) for x in os.getloadavg()]})
    for task, res in results.items():
        last = summarise(res)["rows"][-1]
        extra = "".join(f", TD {v} {last[f'td_{v}']['mean']:.1f}" for v in res.get("variants", {}))
        print(f"{task}: at {last['robot_steps']:,} robot-steps GA {last['ga']['mean']:.1f} %, TD "
              f"{last['td']['mean']:.1f} %{extra} ({last['verdict']}); GA {res['seconds']['ga']:.0f} s, "
              f"TD {res['seconds']['td'] + res['seconds']['variants']:.0f} s")
    for c in data["claims"]:
        print(f"  {c['verdict']}: {c['claim']}")
    print(f"report: {out / 'report.md'}")
    return 1 if prog.failed else 0
