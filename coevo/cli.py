"""The ``coevo`` command line: argument parsing, and a call per command.

Each command parses its arguments and calls the function that does the work, which
lives beside the thing it is about (``coevo.runs``, ``coevo.agents``, ``coevo.broker``,
``coevo.experiments``).  Every sub-command catches :class:`~coevo.errors.CoevoError`,
prints ``ErrorType: message`` to stderr and exits with status 2; a bad flag value is
refused by argparse with status 2 too; a bug still shows its traceback.  Logging
handlers are configured here and nowhere else.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

from coevo.config import build
from coevo.console import (
    ProgressBar,
    add_max_lead,
    max_lead_of,
    add_settings,
    count_arg,
    ga_settings,
    pairs,
    positive_float_arg,
    seed_arg,
    world_settings,
)
from coevo.rundir.settings import DEFAULT_MAX_LEAD
from coevo.errors import CoevoError, ConfigError
from coevo.policy.schema import registered

__all__ = ["main", "build_parser", "seed_arg"]

EXIT_ERROR = 2
MODELS = ("best", "current", "recent")


def _read_rules(path: str | None, behaviour: str) -> Any:
    if path is None:
        return None
    from coevo.policy.text import read_rule_file

    return read_rule_file(Path(path), behaviour)


GA_FLAGS = ("generations", "population", "episodes", "world", "ga")  # the settings flags of console.add_settings
RUN_FLAGS = ("task", "regime", "seed", "model", "max_lead", *GA_FLAGS)  # and a run's


def _refuse(args: argparse.Namespace, names: tuple[str, ...], why: str) -> None:
    """A ConfigError naming each of the flags ``names`` that was given, when ``why`` says they cannot be."""
    given = [f"--{n.replace('_', '-')}" for n in names if getattr(args, n, None) is not None]
    if given:
        raise ConfigError(f"{why}; drop {', '.join(given)}")


# ---------------------------------------------------------------- commands
def cmd_learn(args: argparse.Namespace) -> int:
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

        _refuse(args, (*GA_FLAGS, "fail", "seed"), "--settings gives the world, GA and seed")
        settings = RunSettings.load(Path(args.settings))
        if settings.task != task.name:
            raise ConfigError(f"--settings {args.settings!r} are for task {settings.task!r}, not {task.name!r}")
        world, ga, args.seed = settings.world_config(), settings.ga, settings.worker_seed(args.behaviour)
    else:
        world_values = pairs(args.world, "world")
        if args.fail is not None:
            world_values["failed"] = args.fail
        world = build(task.world_settings, world_values)
        ga = ga_settings(args)
        args.seed = 0 if args.seed is None else args.seed
    partners = {b: _read_rules(f, b) for b, f in (("tracking", args.tracking), ("docking", args.docking)) if f}
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


def cmd_bench(args: argparse.Namespace) -> int:
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


def cmd_router(args: argparse.Namespace) -> int:
    """A plain Zenoh router (no store): a second site's meeting point, joined to the broker with --connect."""
    from coevo.broker.server import serve_router

    return serve_router(args)


def cmd_broker(args: argparse.Namespace) -> int:
    from coevo.broker.server import serve_broker
    from coevo.broker.store import Quota

    return serve_broker(args, data_dir=Path(args.data_dir), inbox_bytes=int(args.inbox_mb * (1 << 20)), open_runs=args.open,
                        quota=Quota(runs=args.quota_runs, policies=args.quota_policies, bytes=int(args.quota_mb * (1 << 20))))


def cmd_worker(args: argparse.Namespace) -> int:
    from coevo.agents.worker import Worker, run_worker
    from coevo.bus.session import config_from_args
    from coevo.rundir.layout import RunPaths
    from coevo.rundir.settings import RunSettings, find_run_key

    if args.settings:
        _refuse(args, ("task", "regime", "run", "model", "max_lead", *GA_FLAGS), "--settings gives every run setting")
        settings = RunSettings.load(Path(args.settings))
        base: Path | None = Path(args.settings).parent
    else:
        base = None
        if args.run is None or args.regime is None:
            raise ConfigError("give --settings RUN/run.json (a run's settings), or --run and --regime")
        task = args.task or "fuel"
        settings = RunSettings.make(run=args.run, task=task, regime=args.regime, seed=args.seed or 0,
                                    model=args.model or "best", max_lead=max_lead_of(args.max_lead, DEFAULT_MAX_LEAD),
                                    world=world_settings(args, task), ga=ga_settings(args))
    kind = None
    if settings.cel is not None:  # a CEL run's learner (coevo cel) plugs into the worker's seam
        from coevo.cel_service.learner import CelLearner

        kind = CelLearner
    return run_worker(settings, kind=kind or Worker, behaviour=args.behaviour, seed=args.seed, worker_id=args.worker_id,
                      out=Path(args.out) if args.out else (RunPaths(base).worker(args.behaviour).dir if base else None),
                      conf=config_from_args(args), resume=args.resume,
                      final_sync=args.final_sync, run_key=find_run_key(args.key_file, settings, base))


