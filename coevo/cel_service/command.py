"""``coevo cel`` (a live CEL run on this machine) and ``coevo execution`` (its execution module process).

Registered by :mod:`coevo.cli`; the run is :mod:`coevo.cel_service.run`, the processes
:mod:`coevo.cel_service.learner` and :mod:`coevo.cel_service.robot`.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path
from typing import Any

from coevo.console import add_max_lead, add_settings, count_arg, given_settings, max_lead_of, seed_arg
from coevo.errors import ConfigError

__all__ = ["configure_cel", "configure_execution", "cmd_cel", "cmd_execution", "SCHEDULES"]

#: Named failure schedules: (generation, failed sonars) events (docs/cel.md).
SCHEDULES: dict[str, tuple[tuple[int, tuple[str, ...]], ...]] = {
    "figure3": ((50, ("front", "front_right", "right")),),
    "cyclic": ((25, ("front", "front_right", "right")), (50, ()), (75, ("front", "front_right", "right"))),
    "none": (),
}


#: The learner's lead over the robot (ours): 0, the lockstep order, so that a live run is the lockstep run of its seed
#: (docs/cel.md, "The clock"); it costs the learner ~50 ms of waiting a generation (measured, docs/cel.md).
CEL_MAX_LEAD = 0
#: Figure 3's run: 100 generations, the failure at 50.
CEL_GENERATIONS = 100


def fail_arg(text: str) -> tuple[int, tuple[str, ...]]:
    """``GEN:SONAR,SONAR`` (``GEN:`` repairs every sonar) -> an event of the failure schedule."""
    gen, sep, names = text.partition(":")
    try:
        g = int(gen)
    except ValueError:
        g = -1
    if not sep or g < 0:
        raise argparse.ArgumentTypeError(f"invalid failure {text!r}: give GENERATION:SONAR,SONAR (e.g. "
                                         "50:front,front_right,right; 75: repairs them)")
    from coevo.tasks.door.flags import sonars_arg

    return g, tuple(n for n in sonars_arg(names).split(",") if n)


def _settings(args: argparse.Namespace) -> Any:
    from coevo.cel.settings import CelSettings
    from coevo.config import build
    from coevo.runs.local import default_run_id
    from coevo.rundir.settings import RunSettings

    if args.fail and args.schedule:
        raise ConfigError("give --schedule or --fail events, not both")
    schedule = tuple(args.fail) if args.fail else SCHEDULES[args.schedule or "figure3"]
    given = {k: getattr(args, k) for k in ("trials_per_generation", "chunk", "zero_run", "repair_run")
             if getattr(args, k) is not None}
    given.setdefault("chunk", given.get("trials_per_generation", CelSettings().trials_per_generation))  # a generation's trials at once
    cel = build(CelSettings, {"schedule": schedule, "case_base": args.case_base or bool(args.cases_from), **given})
    world, ga = given_settings(args, "door")
    ga.setdefault("generations", CEL_GENERATIONS)  # checked once, with the rest, by RunSettings
    return RunSettings.make(run=args.run or default_run_id("cel"), task="door", regime="independent", seed=args.seed or 0,
                            max_lead=max_lead_of(args.max_lead, CEL_MAX_LEAD), world=world, ga=ga, cel=cel)


def _given_settings(args: argparse.Namespace) -> Any:
    """``--settings RUN_JSON``: a CEL run's settings written beforehand (e.g. by ``coevo cel-experiment``), for a new
    run (its own endpoint and key; ``--run`` renames it)."""
    from coevo.rundir.settings import RunSettings
    from coevo.runs.command import refuse

    refuse(args, ("seed", "fail", "schedule", "cases_from", "trials_per_generation", "chunk", "zero_run", "repair_run",
                  "max_lead", "generations", "population", "episodes", "world", "ga"),
           "--settings gives every run setting but the run id")
    if args.case_base:
        raise ConfigError("--settings gives every run setting but the run id; drop --case-base")
    settings = RunSettings.load(Path(args.settings)).fresh(args.run)
    if settings.block("cel") is None:
        raise ConfigError(f"--settings {args.settings}: not a CEL run's settings (no cel block); start it with coevo run")
    return settings


def cmd_cel(args: argparse.Namespace) -> int:
    """A SIGTERM from the first line to the last is a stop, as Ctrl-C is (interrupted, 130): while the CEL run is made or
    readied it leaves nothing half-made, while it runs it stops it in order (its workers' done.json, its measures)."""
    from coevo.rundir.layout import sigterm_stops

    with sigterm_stops():
        return _cmd_cel(args)


def _cmd_cel(args: argparse.Namespace) -> int:
    from coevo.bus.status import StatusDisplay
    from coevo.cel_service.run import CelRun, cases_of_run, import_cases
    from coevo.cel_service.status import CelPlain, cel_table
    from coevo.runs.local import run_local
    from coevo.rundir.settings import RunSettings

    if args.force and not args.resume:
        raise ConfigError("--force goes with --resume (continue a run that ran on other code)")
    if args.resume:
        given = [f for f in ("run", "settings", "prepare", "seed", "fail", "schedule", "case_base", "cases_from", "trials_per_generation", "chunk",
                             "zero_run", "repair_run", "max_lead", "generations", "population", "episodes", "world", "ga")
                 if getattr(args, f, None) is not None and getattr(args, f) is not False]
        if given:
            raise ConfigError("--resume takes every setting from the run's run.json; drop " +
                              ", ".join(f"--{f.replace('_', '-')}" for f in given))
        lr: CelRun = CelRun.resume(Path(args.resume), log_level=args.log_level,  # type: ignore[assignment]
                                   force=args.force)
        if lr.settings.block("cel") is None:
            raise ConfigError(f"{args.resume} is not a CEL run (its run.json has no cel block); use coevo run --resume")
    else:
        settings: RunSettings = _given_settings(args) if args.settings else _settings(args)
        lr = CelRun(settings, root=Path(args.root), log_level=args.log_level, open_run=args.open)
        cases = cases_of_run(Path(args.cases_from)) if args.cases_from else None  # checked before anything is made
        lr.create()
        if cases is not None:
            try:
                import_cases(lr.paths, cases, worker=lr.settings.roster["door"])  # type: ignore[index]
            except BaseException:  # stopped (or failed) before it started: no run without its case base is left
                shutil.rmtree(lr.dir, ignore_errors=True)
                raise
            print(f"case base: {len(cases)} cases from {args.cases_from}")
    cel = lr.settings.block("cel")
    if cel is None:  # refused above for a resume and made for a new run
        raise ConfigError(f"{lr.dir} is not a CEL run (its run.json has no cel block); use coevo run --resume")
    if args.prepare:
        run_json = lr.paths.run_json
        print(f"CEL run {lr.run} prepared in {lr.dir} (run.json{', secret.key' if not lr.open else ''}); start its "
              "processes, each host holding a copy of run.json and secret.key side by side (mode 0600):\n"
              f"  broker host:  coevo broker --data-dir {lr.dir.parent} --listen tcp/0.0.0.0:7447\n"
              f"  learner:      coevo worker --behaviour door --settings {run_json} --connect BROKER_ENDPOINT\n"
              f"  robot:        coevo execution --settings {run_json} --connect BROKER_ENDPOINT\n"
              f"then: coevo status --run {lr.run} --key-file {lr.paths.key_file} --connect BROKER_ENDPOINT")
        return 0
    events = "; ".join(f"gen {g}: {','.join(f) or 'repair'}" for g, f in cel.schedule) or "no failures"
    title = (f"CEL run {lr.run}: {lr.settings.ga.generations} generations, {events}"
             + (", case base" if cel.case_base else "") + (" OPEN" if lr.open else ""))
    with StatusDisplay(title, quiet=args.quiet, table=cel_table(cel.trials_per_generation),
                       plain=CelPlain(cel.trials_per_generation)) as display:
        summary = run_local(lr, resume=bool(args.resume), measure_epochs=1, on_status=display.show)
    c = summary.get("cel", {})
    print(f"run directory: {lr.dir} ({summary['seconds']:.1f} s)")
    for d in c.get("detections", []):
        if d["detected"]:
            print(f"failure at generation {d['generation']} ({','.join(d['failed']) or 'repair'}): detected after "
                  f"{d['trials']} trials, {d['decisions']} decisions; learner on the new model from generation "
                  f"{d.get('learner_from', '?')}")
        else:
            print(f"failure at generation {d['generation']}: NOT detected")
    if c.get("external_end") is not None:
        print(f"external performance at the end: {c['external_end']:.0f} %; new rules reached the robot in "
              f"{c['latency_ms']['median']:.1f} ms (median)" if c.get("latency_ms") else "")
    if summary["interrupted"]:
        print(f"the run stopped early; continue it with {lr.resume_command}", file=sys.stderr)
        return 130 if summary.get("stopped_here") else 1
    return 0


def cmd_execution(args: argparse.Namespace) -> int:
    from coevo.bus.session import config_from_args
    from coevo.cel_service.robot import run_execution
    from coevo.rundir.layout import RunPaths
    from coevo.rundir.settings import RunSettings, find_run_key

    settings = RunSettings.load(Path(args.settings))
    out = Path(args.out) if args.out else RunPaths(Path(args.settings).parent).execution.dir  # beside run.json
    return run_execution(settings, out=out, conf=config_from_args(args),
                         resume=args.resume, run_key=find_run_key(args.key_file, settings, Path(args.settings).parent))


def add_cel_flags(p: argparse.ArgumentParser, *, schedules: list[str]) -> None:
    """The flags of a live CEL run that ``coevo cel`` and ``coevo cel-experiment`` share: the failure schedule (one of
    ``schedules``) or events, restarts from the case base, and K."""
    p.add_argument("--schedule", choices=schedules,
                   help="figure3: front, front-right and right fail at generation 50 (default); cyclic: fail at 25, "
                        "repaired at 50, fail again at 75" + ("; none" if "none" in schedules else ""))
    p.add_argument("--fail", type=fail_arg, action="append", metavar="GEN:SONARS",
                   help="a failure event instead of --schedule, e.g. 50:front,front_right,right (75: repairs; "
                        "repeatable; front-right, as the report writes it, is the same)")
    p.add_argument("--case-base", action="store_true",
                   help="restart from the case base's nearest earlier strategies (kept in the broker's store)")
    p.add_argument("--trials-per-generation", type=count_arg(1, 100_000),
                   help="K: the robot's trials per learner generation (default 100, Figure 3's y-axis)")


def configure_cel(p: argparse.ArgumentParser) -> None:
    """``coevo cel``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    p.add_argument("--run", help="run id (default cel-TIME)")
    p.add_argument("--root", default="runs", help="parent of the run directory (default runs/)")
    p.add_argument("--resume", metavar="RUN_DIR", help="continue this run from its processes' checkpoints")
    p.add_argument("--force", action="store_true",
                   help="with --resume: continue a run that ran on other code (code.json names it) all the same")
    p.add_argument("--settings", metavar="RUN_JSON",
                   help="start a run with these settings (a CEL run's run.json, e.g. one coevo cel-experiment wrote)")
    p.add_argument("--seed", type=seed_arg, help="the learner's seed (default 0); the robot's world uses seed + 1000003")
    add_cel_flags(p, schedules=list(SCHEDULES))
    p.add_argument("--cases-from", metavar="RUN_DIR", help="start the case base with an earlier run's (implies --case-base)")
    p.add_argument("--chunk", type=count_arg(1, 100_000), help="trials per stretch of the robot (default K)")
    p.add_argument("--zero-run", type=count_arg(1, 10_000),
                   help="the monitor: zero readings in a row while moving forward to mark a sonar defective (default 8)")
    p.add_argument("--repair-run", type=count_arg(1, 10_000),
                   help="the monitor: non-zero readings in a row to mark it working again (default 3)")
    p.add_argument("--quiet", action="store_true", help="no live status table")
    p.add_argument("--open", action="store_true", help="make no key: messages unauthenticated (local experiments only)")
    p.add_argument("--prepare", action="store_true",
                   help="only make the run directory (run.json, key, cases) and print how to start its three processes, "
                        "e.g. on several hosts (deploy/README.md)")
    add_max_lead(p, default=CEL_MAX_LEAD)
    add_settings(p, generations=CEL_GENERATIONS,
                 initial="how the learner starts: the door task's direction-only rule set (default) or random rule sets")
    p.set_defaults(func=cmd_cel)


def configure_execution(p: argparse.ArgumentParser) -> None:
    """``coevo execution``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    from coevo.bus.flags import add_connection_args

    p.add_argument("--settings", required=True, metavar="RUN_JSON", help="the run's settings (its run.json, made by coevo cel)")
    p.add_argument("--out", help="its directory (default: execution/ beside run.json)")
    p.add_argument("--resume", action="store_true", help="continue from the checkpoint in --out")
    p.add_argument("--key-file", metavar="FILE", help="the run's secret key (default: the key_file run.json names)")
    add_connection_args(p)
    p.set_defaults(func=cmd_execution)
