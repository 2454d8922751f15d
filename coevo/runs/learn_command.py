"""The commands that learn or measure without the network: ``coevo learn`` and ``coevo bench``.

Gathered by :mod:`coevo.cli`; the work is :mod:`coevo.runs.learn` and :mod:`coevo.tasks.fuel.bench`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from coevo.console import (
    SONARS_HELP,
    ProgressBar,
    add_settings,
    count_arg,
    given_settings,
    pairs,
    positive_float_arg,
    seed_arg,
    sonars_arg,
)
from coevo.errors import ConfigError
from coevo.runs.command import GA_FLAGS, behaviour_names, refuse, task_names

__all__ = ["configure_learn", "configure_bench"]


def _read_rules(path: str | None, behaviour: str) -> Any:
    if path is None:
        return None
    from coevo.policy.text import read_rule_file

    return read_rule_file(Path(path), behaviour)




def configure_learn(p: argparse.ArgumentParser) -> None:
    """``coevo learn``'s arguments."""
    p.add_argument("--behaviour", choices=behaviour_names(), help="the behaviour to learn (optional for a task with one)")
    p.add_argument("--settings", metavar="RUN_JSON",
                   help="take the world, GA settings and the behaviour's seed from a run's settings (a run.json)")
    p.add_argument("--task", choices=task_names(), help="the task (default: the behaviour's; door: --behaviour door)")
    p.add_argument("--fail", metavar="SONARS", type=sonars_arg,
                   help=f"door task: sonars that fail, {SONARS_HELP} (the same as --world failed=...)")
    p.add_argument("--seed", type=seed_arg, help="default 0")
    p.add_argument("--out", help="run directory to create (default runs/learn-BEHAVIOUR-seedN-TIME)")
    p.add_argument("--tracking", help="Tracking rule file (for --behaviour executive)")
    p.add_argument("--docking", help="Docking rule file (for --behaviour executive)")
    p.add_argument("--seed-policy", help="start the population from this rule file instead of the behaviour's default (or random) rules")
    p.add_argument("--history", metavar="RUN_DIR", help="executive: adopt the Tracking/Docking policies stored in a finished run, in step")
    p.add_argument("--rate", type=positive_float_arg(maximum=1e6), default=1.0,
                   help="with --history: partner generations per executive generation (default 1)")
    p.add_argument("--measure-epochs", type=count_arg(1, 1_000_000), default=100, help="fresh epochs for the final measures")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_settings(p)
    p.set_defaults(func=cmd_learn)


def cmd_learn(args: argparse.Namespace) -> int:
    from coevo.config import GAConfig, build
    from coevo.runs.learn import default_out, learn
    from coevo.tasks import get_task, task_of

    if args.behaviour is None:
        if args.task is None or len(get_task(args.task).behaviours) != 1:
            raise ConfigError("give --behaviour" + (f" (task {args.task!r} has {', '.join(get_task(args.task).behaviours)})"
                                                    if args.task else ""))
        args.behaviour = get_task(args.task).behaviours[0]
    task = task_of(args.behaviour)
    if args.task is not None and args.task != task.name:
        raise ConfigError(f"--behaviour {args.behaviour} belongs to task {task.name!r}, not {args.task!r}")
    if args.settings:  # a run's settings (coevo compare's offline Executive): world, GA and seed from there
        from coevo.rundir.settings import RunSettings

        refuse(args, (*GA_FLAGS, "fail", "seed"), "--settings gives the world, GA and seed")
        settings = RunSettings.load(Path(args.settings))
        if settings.task != task.name:
            raise ConfigError(f"--settings {args.settings!r} are for task {settings.task!r}, not {task.name!r}")
        world, ga, args.seed = settings.world_config(), settings.ga, settings.worker_seed(args.behaviour)
    else:
        world_values, ga_values = given_settings(args, task.name)
        if args.fail is not None:
            world_values["failed"] = args.fail
        world = build(task.world_settings, world_values)
        ga = build(GAConfig, ga_values)
        args.seed = 0 if args.seed is None else args.seed
    partners = {b: _read_rules(f, b) for b, f in (("tracking", args.tracking), ("docking", args.docking)) if f}
    if args.out is not None and not args.out.strip():
        raise ConfigError(f"--out {args.out!r} is empty: give the run directory to create (or leave --out out)")
    out = Path(args.out) if args.out else default_out(args.behaviour, args.seed)

    def info(r: Any) -> str:
        own = "".join(f" {k} {v:.0f}%" for k, v in task.status_measures(args.behaviour, r.measures).items())
        return f"best {r.best_fitness:.3f} (so far {r.best_so_far:.3f}){own}"

    with ProgressBar(args.behaviour, total=ga.generations, unit="gen", quiet=args.quiet) as bar:
        res = learn(
            args.behaviour, world=world, ga=ga, seed=args.seed, out_dir=out, partners=partners,
            seed_policy=_read_rules(args.seed_policy, args.behaviour), measure_epochs=args.measure_epochs,
            on_generation=lambda r: bar.update(r.generation, info=info(r)),
            history=Path(args.history) if args.history else None, rate=args.rate,
        )
    m = res.measures
    print(f"run directory: {res.out_dir}")
    print(f"time: {res.seconds:.1f} s; best fitness {m['best_fitness']:.3f}")
    print("measures: " + ", ".join(f"{k} {v:.1f}" for k, v in m.items()
                                   if k not in ("best_fitness", "episodes", "epochs") and isinstance(v, float)))
    return 0


def configure_bench(p: argparse.ArgumentParser) -> None:
    """``coevo bench``'s arguments."""
    p.add_argument("--behaviour", default="tracking", choices=["tracking", "docking"])
    p.add_argument("--lanes", type=count_arg(1, 100_000), default=4500, help="episodes run at once (default 50 x 90)")
    p.add_argument("--rules", type=count_arg(1, 64), default=32, help="rules per policy (evolved size)")
    p.add_argument("--policy", help="a rule file to drive every lane instead of random rule sets")
    p.add_argument("--repeats", type=count_arg(1, 1000), default=3)
    p.add_argument("--baseline-seconds", type=positive_float_arg(maximum=3600), default=3.0)
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--world", action="append", metavar="NAME=VALUE")
    p.add_argument("--json", action="store_true", help="print both figures and their ratio as JSON")
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    from coevo.config import build
    from coevo.tasks.fuel.bench import bench
    from coevo.tasks.fuel.settings import WorldConfig

    world = build(WorldConfig, pairs(args.world, "world"))
    res = bench(world=world, behaviour=args.behaviour, lanes=args.lanes, rules=args.rules, repeats=args.repeats,
                baseline_seconds=args.baseline_seconds, seed=args.seed, policy=_read_rules(args.policy, args.behaviour))
    if args.json:
        print(json.dumps(res.as_dict(), indent=2))
    else:
        print(f"batched ({res.lanes} lanes, {res.rules_per_policy} rules): {res.batched_steps_per_s / 1e6:.3f} M robot-steps/s")
        print(f"plain one-episode loop:                {res.baseline_steps_per_s / 1e6:.3f} M robot-steps/s")
        print(f"ratio {res.ratio:.1f}x; batch peak {res.batch_peak_mb:.0f} MB (tracemalloc), process max RSS {res.max_rss_mb:.0f} MB")
    return 0
