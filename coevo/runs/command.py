"""The commands that start a run's processes or follow them: ``coevo run``, ``worker``, ``chaos``, ``status``, ``keygen``.

Each command is a ``configure_NAME`` (its arguments, declared here beside it) and a ``cmd_NAME`` (what it
does); :mod:`coevo.cli` gathers them.  The module's top imports only what a parser needs, so that
``coevo status --help`` answers at once: the work's modules are imported by the command that runs.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from functools import partial
from pathlib import Path
from typing import Any

from coevo.console import (
    add_max_lead,
    add_settings,
    count_arg,
    given_settings,
    max_lead_of,
    positive_float_arg,
    seed_arg,
    task_arg,
)
from coevo.config import DEFAULT_MAX_LEAD, HALL_SAMPLE, HALL_SHARE, MODELS, Bounded
from coevo.errors import ConfigError, RunDirError

__all__ = ["configure_run", "configure_worker", "configure_chaos", "configure_status", "configure_keygen",
           "GA_FLAGS", "RUN_FLAGS", "refuse", "add_run_settings"]

GA_FLAGS = ("generations", "population", "episodes", "world", "ga")  # the settings flags of console.add_settings
WIDTH = 110  # characters of a line of the run's last words

RUN_FLAGS = ("task", "regime", "seed", "model", "hall_sample", "hall_share", "max_lead", *GA_FLAGS)  # and a run's



def _given(args: argparse.Namespace, task: str) -> dict[str, dict[str, Any]]:
    """The world and GA settings the flags give, unchecked: :class:`RunSettings` checks them, once, against the
    task's world model and the GA's."""
    world, ga = given_settings(args, task)
    return {"world": world, "ga": ga}

def refuse(args: argparse.Namespace, names: tuple[str, ...], why: str) -> None:
    """A ConfigError naming each of the flags ``names`` that was given, when ``why`` says they cannot be."""
    given = [f"--{n.replace('_', '-')}" for n in names if getattr(args, n, None) is not None]
    if given:
        raise ConfigError(f"{why}; drop {', '.join(given)}")


def kind_arg(value: str) -> str:
    """A kind of learner's name, as installed (coevo plugins lists them); nothing is imported to check it."""
    from coevo.rundir.kinds import kind_names

    if value not in kind_names():
        raise argparse.ArgumentTypeError(f"unknown kind of learner {value!r} (installed: {', '.join(kind_names())})")
    return value


def add_run_settings(p: argparse.ArgumentParser, *, defaults_note: bool = True) -> None:
    """A run's settings flags (task, seed, partner model, pacing, GA and world), shared by run and worker."""
    p.add_argument("--task", type=task_arg, help="the task (default fuel; coevo plugins lists those installed)")
    p.add_argument("--seed", type=seed_arg, help="default 0" + ("; worker i of the task's behaviours uses seed + i" if defaults_note else ""))
    p.add_argument("--model", choices=MODELS, help="how partners are modelled (default best so far; hall: the best so "
                   "far and a sample of past bests, docs/competition.md)")
    p.add_argument("--hall-sample", type=Bounded(1, 1000), metavar="N",
                   help=f"--model hall: past bests sampled each generation (default {HALL_SAMPLE})")
    p.add_argument("--hall-share", type=Bounded(0, 1, whole=False, above=True), metavar="SHARE",
                   help=f"--model hall: share of the episodes played against them, below 1 (default {HALL_SHARE})")
    add_max_lead(p)
    add_settings(p)


def model_settings(args: argparse.Namespace) -> dict[str, object]:
    """The partner model's settings from ``--model`` and the hall of fame's flags, which only ``--model hall`` takes."""
    model = args.model or "best"
    if model != "hall":
        refuse(args, ("hall_sample", "hall_share"), f"the hall of fame's flags are for --model hall, not {model}")
    given = {k: getattr(args, k) for k in ("hall_sample", "hall_share") if getattr(args, k, None) is not None}
    return {"model": model, **given}