def cmd_run(args: argparse.Namespace) -> int:
    from coevo.bus.status import StatusDisplay
    from coevo.runs.local import LocalRun, default_run_id, run_local
    from coevo.rundir.settings import RunSettings

    if args.resume:
        _refuse(args, (*RUN_FLAGS, "run", "settings"), "--resume takes every setting from the run's run.json")
        lr = LocalRun.resume(Path(args.resume), log_level=args.log_level)
        if lr.settings.cel is not None:
            raise ConfigError(f"{args.resume} is a CEL run: continue it with coevo cel --resume {args.resume}")
    else:
        if args.settings:
            _refuse(args, RUN_FLAGS, "--settings gives every run setting but the run id")
            settings = RunSettings.load(Path(args.settings)).fresh(args.run)  # a new run: its own endpoint and key
        else:
            task = args.task or "fuel"
            regime = args.regime or "independent"
            settings = RunSettings.make(run=args.run or default_run_id(regime), task=task, regime=regime,
                                        seed=args.seed or 0, model=args.model or "best",
                                        max_lead=max_lead_of(args.max_lead, DEFAULT_MAX_LEAD),
                                        world=world_settings(args, task), ga=ga_settings(args))
        if settings.cel is not None:
            raise ConfigError(f"{args.settings} is a CEL run's settings: start it with coevo cel (its execution module "
                              "is not a worker)")
        lr = LocalRun(settings, root=Path(args.root), log_level=args.log_level, open_run=args.open)
        lr.create()
    title = f"run {lr.run} ({lr.settings.regime})" + (" OPEN: messages unauthenticated" if lr.open else "")
    with StatusDisplay(title, quiet=args.quiet) as display:
        summary = run_local(lr, resume=bool(args.resume), measure_epochs=args.measure_epochs, on_status=display.show)
    print(f"run directory: {lr.dir} ({summary['seconds']:.1f} s)")
    if "measures" in summary:
        m = summary["measures"]
        print("final policies together: " + ", ".join(f"{k} {v:.1f}" for k, v in m.items()
                                                     if isinstance(v, float) and k not in ("tracking_payoff", "docking_payoff")))
    if summary["interrupted"]:
        early = ", ".join(f"{b} after {g}" for b, g in summary.get("stopped_early", {}).items())
        print(f"the run stopped early{' (' + early + ' generations)' if early else ''}; continue it with "
              f"coevo run --resume {lr.dir}", file=sys.stderr)
        return 130 if summary.get("stopped_here") else 1
    return 0


def cmd_status(args: argparse.Namespace) -> int:
    from coevo.bus import keys
    from coevo.bus.auth import RunKey
    from coevo.bus.session import config_from_args
    from coevo.bus.status import StatusDisplay, follow
    from coevo.bus.trust import Gate

    keys.check_id("run id", args.run)
    gate = None
    if args.key_file:
        gate = Gate(key=RunKey.load(Path(args.key_file), run=args.run))
    title = f"run {args.run} at {{time}}" + ("" if gate else " (unverified: no --key-file)")
    with StatusDisplay(title, json_lines=args.json) as display:
        follow(config_from_args(args), args.run, display.show, every=args.every, stall=args.stall, duration=args.duration,
               gate=gate)
    return 0


def cmd_keygen(args: argparse.Namespace) -> int:
    from coevo.bus import keys
    from coevo.bus.auth import RunKey

    RunKey.create(keys.check_id("run id", args.run)).save(Path(args.out))
    print(f"run {args.run}'s key written to {args.out} (mode 0600); copy it to each host of the run, see deploy/README.md")
    return 0


