"""``coevo seeds``: learning over seeds against a target, with a report (registered by :mod:`coevo.cli`).

``--task fuel`` (the default task, :data:`coevo.tasks.DEFAULT_TASK`): Tracking and Docking learned offline against
the learning targets (:mod:`.experiment`);
``--task door``: Appendix B's door traversal, all sonars then three failed, beside Figure 3's numbers
(:mod:`.door`, :mod:`.door_report`).  Both run their seeds through :mod:`coevo.replicates`.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from coevo.console import ProgressBar, count_arg, seed_arg
from coevo.errors import ConfigError, RunDirError
from coevo.replicates.flags import add_backend_flags, backend_of, check_backend_flags

__all__ = ["configure_seeds", "cmd_seeds"]

#: Seeds per behaviour by default: the learning targets' 5; the door experiment's 10 (Figure 3's runs).
DEFAULT_SEEDS = {"fuel": 5, "door": 10}
FUEL_FLAGS = ("behaviours", "learn_args")
DOOR_FLAGS = ("fail",)


def _refuse(args: argparse.Namespace, names: tuple[str, ...], task: str) -> None:
    """A ConfigError naming the flags of the other task that were given."""
    flag = {"learn_args": "learn-arg"}
    given = [f"--{flag.get(n, n.replace('_', '-'))}" for n in names if getattr(args, n) is not None]
    if given:
        raise ConfigError(f"{', '.join(given)}: not a setting of --task {task}")


def cmd_seeds(args: argparse.Namespace) -> int:
    check_backend_flags(args)  # before anything is written into --out
    if args.task == "door":
        _refuse(args, FUEL_FLAGS, "door")
        return _cmd_door(args)
    _refuse(args, DOOR_FLAGS, args.task)
    from coevo.experiments.seeds.experiment import problems, replicates, write_report
    from coevo.replicates.backends import ClusterLost
    from coevo.replicates.runner import run_replicates

    extra, ga = _fuel_settings(args, args.task)  # checked before anything is written
    extra += list(args.learn_args or [])
    out = Path(args.out) if args.out else Path("runs") / f"seeds-{time.strftime('%Y%m%d-%H%M%S')}"
    from coevo.rundir.layout import ensure_dir

    behaviours = args.behaviours or ["docking", "tracking"]
    seeds = list(range(args.first_seed, args.first_seed + (args.seeds or DEFAULT_SEEDS[args.task])))
    if out.is_dir() and any(out.iterdir()):
        if not args.resume:
            raise RunDirError(f"--out {str(out)!r} is not empty; add --resume to continue the runs there")
        found = problems(out, behaviours, seeds)  # before anything is changed
        if found:
            raise RunDirError(f"cannot resume the runs in {out}: {found[0]}; nothing was started or changed")
    ensure_dir(out, what="--out")
    reps = replicates(behaviours, seeds, extra, weight=2)  # --jobs counts learners here: one core each
    backend = backend_of(args, default_jobs=1)
    print(f"learning over seeds in {out}: {len(reps)} runs, {backend.description}", flush=True)
    t0 = time.time()
    with ProgressBar("seeds", total=len(reps), unit="runs", quiet=args.quiet) as bar:
        try:
            prog = run_replicates(reps, out, backend, on_progress=lambda p: bar.update(
                p.runs_done, p.runs_total, f"{len(p.failed)} failed" if p.failed else ""))  # the bar counts the runs
        except ClusterLost as exc:
            print(f"{exc}; finished runs are kept: continue with the same command and --resume --out {out}",
                  file=sys.stderr)
            return 3
    for name, why in prog.failed.items():
        print(f"  {name} failed: {why} (log: {out / 'logs' / (name + '.log')})", file=sys.stderr)
    from coevo.experiments.common import below_report

    caveat = below_report({"generations": ga.generations, "population": ga.population, "episodes": ga.episodes})
    results = write_report(out, behaviours, seeds, elapsed=time.time() - t0, caveat=caveat)
    print(f"report: {out / 'report.md'}")
    for v in results["verdicts"]:
        print(v["text"])
    if caveat:
        print(caveat)
    return 1 if prog.failed else 0


def _fuel_settings(args: argparse.Namespace, name: str) -> tuple[list[str], Any]:
    """``--generations``, ``--world`` and ``--ga`` as ``coevo learn`` arguments, and the GA settings they make, checked
    first against the task ``name`` (a bad one is a ConfigError naming it, before anything runs)."""
    from coevo.config import GAConfig, build
    from coevo.console import pairs
    from coevo.tasks import get_task, split_settings
    from coevo.tasks.base import check_ga

    task = get_task(name)
    world, ga = split_settings(task, pairs(args.world, "world"), pairs(args.ga, "ga"))
    build(task.world_settings, world)
    config = build(GAConfig, {**ga, **({} if args.generations is None else {"generations": args.generations})})
    check_ga(task, config)
    out = [] if args.generations is None else [f"--generations={args.generations}"]
    return out + [f"--world={k}={v}" for k, v in world.items()] + [f"--ga={k}={v}" for k, v in ga.items()], config


def _door_spec(args: argparse.Namespace) -> dict[str, Any]:
    """The door experiment's settings, checked before anything runs (a bad one is a ConfigError naming it)."""
    from coevo.config import build
    from coevo.console import pairs
    from coevo.tasks.door import DoorConfig, door_ga

    world = pairs(args.world, "world")
    ga = pairs(args.ga, "ga")
    fail = "front,front_right,right" if args.fail is None else args.fail
    failed = [s.strip() for s in fail.split(",") if s.strip()]
    intact = build(DoorConfig, world)
    blind = build(DoorConfig, {**world, "failed": failed})
    if not blind.failed:
        raise ConfigError(f"--fail {args.fail!r}: name at least one sonar")
    door_ga(**ga)
    return {"task": "door", "seeds": args.seeds or DEFAULT_SEEDS["door"], "first_seed": args.first_seed,
            "generations": 50 if args.generations is None else args.generations, "failed": list(blind.failed),
            "world": intact.model_dump(mode="json"), "ga": ga}