def configure_run(p: argparse.ArgumentParser) -> None:
    """``coevo run``'s arguments."""
    p.add_argument("--regime", help="mutual or independent (default independent)")
    p.add_argument("--run", help="run id (default REGIME-TIME)")
    p.add_argument("--root", default="runs", help="parent of the run directory (default runs/)")
    p.add_argument("--resume", metavar="RUN_DIR", help="continue this run from its workers' checkpoints, with its settings")
    p.add_argument("--settings", metavar="RUN_JSON", help="start a run with these settings (a run.json, e.g. one coevo compare wrote)")
    p.add_argument("--force", action="store_true",
                   help="with --resume: continue a run that ran on other code (code.json names it) all the same")
    p.add_argument("--measure-epochs", type=count_arg(1, 1_000_000), default=100,
                   help="fresh epochs measuring the final policies together at the end (default 100)")
    p.add_argument("--quiet", action="store_true", help="no live status table")
    p.add_argument("--open", action="store_true",
                   help="make no key: the run's messages are unauthenticated (local experiments only)")
    p.add_argument("--listen", metavar="ENDPOINT",
                   help="where the run's broker listens, e.g. tcp/0.0.0.0:7447 (default: a free loopback port); "
                        "run.json records it, coevo status and coevo dashboard find it there")
    add_run_settings(p)
    p.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    """A SIGTERM from the first line to the last is a stop, as Ctrl-C is (interrupted, 130): while the run is made or
    readied it leaves nothing half-made, while it runs it stops it in order (its workers' done.json, its measures)."""
    from coevo.rundir.layout import sigterm_stops

    with sigterm_stops():
        return _cmd_run(args)


def _cmd_run(args: argparse.Namespace) -> int:
    from coevo.bus.status import StatusDisplay
    from coevo.runs.discover import follow_hint
    from coevo.runs.kinds import COEVOLUTION, kind_of_settings
    from coevo.runs.local import LocalRun, check_listen, default_run_id, run_local
    from coevo.rundir.settings import RunSettings
    from coevo.rundir.code import refuse_other_code
    from coevo.tasks import DEFAULT_TASK

    listen = check_listen(args.listen) if args.listen else None
    if args.force and not args.resume:
        raise ConfigError("--force goes with --resume (continue a run that ran on other code)")
    if args.resume:
        refuse(args, (*RUN_FLAGS, "run", "settings"), "--resume takes every setting from the run's run.json")
        lr = LocalRun.resumable(Path(args.resume), log_level=args.log_level, listen=listen)
        if (kind := kind_of_settings(lr.settings)) is not COEVOLUTION:
            raise ConfigError(f"{args.resume} is {kind.label}: continue it with {kind.run().COMMAND} --resume {args.resume}")
        refuse_other_code(lr.dir, force=args.force, what="curves")  # a damaged code.json too, before anything
        if (done := _complete(lr)) is not None:  # nothing to continue: say so, start nothing, change nothing
            print(f"run {lr.run} is complete: every worker finished its generations; nothing to continue")
            _say_end(lr, done)
            return 0
        lr = LocalRun.resume(Path(args.resume), log_level=args.log_level, listen=listen, force=args.force)
    else:
        if args.settings:
            refuse(args, RUN_FLAGS, "--settings gives every run setting but the run id")
            settings = RunSettings.load(Path(args.settings)).fresh(args.run)  # a new run: its own endpoint and key
        else:
            task = args.task or DEFAULT_TASK
            regime = args.regime or "independent"
            settings = RunSettings.make(run=args.run or default_run_id(regime), task=task, regime=regime,
                                        seed=args.seed or 0, **model_settings(args),
                                        max_lead=max_lead_of(args.max_lead, DEFAULT_MAX_LEAD),
                                        **_given(args, task))
        if (kind := kind_of_settings(settings)) is not COEVOLUTION:
            raise ConfigError(f"{args.settings} holds the settings of {kind.label}: start it with {kind.run().COMMAND}")
        lr = LocalRun(settings, root=Path(args.root), log_level=args.log_level, open_run=args.open, listen=listen)
        lr.create()
    print(f"run {lr.run}: its broker listens on {lr.endpoint}, its files are in {lr.dir}\n"
          f"follow it with: {'  or  '.join(follow_hint(lr.run, lr.root))}", flush=True)
    title = f"run {lr.run} ({lr.settings.regime})" + (" OPEN: messages unauthenticated" if lr.open else "")
    with StatusDisplay(title, quiet=args.quiet) as display:
        summary = run_local(lr, resume=bool(args.resume), measure_epochs=args.measure_epochs, on_status=display.show)
    print(f"run directory: {lr.dir} ({summary['seconds']:.1f} s)")
    _say_end(lr, summary, measure_epochs=args.measure_epochs,
             complete=not summary["interrupted"] and not summary["unstored"])
    if summary["interrupted"]:
        early = ", ".join(f"{b} after {g}" for b, g in summary.get("stopped_early", {}).items())
        print(f"the run stopped early{' (' + early + ' generations)' if early else ''}; continue it with "
              f"{lr.resume_command}", file=sys.stderr)
        return 130 if summary.get("stopped_here") else 1
    if summary["unstored"]:
        print(f"the broker's store lacks published versions {summary['unstored']} (they stay in the workers' "
              f"published.jsonl; see {lr.paths.log('broker')}): the run is not complete; coevo check {lr.dir} "
              "says what is wrong", file=sys.stderr)
        return 1
    return 0


