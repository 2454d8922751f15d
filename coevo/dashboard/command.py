"""``coevo dashboard``: its arguments (declared here, light imports only) and what it runs."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from coevo.console import count_arg, positive_float_arg
from coevo.errors import ConfigError, RunDirError

if TYPE_CHECKING:  # for the annotations only: the command's arguments are declared with light imports
    from coevo.bus.trust import Gate
    from coevo.dashboard.robot import RobotPanel

__all__ = ["configure_dashboard", "cmd_dashboard"]

DEFAULT_PORT = 5006  # Bokeh's own default


def configure_dashboard(p: argparse.ArgumentParser) -> None:
    """``coevo dashboard``'s arguments."""
    p.add_argument("dir", nargs="?", metavar="DIR",
                   help="show this run directory, comparison directory (coevo compare --out), study directory (coevo "
                        "study --out) or directory of runs from its files, as they grow (the bus is then followed only "
                        "with --connect)")
    p.add_argument("--run", help="follow only this run on the bus (default: every run whose workers are on it)")
    p.add_argument("--runs-dir", metavar="ROOT",
                   help="where the runs' directories are (coevo run --root, coevo broker --data-dir): the curves of a run "
                        "seen on the bus are read whole from ROOT/RUN/workers/*/curve.jsonl")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to serve the page on (default 127.0.0.1: this machine only; the page is read-only)")
    p.add_argument("--port", type=count_arg(1, 65535), default=DEFAULT_PORT, help=f"default {DEFAULT_PORT}")
    p.add_argument("--every", type=positive_float_arg(maximum=3600), default=0.5,
                   help="seconds between reads of the bus and the files (default 0.5)")
    p.add_argument("--stall", type=positive_float_arg(maximum=86400), default=3.0,
                   help="seconds without a heartbeat before a live worker counts as stalled (default 3)")
    p.add_argument("--stale", type=positive_float_arg(maximum=86400), default=120.0,
                   help="seen from its files only, seconds without a new line before a run counts as stopped (a "
                        "comparison's or study's replicate: failed; a study whose files all stood still: stopped) "
                        "(default 120)")
    p.add_argument("--robot", metavar="RUN",
                   help="draw this run's robot from its newest policies, redrawn as they are published: a run directory, "
                        "or a run's name in the directory shown or in --runs-dir (a study's: cells/CELL/runs/RUN) "
                        "(default: the run shown, when it is one)")
    p.add_argument("--no-robot", action="store_true", help="draw no robot (saves ~1 s of CPU per new policy)")
    p.add_argument("--key-file", metavar="FILE",
                   help="the run's key (with --run): show only its authenticated heartbeats (default: unverified)")
    from coevo.bus.flags import add_connection_args

    add_connection_args(p)
    p.set_defaults(func=cmd_dashboard)


def cmd_dashboard(args: argparse.Namespace) -> int:
    from coevo.dashboard.model import Dashboard, classify_dir

    from coevo.dashboard.port import check_port

    check_port(args.host, args.port)  # a port that is taken is refused at once, before anything loads
    target = Path(args.dir) if args.dir else None
    kind = classify_dir(target) if target else None
    runs_dir = Path(args.runs_dir) if args.runs_dir else None
    if runs_dir is not None and not runs_dir.is_dir():
        raise RunDirError(f"--runs-dir {str(runs_dir)!r} is not a directory")
    if args.key_file and not args.run:
        raise ConfigError("--key-file is one run's key: give that run with --run")
    gate = _gate(args)  # a bad key file is said before anything is tried
    from coevo.bus.flags import connection_given

    # the runs under --runs-dir (default runs/), when neither a directory nor a bus is given
    local_root = _local_root(runs_dir, args.run) if target is None and not connection_given(args) else None
    local = local_root is not None
    gone = False
    if local_root is not None:
        runs_dir = local_root
    elif target is None and args.connect and args.connect_timeout is None and not _answers(args.connect):
        why = f"no broker answers at {', '.join(args.connect)}"  # ended, or not started: --connect-timeout waits
        if runs_dir is None:
            from coevo.errors import ServiceError

            raise ServiceError(f"{why}: has its run ended? Give --runs-dir ROOT to see it from its files (or no "
                               "--connect: the runs under runs/), or --connect-timeout SECONDS to wait for it")
        print(f"dashboard: {why}: showing the runs under {runs_dir} from their files", flush=True)
        target, kind, gone = runs_dir, classify_dir(runs_dir), True
    robot = None if args.no_robot else _robot(args.robot, target, kind, runs_dir, args.run)
    if local_root is not None and robot is None and not args.no_robot:
        robot = _newest_robot(local_root)
    note = "" if robot is not None or args.no_robot else _no_robot(target, kind, runs_dir, args.run, local)
    on_bus = local or not gone and (target is None or bool(args.connect))  # gone: the files only, as it said (it
    # went on to the bus, and 30 s later ended on a ServiceError)
    if local or not on_bus:  # (the bus's path says so itself) SIGTERM ends it as Ctrl-C does: status 0, no traceback
        from coevo.bus.session import sigterm_as_exit

        sigterm_as_exit()
    title = (f"coevo dashboard: {kind} {target}" if target else f"coevo dashboard: the runs under {runs_dir}" if local
             else "coevo dashboard" + (f": run {args.run}" if args.run else ""))

    def ready(url: str) -> None:
        print(f"dashboard: {url} (read-only; Ctrl-C stops it)", flush=True)

    if local_root is not None:
        from coevo.dashboard.model import LocalRuns
        from coevo.dashboard.server import serve

        source = LocalRuns(local_root, stall=args.stall)
        try:
            serve(Dashboard(bus=source, stale=args.stale, title=title, robot=robot, robot_note=note), host=args.host, port=args.port,
                  every=args.every, on_ready=ready)
        finally:
            source.close()
        return 0
    if not on_bus:
        from coevo.dashboard.server import serve

        serve(Dashboard(target=target, runs_dir=runs_dir, stale=args.stale, title=title, robot=robot, robot_note=note),
              host=args.host,
              port=args.port, every=args.every, on_ready=ready)
        return 0
    return _on_bus(args, target, runs_dir, title, ready, robot, gate, note)