def _cmd_door(args: argparse.Namespace) -> int:
    from coevo.experiments.common import open_out, run_with_progress
    from coevo.experiments.seeds.door import replicates
    from coevo.experiments.seeds.door_report import write_report

    spec = _door_spec(args)
    out = Path(args.out) if args.out else Path("runs") / f"door-seeds-{time.strftime('%Y%m%d-%H%M%S')}"
    backend = open_out(args, out, "door-seeds.json", spec, default_jobs=1)
    seeds = list(range(spec["first_seed"], spec["first_seed"] + spec["seeds"]))
    reps = replicates(seeds, generations=spec["generations"], world=spec["world"], failed=spec["failed"], ga=spec["ga"])
    print(f"the door task over seeds in {out}: {len(reps)} seeds, {backend.description}", flush=True)
    t0 = time.time()
    prog = run_with_progress(reps, out, backend, label="door seeds", quiet=args.quiet)
    if prog is None:
        return 3
    data = write_report(out, seeds, spec, elapsed=time.time() - t0)
    if data["runs_finished"]:
        from coevo.experiments.seeds.door_report import KEYS, REPORT

        m, sd = data["mean_success_1000_trials"], data["sd_over_seeds"]
        for k in KEYS:
            print(f"  {k:10s} {m[k]:5.1f} ± {sd[k]:4.1f} %   (report {'over ' if k == 'adapted' else ''}{REPORT[k]:.0f} %)")
    print(f"report: {out / 'report.md'}")
    return 1 if prog.failed else 0


def configure_seeds(p: argparse.ArgumentParser) -> None:
    """``coevo seeds``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    from coevo.tasks import DEFAULT_TASK
    from coevo.tasks.door.flags import SONARS_HELP, sonars_arg  # the door task is one of the two it runs

    p.add_argument("--task", choices=["fuel", "door"], default=DEFAULT_TASK,
                   help="fuel: Tracking and Docking against the learning targets (default); door: Appendix B's door "
                        "traversal, all sonars then --fail, beside Figure 3's numbers")
    p.add_argument("--seeds", type=count_arg(1, 10_000), help="seeds per behaviour (default 5; --task door: 10)")
    p.add_argument("--first-seed", type=seed_arg, default=0, help="the first of the seeds (default 0)")
    p.add_argument("--out", help="output directory (default runs/seeds-TIME, runs/door-seeds-TIME)")
    p.add_argument("--resume", action="store_true", help="keep the finished runs in --out and run the rest")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    fuel = p.add_argument_group("--task fuel")
    fuel.add_argument("--behaviours", nargs="+", choices=["docking", "tracking"], help="default: docking tracking")
    fuel.add_argument("--learn-arg", dest="learn_args", action="append", metavar="ARG",
                      help="an argument passed on to every coevo learn (repeatable), e.g. --learn-arg=--generations=5")
    p.add_argument("--generations", type=count_arg(1, 100_000),
                   help="generations (default 50; --task door: with all sonars, and again after the failure)")
    p.add_argument("--world", action="append", metavar="NAME=VALUE",
                   help="a world setting, e.g. target_speed=3 (door: for both phases, e.g. sonar_noise=12; repeatable)")
    p.add_argument("--ga", action="append", metavar="NAME=VALUE",
                   help="a GA setting, e.g. specialise_fraction=0.1 (repeatable)")
    door = p.add_argument_group("--task door")
    door.add_argument("--fail", metavar="SONAR,SONAR", type=sonars_arg,
                      help=f"the sonars that fail (default front,front_right,right), {SONARS_HELP}")
    add_backend_flags(p, jobs_help="runs at once on this machine (default 1: the timing target is per core)")
    p.set_defaults(func=cmd_seeds)