def _complete(lr: Any) -> dict[str, Any] | None:
    """A finished run's summary.json when there is nothing to continue: every worker finished its generations, the
    run ended complete (not interrupted, every version stored) and its files are whole (a resume would read them
    without a problem, and ``coevo check`` without its replay finds none: a torn or damaged file is the resume's to
    refuse or repair); else None."""
    from coevo.rundir.layout import read_json
    from coevo.runs.check import check_run

    if lr.unfinished() or not lr.paths.summary.exists() or lr.problems():
        return None
    summary: dict[str, Any] = read_json(lr.paths.summary, what="run directory (its summary.json)")
    if summary.get("interrupted") or summary.get("unstored") or not check_run(lr.dir, replay=False).ok:
        return None
    return summary


def _say_end(lr: Any, summary: dict[str, Any], *, measure_epochs: int | None = None, complete: bool = True) -> None:
    """A run's last lines: what its final policies did together, in the task's words; for a complete run, what they
    amount to (the task's verdict) and what to do next, with the run's own path."""
    import shlex
    import textwrap

    from coevo.tasks.base import measures_text

    if "measures" in summary:
        m = summary["measures"]
        over = f" (measured together on {measure_epochs} fresh epochs)" if measure_epochs else ""
        print(_wrapped(["final policies together:", *(f"{x}," for x in measures_text(lr.task, m))], over))
        if complete and (verdict := lr.task.run_verdict(m)):
            print(textwrap.fill(verdict, WIDTH, subsequent_indent="  ", break_on_hyphens=False))
    if not complete:
        return
    where = shlex.quote(str(lr.dir))
    print(f"next: coevo show {where}  (draw an epoch of the final policies)\n"
          f"      coevo check {where}  (is the run complete, does it replay exactly)\n"
          f"      coevo dashboard {where}  (its curves and its robot in the browser)")


def _wrapped(items: list[str], end: str) -> str:
    """``items`` in lines of at most WIDTH characters, broken only between items, the last one's comma replaced by
    ``end``: a measure's name and value stay on one line."""
    items = [*items[:-1], items[-1].rstrip(",") + end]
    lines = [items[0]]
    for item in items[1:]:
        if len(lines[-1]) + 1 + len(item) > WIDTH:
            lines.append(" ")
        lines[-1] += f" {item}"
    return "\n".join(lines)


def configure_worker(p: argparse.ArgumentParser) -> None:
    """``coevo worker``'s arguments."""
    p.add_argument("--settings", metavar="RUN_JSON", help="the run's settings (its run.json; what coevo run starts workers with)")
    p.add_argument("--behaviour", required=True, help="the behaviour this worker learns: one of the run's task's")
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
    add_run_settings(p, defaults_note=False)
    from coevo.bus.flags import add_connection_args

    add_connection_args(p)
    p.set_defaults(func=cmd_worker)


