"""The command that learns without the network: ``coevo learn``, for any task.

Gathered by :mod:`coevo.cli`; the work is :mod:`coevo.runs.learn`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from coevo.console import (
    ProgressBar,
    accept_task_flags,
    add_settings,
    count_arg,
    given_settings,
    positive_float_arg,
    seed_arg,
    task_arg,
    task_flags,
)
from coevo.errors import ConfigError
from coevo.runs.command import GA_FLAGS, refuse

__all__ = ["configure_learn"]


def _read_rules(path: str | None, behaviour: str) -> Any:
    if path is None:
        return None
    from coevo.policy.text import read_rule_file

    return read_rule_file(Path(path), behaviour)




def configure_learn(p: argparse.ArgumentParser) -> None:
    """``coevo learn``'s arguments."""
    p.add_argument("--behaviour", help="the behaviour to learn (optional for a task with one; coevo plugins lists the "
                   "tasks, and a task's behaviours are in its docs)")
    p.add_argument("--settings", metavar="RUN_JSON",
                   help="take the world, GA settings and the behaviour's seed from a run's settings (a run.json)")
    p.add_argument("--task", type=task_arg, help="the task (default: the behaviour's; door: --behaviour door)")
    p.add_argument("--seed", type=seed_arg, help="default 0")
    p.add_argument("--out", help="run directory to create (default runs/learn-BEHAVIOUR-seedN-TIME)")
    p.epilog = ("The task's own flags are taken too: --PARTNER FILE, a partner behaviour's rule file (the fuel task's "
                "Executive: --tracking t.rules --docking d.rules), and the task's names for world settings (the door "
                "task: --fail front,front_right, the same as --world failed=...).")
    p.add_argument("--seed-policy", help="start the population from this rule file instead of the behaviour's default (or random) rules")
    p.add_argument("--history", metavar="RUN_DIR", help="executive: adopt the Tracking/Docking policies stored in a finished run, in step")
    p.add_argument("--rate", type=positive_float_arg(maximum=1e6), default=1.0,
                   help="with --history: partner generations per executive generation (default 1)")
    p.add_argument("--measure-epochs", type=count_arg(1, 1_000_000), default=100, help="fresh epochs for the final measures")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_settings(p)
    accept_task_flags(p)
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
    partner_files, world_flags = task_flags(args, task)
    if args.behaviour in partner_files:  # task_flags takes only the task's behaviours: the learner's own is the one left
        raise ConfigError(f"--{args.behaviour}: {args.behaviour} learns with partners of its own task's other behaviours "
                          f"({', '.join(b for b in task.behaviours if b != args.behaviour) or 'none'})")
    if args.settings:  # a run's settings (coevo compare's offline Executive): world, GA and seed from there
        from coevo.rundir.settings import RunSettings

        refuse(args, (*GA_FLAGS, "seed"), "--settings gives the world, GA and seed")
        if world_flags:
            raise ConfigError(f"--settings gives the world; drop {', '.join('--' + f for f in task.flags)}")
        settings = RunSettings.load(Path(args.settings))
        if settings.task != task.name:
            raise ConfigError(f"--settings {args.settings!r} are for task {settings.task!r}, not {task.name!r}")
        world, ga, args.seed = settings.world_config(), settings.ga, settings.worker_seed(args.behaviour)
    else:
        world_values, ga_values = given_settings(args, task.name)
        world = build(task.world_settings, world_values)
        ga = build(GAConfig, ga_values)
        args.seed = 0 if args.seed is None else args.seed
    partners = {b: _read_rules(f, b) for b, f in partner_files.items()}
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