def cmd_chaos(args: argparse.Namespace) -> int:
    from coevo.runs.chaos import CHAOS_REPORT, ChaosPlan, run_chaos, summary_lines
    from coevo.runs.local import default_run_id
    from coevo.rundir.settings import RunSettings

    plan = ChaosPlan(faults=args.faults, kinds=tuple(args.kinds), gap=tuple(args.gap), down=tuple(args.down), seed=args.seed)
    task = args.task or ("door" if args.cel else "fuel")
    regime = args.regime or ("independent" if task == "door" else "mutual")
    ga = ga_settings(args)
    cel = None
    if args.cel:  # a CEL run: the Figure 3 failure halfway through, the learner in lockstep with the robot
        if task != "door":
            raise ConfigError(f"--cel is a door-task run; drop --task {task}")
        from coevo.cel.settings import FIGURE3_SCHEDULE

        cel = {"schedule": [[ga.generations // 2, list(FIGURE3_SCHEDULE[0][1])]]}
    settings = RunSettings.make(run=args.run or default_run_id(f"chaos-{'cel' if cel else regime}"), task=task,
                                regime=regime, seed=args.seed, model=args.model, world=world_settings(args, task), ga=ga, cel=cel,
                                **({"max_lead": 0} if cel else {}))

    def say(text: str) -> None:
        if not args.quiet:
            print(f"{time.strftime('%H:%M:%S')} {text}", flush=True)

    report = run_chaos(settings, root=Path(args.root), plan=plan, measure_epochs=args.measure_epochs, on_event=say,
                       log_level=args.log_level)
    for line in summary_lines(report):
        print(line)
    print(f"report: {settings.paths(Path(args.root)).dir / CHAOS_REPORT}")
    return 0 if report["complete"] else 1


def cmd_check(args: argparse.Namespace) -> int:
    from coevo.runs.check import check_run

    res = check_run(Path(args.run_dir), replay=not args.no_replay)
    for beh, facts in sorted((k, v) for k, v in res.facts.items() if isinstance(v, dict) and "published" in v):
        print(f"{beh}: {facts['generations']} generations, {facts['published']} versions published, "
              f"{facts['adoptions']} adoptions")
    ex = res.facts.get("execution")
    if ex:
        print(f"execution: {ex['generations']} generations of trials, {ex['policies_used']} rule sets used, "
              f"{ex['changes']} capability changes")
    if res.ok:
        print("complete" + (" (replay exact)" if res.facts.get("replayed") else ""))
        return 0
    for p in res.problems:
        print(f"PROBLEM: {p}")
    return 1


def cmd_replay(args: argparse.Namespace) -> int:
    from coevo.runs.replay import replay

    ok = True
    for r in replay(Path(args.run_dir)):
        ok &= r.reproduced
        verdict = "reproduced exactly" if r.reproduced else f"DIFFERS at generation {r.first_mismatch}: {r.detail}"
        print(f"{r.behaviour}: {r.generations} generations {verdict}")
    return 0 if ok else 1


# ---------------------------------------------------------------- the parser
class _Parser(argparse.ArgumentParser):
    """argparse, but a bad flag or value is one line ``ConfigError: ...`` naming it (status 2), like every other
    bad input, instead of the usage followed by the error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_ERROR, f"ConfigError: {self.prog}: {message} (see {self.prog} --help)\n")


def _add_run_settings(p: argparse.ArgumentParser, *, defaults_note: bool = True) -> None:
    from coevo.tasks import TASKS

    p.add_argument("--task", choices=list(TASKS), help="the task (default fuel)")
    p.add_argument("--seed", type=seed_arg, help="default 0" + ("; worker i of the task's behaviours uses seed + i" if defaults_note else ""))
    p.add_argument("--model", choices=MODELS, help="how partners are modelled (default best so far)")
    add_max_lead(p)
    add_settings(p)


def build_parser() -> argparse.ArgumentParser:
    from coevo.bus.session import add_connection_args

    parser = _Parser(prog="coevo", description="Co-evolve robot behaviours with SAMUEL-style rule GAs.")
    parser.add_argument("--log-level", default="WARNING", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    behaviours = list(registered())

    from coevo.tasks import TASKS

    p = sub.add_parser("learn", help="one behaviour learns offline (no network)")
    p.add_argument("--behaviour", choices=behaviours, help="the behaviour to learn (optional for a task with one)")
    p.add_argument("--settings", metavar="RUN_JSON",
                   help="take the world, GA settings and the behaviour's seed from a run's settings (a run.json)")
    p.add_argument("--task", choices=list(TASKS), help="the task (default: the behaviour's; door: --behaviour door)")
    p.add_argument("--fail", metavar="SONARS",
                   help="door task: sonars that fail, e.g. front,front-right,right (the same as --world failed=...)")
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

    p = sub.add_parser("bench", help="robot-steps/s of the batched world vs a plain one-episode pymunk loop")
    p.add_argument("--behaviour", default="tracking", choices=["tracking", "docking"])
    p.add_argument("--lanes", type=count_arg(1, 10_000_000), default=4500, help="episodes run at once (default 50 x 90)")
    p.add_argument("--rules", type=count_arg(1, 64), default=32, help="rules per policy (evolved size)")
    p.add_argument("--policy", help="a rule file to drive every lane instead of random rule sets")
    p.add_argument("--repeats", type=count_arg(1, 1000), default=3)
    p.add_argument("--baseline-seconds", type=positive_float_arg(maximum=3600), default=3.0)
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--world", action="append", metavar="NAME=VALUE")
    p.add_argument("--json", action="store_true", help="print both figures and their ratio as JSON")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("broker", help="the Zenoh router workers meet at, plus the policy store")
    add_connection_args(p, default_mode="router")
    p.add_argument("--data-dir", default="runs", help="where the store keeps each run's policies (default runs/)")
    p.add_argument("--inbox-mb", type=positive_float_arg(maximum=65536), default=64.0,
                   help="policy messages waiting to be stored at most (default 64 MB); a flood beyond is dropped and counted")
    p.add_argument("--open", action="store_true",
                   help="also store runs it holds no key for (DATA_DIR/RUN/secret.key), unauthenticated; "
                        "default: refuse them and count 'unauthenticated'")
    p.add_argument("--quota-runs", type=count_arg(1, 1_000_000), default=32,
                   help="runs the store takes policies for since the broker started (default 32); beyond: refused, counted as quota")
    p.add_argument("--quota-policies", type=count_arg(1, 10**9), default=10_000,
                   help="policies stored per run at most (default 10000; the report's parameters publish at most 150)")
    p.add_argument("--quota-mb", type=positive_float_arg(maximum=1 << 20), default=64.0,
                   help="bytes on disk per run at most, in MB (default 64: 10000 of the largest policies)")
    p.set_defaults(func=cmd_broker)

    p = sub.add_parser("router", help="a plain Zenoh router, no store: another site's meeting point (--connect to the broker)")
    add_connection_args(p, default_mode="router")
    p.set_defaults(func=cmd_router)

    p = sub.add_parser("worker", help="one behaviour's GA as its own process on the bus")
    p.add_argument("--settings", metavar="RUN_JSON", help="the run's settings (its run.json; what coevo run starts workers with)")
    p.add_argument("--behaviour", required=True, choices=behaviours)
    p.add_argument("--regime", help="without --settings: mutual or independent (the task's regimes)")
    p.add_argument("--run", help="without --settings: run id (letters, digits, _ - .)")
    p.add_argument("--worker-id", help="default BEHAVIOUR-SEED")
    p.add_argument("--out", help="worker directory (default: workers/BEHAVIOUR beside --settings' run.json, else "
                                 "runs/RUN/workers/BEHAVIOUR)")
    p.add_argument("--resume", action="store_true",
                   help="continue from the checkpoint in --out (or start afresh if there is none yet)")
    p.add_argument("--final-sync", type=positive_float_arg(allow_zero=True, maximum=86400), default=30.0, metavar="SECONDS",
                   help="at the end, wait this long for the broker's store to hold every published version (default 30)")
    p.add_argument("--key-file", metavar="FILE",
                   help="the run's secret key (default: $COEVO_RUN_KEY_FILE, else the key_file run.json names); "
                        "without one the worker is open: it sends and accepts unauthenticated messages")
    _add_run_settings(p, defaults_note=False)
    add_connection_args(p)
    p.set_defaults(func=cmd_worker)

    p = sub.add_parser("run", help="broker + one worker per behaviour on this machine, with a live status")
    p.add_argument("--regime", help="mutual or independent (default independent)")
    p.add_argument("--run", help="run id (default REGIME-TIME)")
    p.add_argument("--root", default="runs", help="parent of the run directory (default runs/)")
    p.add_argument("--resume", metavar="RUN_DIR", help="continue this run from its workers' checkpoints, with its settings")
    p.add_argument("--settings", metavar="RUN_JSON", help="start a run with these settings (a run.json, e.g. one coevo compare wrote)")
    p.add_argument("--measure-epochs", type=count_arg(1, 1_000_000), default=100)
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--open", action="store_true",
                   help="make no key: the run's messages are unauthenticated (local experiments only)")
    _add_run_settings(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("keygen", help="make a run's secret key file (mode 0600), for a run spread over hosts by hand")
    p.add_argument("--run", required=True, help="the run id the key is for")
    p.add_argument("--out", required=True, metavar="FILE", help="the key file to create (never overwritten)")
    p.set_defaults(func=cmd_keygen)

    from coevo.experiments.compare.command import add_parser as add_compare
    from coevo.experiments.earl.command import add_parser as add_earl
    from coevo.experiments.evolvability.command import add_parser as add_evolvability
    from coevo.show.command import add_parser as add_show

    from coevo.runs.cel_command import add_parsers as add_cel

    add_compare(sub)
    add_cel(sub)
    add_evolvability(sub)
    add_earl(sub)
    from coevo.experiments.earl.td_command import add_td_arguments, td_main

    p = sub.add_parser("td-baseline", help="Appendix C: Q-learning against the GA on the robot tasks, at equal experience")
    add_td_arguments(p)
    p.set_defaults(func=td_main)
    add_show(sub)

    p = sub.add_parser("replay", help="re-run a finished run in one process from its adoption log")
    p.add_argument("run_dir")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("chaos", help="a whole run while random processes are killed and restarted; then check it")
    p.add_argument("--regime", help="mutual or independent (default mutual; the door task's: independent)")
    p.add_argument("--run", help="run id (default chaos-REGIME-TIME)")
    p.add_argument("--cel", action="store_true",
                   help="a CEL run (coevo cel, door task): its execution module is killed and paused too; front, "
                        "front-right and right fail halfway")
    p.add_argument("--root", default="runs", help="parent of the run directory (default runs/)")
    p.add_argument("--task", help="the task (default fuel)")
    p.add_argument("--seed", type=seed_arg, default=0, help="seeds the workers and the choice of faults")
    p.add_argument("--model", default="best", choices=MODELS)
    p.add_argument("--faults", type=count_arg(0, 10_000), default=8, help="faults to inject (default 8)")
    p.add_argument("--kinds", nargs="+", default=["kill-worker", "kill-broker", "pause-worker"], metavar="KIND",
                   help="kill-worker kill-broker pause-worker (default all three)")
    p.add_argument("--gap", type=positive_float_arg(allow_zero=True, maximum=3600), nargs=2, default=[1.0, 4.0],
                   metavar=("MIN", "MAX"), help="seconds between faults (default 1 4)")
    p.add_argument("--down", type=positive_float_arg(allow_zero=True, maximum=3600), nargs=2, default=[0.5, 3.0],
                   metavar=("MIN", "MAX"), help="seconds a killed process stays down or a paused one stopped (default 0.5 3)")
    p.add_argument("--measure-epochs", type=count_arg(1, 1_000_000), default=20)
    p.add_argument("--quiet", action="store_true")
    add_settings(p)
    p.set_defaults(func=cmd_chaos)

    p = sub.add_parser("check", help="is a finished run directory complete? (every generation, every version stored, replay)")
    p.add_argument("run_dir")
    p.add_argument("--no-replay", action="store_true", help="skip re-running the GAs")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("status", help="follow a run's workers")
    p.add_argument("--run", required=True)
    p.add_argument("--json", action="store_true", help="one JSON object per update")
    p.add_argument("--stall", type=positive_float_arg(maximum=86400), default=3.0,
                   help="seconds without a heartbeat before a live worker counts as stalled (default 3; workers beat every second)")
    p.add_argument("--every", type=positive_float_arg(maximum=3600), default=0.5,
                   help="refresh period in seconds (default 0.5; changes show at once)")
    p.add_argument("--duration", type=positive_float_arg(maximum=1e7), help="stop after this many seconds (default: until Ctrl-C)")
    p.add_argument("--key-file", metavar="FILE", help="the run's key: show only authenticated heartbeats (default: unverified)")
    add_connection_args(p)
    p.set_defaults(func=cmd_status)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        return int(args.func(args))
    except CoevoError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