def cmd_worker(args: argparse.Namespace) -> int:
    from coevo.agents.worker import run_worker
    from coevo.bus.session import config_from_args
    from coevo.rundir.layout import RunPaths
    from coevo.rundir.settings import RunSettings, find_run_key
    from coevo.runs.kinds import kind_of_settings
    from coevo.tasks import DEFAULT_TASK
    from coevo.tasks.base import check_behaviour

    if args.settings:
        refuse(args, ("task", "regime", "run", "model", "hall_sample", "hall_share", "max_lead", *GA_FLAGS),
               "--settings gives every run setting")
        settings = RunSettings.load(Path(args.settings))
        base: Path | None = Path(args.settings).parent
    else:
        base = None
        if args.run is None or args.regime is None:
            raise ConfigError("give --settings RUN/run.json (a run's settings), or --run and --regime")
        task = args.task or DEFAULT_TASK
        settings = RunSettings.make(run=args.run, task=task, regime=args.regime, seed=args.seed or 0,
                                    **model_settings(args), max_lead=max_lead_of(args.max_lead, DEFAULT_MAX_LEAD),
                                    **_given(args, task))
    check_behaviour(settings.the_task, args.behaviour)
    kind = kind_of_settings(settings).worker()  # another kind's learner (coevo.rundir.kinds) plugs into the worker's seam
    out = Path(args.out) if args.out else (RunPaths(base).worker(args.behaviour).dir if base else None)
    conf = config_from_args(args)
    run_key = find_run_key(args.key_file, settings, base)
    if base is None:
        _record_hand_run(settings, out, args)
    return run_worker(settings, kind=kind, behaviour=args.behaviour, seed=args.seed, worker_id=args.worker_id, out=out,
                      conf=conf, resume=args.resume, final_sync=args.final_sync, run_key=run_key)


def _record_hand_run(settings: Any, out: Path | None, args: argparse.Namespace) -> None:
    """A worker started by hand (no --settings) leaves the run.json coevo run would have written, when its directory
    is a run's (``RUN/workers/BEHAVIOUR``, the default ``runs/RUN/workers/BEHAVIOUR``) and none is there yet: the
    task, regime and GA settings for coevo show, check and the dashboard, and the broker's endpoint and the key's
    path for coevo status.  The first worker of the run writes it; its ``seed`` is that worker's."""
    import logging
    import os

    from coevo.bus.auth import KEY_ENV
    from coevo.bus.flags import DEFAULT_ENDPOINT
    from coevo.rundir.layout import RunPaths

    run_dir = (out.parent.parent if out.parent.name == "workers" else None) if out else Path("runs") / settings.run
    if run_dir is None or RunPaths(run_dir).run_json.exists():
        return
    endpoint = (args.connect or [None if args.config else DEFAULT_ENDPOINT])[0]
    key_file = args.key_file or os.environ.get(KEY_ENV)
    key = os.path.relpath(key_file, run_dir) if key_file else None
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        settings.model_copy(update={"endpoint": endpoint, "key_file": key}).save(RunPaths(run_dir).run_json)
    except OSError as exc:  # the worker's own directory says what is wrong, if anything is
        logging.getLogger(__name__).warning("cannot write %s: %s", RunPaths(run_dir).run_json, exc.strerror or exc)