def _gate(args: argparse.Namespace) -> Gate | None:
    """With --key-file, the gate that shows only --run's authenticated heartbeats; else None."""
    from coevo.bus import keys

    if args.run:
        keys.check_id("run id", args.run)
    if not args.key_file:
        return None
    from coevo.bus.auth import RunKey
    from coevo.bus.trust import Gate

    return Gate(key=RunKey.load(Path(args.key_file), run=args.run))


def _answers(connect: list[str] | None) -> bool:
    from coevo.bus.flags import DEFAULT_ENDPOINT
    from coevo.runs.discover import answers

    return any(answers(ep) for ep in connect or [DEFAULT_ENDPOINT])


def _local_root(runs_dir: Path | None, run: str | None) -> Path:
    """The directory whose runs are shown (default runs/), said in one line when it holds none (yet)."""
    root = runs_dir or Path("runs")
    if run is not None:
        raise ConfigError(f"--run {run} follows one run on the bus: give --connect ENDPOINT too (its run.json's "
                          f"endpoint), or drop --run to see every run under {root}")
    if not root.is_dir():  # not yet: coevo run & coevo dashboard
        print(f"dashboard: no runs under {root}/ yet: each run coevo run starts there will be shown", flush=True)
    return root


def _newest_robot(root: Path) -> RobotPanel | None:
    """The robot of the run under ``root`` started last (its run.json written last), if there is one."""
    from coevo.dashboard.robot import RobotPanel
    from coevo.rundir.layout import RunPaths

    runs = [RunPaths(d).run_json for d in root.iterdir() if RunPaths(d).run_json.is_file()] if root.is_dir() else []
    return RobotPanel(max(runs, key=lambda p: p.stat().st_mtime).parent) if runs else None


def _no_robot(target: Path | None, kind: str | None, runs_dir: Path | None, run: str | None, local: bool) -> str:
    """Why no robot is drawn, and how to have one, for the page (said instead of a section silently absent)."""
    if local:
        return (f"No robot: no run under {runs_dir} when the dashboard started. Start it again once a run has begun, "
                "or give --robot RUN_DIR.")
    if run is not None:  # --run on the bus without --runs-dir: its files are not known
        return (f"No robot: it is drawn from run {run}'s files, and where they are is not given. Add --runs-dir ROOT "
                f"(the directory holding {run}/), or --robot RUN_DIR.")
    where = (f"a run's name under {target}" if kind in ("runs", "comparison") and target is not None
             else f"cells/CELL/runs/RUN under {target}" if kind == "study" and target is not None
             else f"a run's name under {runs_dir}" if runs_dir is not None else "a run's directory")
    return (f"No robot: this page shows every run {'in ' + str(target) if target else 'on the bus'}, and a robot is one "
            f"run's. Add --robot RUN ({where}) to draw that run's newest robot.")


def _robot(name: str | None, target: Path | None, kind: str | None, runs_dir: Path | None,
           run: str | None) -> RobotPanel | None:
    """The RobotPanel of the run ``--robot`` names (a path, or a run name under the directory shown or --runs-dir),
    by default of the run shown when it is a single run (a run directory, or ``--run`` with ``--runs-dir``, whose
    directory may not exist yet); None when there is none to draw."""
    from coevo.dashboard.model import is_run
    from coevo.dashboard.robot import RobotPanel

    if name is None:
        if kind == "run" and target is not None:
            return RobotPanel(target)
        return RobotPanel(runs_dir / run) if run and runs_dir is not None else None
    places = [Path(name)]
    if target is not None and kind in ("runs", "comparison", "study"):
        places.append(target / "runs" / name if kind == "comparison" else target / name)
    if runs_dir is not None:
        places.append(runs_dir / name)
    places = list(dict.fromkeys(places))  # an absolute RUN is the same place under every directory
    found = next((p for p in places if is_run(p)), None)
    if found is None:
        raise RunDirError(f"--robot {name!r}: no run directory there (looked at {', '.join(repr(str(p)) for p in places)})")
    return RobotPanel(found)


def _on_bus(args: argparse.Namespace, target: Path | None, runs_dir: Path | None, title: str,
            ready: Callable[[str], None], robot: RobotPanel | None, gate: Gate | None, note: str) -> int:
    from coevo.bus.session import config_from_args, open_session, sigterm_as_exit
    from coevo.dashboard.model import BusSource, Dashboard
    from coevo.dashboard.server import serve

    if args.run and gate is None:
        title += " (unverified: no --key-file)"
    conf = config_from_args(args)
    sigterm_as_exit()
    with open_session(conf, what="dashboard session", gate=gate) as session:
        source = BusSource(session, run=args.run, stall=args.stall)
        try:
            serve(Dashboard(bus=source, target=target, runs_dir=runs_dir, stale=args.stale, title=title, robot=robot,
                            robot_note=note),
                  host=args.host, port=args.port, every=args.every, on_ready=ready)
        finally:
            source.close()
    return 0