def configure_chaos(p: argparse.ArgumentParser) -> None:
    """``coevo chaos``'s arguments."""
    p.add_argument("--regime", help="mutual or independent (default mutual; the door task's: independent)")
    p.add_argument("--run", help="run id (default chaos-REGIME-TIME)")
    p.add_argument("--learner", metavar="KIND", type=kind_arg,
                   help="the kind of learner of the run (default coevolution; coevo plugins lists them): e.g. cel, a "
                        "CEL run (door task) whose execution module is killed and paused too, front, front-right and "
                        "right failing halfway")
    p.add_argument("--root", default="runs", help="parent of the run directory (default runs/)")
    p.add_argument("--task", help="the task (default fuel)")
    p.add_argument("--seed", type=seed_arg, default=0, help="seeds the workers and the choice of faults")
    p.add_argument("--model", default="best", choices=MODELS, help="how partners are modelled (default best so far)")
    p.add_argument("--faults", type=count_arg(0, 10_000), default=8, help="faults to inject (default 8)")
    p.add_argument("--kinds", nargs="+", default=["kill-worker", "kill-broker", "pause-worker"], metavar="KIND",
                   help="kill-worker kill-broker pause-worker (default all three)")
    p.add_argument("--gap", type=positive_float_arg(allow_zero=True, maximum=3600), nargs=2, default=[1.0, 4.0],
                   metavar=("MIN", "MAX"), help="seconds between faults (default 1 4)")
    p.add_argument("--down", type=positive_float_arg(allow_zero=True, maximum=3600), nargs=2, default=[0.5, 3.0],
                   metavar=("MIN", "MAX"), help="seconds a killed process stays down or a paused one stopped (default 0.5 3)")
    p.add_argument("--measure-epochs", type=count_arg(1, 1_000_000), default=20,
                   help="fresh epochs measuring the final policies together at the end (default 20)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    add_settings(p)
    p.set_defaults(func=cmd_chaos)


def cmd_chaos(args: argparse.Namespace) -> int:
    from coevo.runs.chaos import CHAOS_REPORT, ChaosPlan, run_chaos, summary_lines
    from coevo.runs.kinds import COEVOLUTION, KINDS
    from coevo.runs.local import default_run_id
    from coevo.rundir.settings import RunSettings
    from coevo.tasks import DEFAULT_TASK, get_task

    plan = ChaosPlan(faults=args.faults, kinds=tuple(args.kinds), gap=tuple(args.gap), down=tuple(args.down), seed=args.seed)
    kind = COEVOLUTION if args.learner is None else KINDS.get(args.learner)
    task = args.task or kind.default_task or DEFAULT_TASK
    regime = args.regime or ("mutual" if "mutual" in get_task(task).regimes else "independent")
    settings = RunSettings.make(run=args.run or default_run_id(f"chaos-{kind.block or regime}"), task=task,
                                regime=regime, seed=args.seed, model=args.model, **_given(args, task))
    if kind.chaos_settings is not None:  # the kind's own block and pacing, from the GA settings as checked
        settings = RunSettings.make(**{**settings.model_dump(mode="json"), **kind.chaos_settings(settings.ga)})

    def say(text: str) -> None:
        if not args.quiet:
            print(f"{time.strftime('%H:%M:%S')} {text}", flush=True)

    report = run_chaos(settings, root=Path(args.root), plan=plan, measure_epochs=args.measure_epochs, on_event=say,
                       log_level=args.log_level)
    for line in summary_lines(report):
        print(line)
    print(f"report: {settings.paths(Path(args.root)).dir / CHAOS_REPORT}")
    return 0 if report["complete"] else 1


def configure_status(p: argparse.ArgumentParser) -> None:
    """``coevo status``'s arguments."""
    p.add_argument("--run", help="the run to follow (default: the newest live run under --runs-dir)")
    p.add_argument("--runs-dir", metavar="ROOT",
                   help="without --connect: find the runs here, from their run.json (default runs/, coevo run's --root)")
    p.add_argument("--json", action="store_true", help="one JSON object per update")
    p.add_argument("--stall", type=positive_float_arg(maximum=86400), default=3.0,
                   help="seconds without a heartbeat before a live worker counts as stalled (default 3; workers beat every second)")
    p.add_argument("--every", type=positive_float_arg(maximum=3600), default=0.5,
                   help="refresh period in seconds (default 0.5; changes show at once)")
    p.add_argument("--duration", type=positive_float_arg(maximum=1e7), help="stop after this many seconds (default: until Ctrl-C)")
    p.add_argument("--key-file", metavar="FILE",
                   help="the run's key: show only authenticated heartbeats (default: the key its run directory holds, "
                        "else unverified)")
    from coevo.bus.flags import add_connection_args

    add_connection_args(p)
    p.set_defaults(func=cmd_status)


def cmd_status(args: argparse.Namespace) -> int:
    from coevo.bus import keys
    from coevo.bus.auth import RunKey
    from coevo.bus.flags import connection_given
    from coevo.bus.session import config_from_args
    from coevo.bus.status import StatusDisplay, follow
    from coevo.bus.trust import Gate

    if args.run is not None:
        keys.check_id("run id", args.run)
    key_file = Path(args.key_file) if args.key_file else None
    until = None
    if connection_given(args):
        if args.runs_dir:
            raise ConfigError("--runs-dir finds runs and their brokers itself: drop it, or the connection flags")
        if args.run is None:
            raise ConfigError("connection flags (--connect ...) follow one run: give it with --run")
        run, conf = args.run, config_from_args(args)
        gate = None if key_file is None else Gate(key=RunKey.load(key_file, run=run))
    else:
        found = _status_of_local_runs(args)
        if found is None:  # nothing to follow: said in a line each; a run asked for by name and unreachable fails
            return 1 if args.run is not None and _gone(Path(args.runs_dir or "runs") / args.run) else 0
        from coevo.runs.discover import ended, find_run, follow_settings

        run, (conf, gate) = found.run, follow_settings(found, key_file=key_file)
        until = partial(ended, found.dir)  # its files say it ended: nothing more to follow
    title = f"run {run} at {{time}}" + ("" if gate else " (unverified: no --key-file)")
    with StatusDisplay(title, json_lines=args.json) as display:
        follow(conf, run, display.show, every=args.every, stall=args.stall, duration=args.duration, gate=gate,
               until=until)
    if until is not None and until():
        _say(find_run(found.dir.parent, found.dir.name), args.json)  # how it ended, from its files
    return 0


def _gone(run_dir: Path) -> bool:
    from coevo.runs.discover import ended

    return not ended(run_dir)


def _say(found: Any, json_lines: bool) -> None:
    import json

    print(json.dumps(found.as_dict()) if json_lines else found.line(), flush=True)


def _status_of_local_runs(args: argparse.Namespace) -> Any:
    """``coevo status`` without --connect: the runs under --runs-dir said in one line each (or JSON), and the one to
    follow (``--run``, else the newest live one), or None when none is live."""
    from coevo.runs.discover import LIVE, find_run, find_runs

    root = Path(args.runs_dir or "runs")
    if args.run is not None:
        one = find_run(root, args.run)
        if one is None:
            raise RunDirError(f"no run {args.run} under {str(root)!r} (no {root / args.run / 'run.json'}): give "
                              "--runs-dir ROOT, or --connect ENDPOINT for a run elsewhere on the bus")
        runs = [one]
    else:
        runs = find_runs(root)
        if not runs:
            raise RunDirError(f"no runs under {str(root)!r} (no {root}/*/run.json): start one with coevo run, or give "
                              "--runs-dir ROOT, or --connect ENDPOINT --run RUN")
    live = [f for f in runs if f.state == LIVE]
    followed = live[-1] if live else None
    for f in runs:
        if f is not followed:
            _say(f, args.json)
    return followed


def configure_keygen(p: argparse.ArgumentParser) -> None:
    """``coevo keygen``'s arguments."""
    p.add_argument("--run", required=True, help="the run id the key is for")
    p.add_argument("--out", required=True, metavar="FILE", help="the key file to create (never overwritten)")
    p.set_defaults(func=cmd_keygen)


def cmd_keygen(args: argparse.Namespace) -> int:
    from coevo.bus import keys
    from coevo.bus.auth import RunKey

    key = RunKey.create(keys.check_id("run id", args.run))
    out = Path(args.out)
    made = [d for d in (out.parent, *out.parent.parents) if not d.exists()]  # the broker's DATA_DIR/RUN, say
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        key.save(out)
    except (OSError, ConfigError) as exc:
        for d in made:  # nothing left behind
            with contextlib.suppress(OSError):
                d.rmdir()
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"cannot create the key file's folder {str(out.parent)!r}: {exc.strerror or exc}") from None
    print(f"run {args.run}'s key written to {args.out} (mode 0600); copy it to each host of the run, see deploy/README.md")
    return 0
