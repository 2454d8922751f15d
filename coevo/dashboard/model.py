"""What the dashboard shows, as plain data: runs, their workers, learning curves, a comparison's replicates, a study's
cells.

Two sources, each followed incrementally:

- **the bus** (:class:`BusSource`): one :class:`~coevo.bus.status.StatusBoard` per run (the
  model behind ``coevo status``: heartbeats, liveliness tokens, the broker's status), for the run
  given with ``--run`` or every run whose workers' tokens appear on the bus.  A worker's curve is
  grown from its heartbeats: a point each time its generation moves on (a generation shorter
  than the poll period can be missed; the files have them all).
- **files** (:class:`RunFiles`): a run directory's ``workers/*/worker.json``, ``curve.jsonl``
  (every generation), ``adoptions.jsonl`` (partner versions), ``done.json``, the store's files
  and ``summary.json`` (the combined robot's measures at the end); a CEL run's
  ``execution/performance.jsonl``.  The logs are read from where the last read stopped.

:class:`Dashboard` merges them into a :class:`View` (a run seen on both shows the bus's live
state and the files' complete curves) and counts a version that moves only when something the
page shows changed, so a page redraws only then.  A comparison directory is read by
:mod:`coevo.dashboard.compare`, a study directory by :mod:`coevo.dashboard.study`.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from contextlib import ExitStack
from typing import TYPE_CHECKING, Any

from coevo.dashboard.files import Tail, mtime
from coevo.errors import RunDirError

if TYPE_CHECKING:
    from coevo.bus.session import CallbackSubscriber, Sample, Session
    from coevo.bus.status import StatusBoard
    from coevo.dashboard.compare import ComparisonFiles
    from coevo.dashboard.robot import RobotPanel, RobotPicture
    from coevo.dashboard.study import StudyFiles
    from coevo.runs.discover import FoundRun

__all__ = ["Curve", "RunView", "View", "Tail", "RunFiles", "BusSource", "LocalRuns", "Dashboard", "classify_dir", "is_run", "STALE", "mtime"]

log = logging.getLogger(__name__)

STALE = 120.0  # seconds without a new line in any of a run's logs before, seen from its files only, it counts as stopped


# ---------------------------------------------------------------- curves
@dataclass
class Curve:
    """One worker's learning curve: per generation its best fitness, the best so far, and the task's measures (%)."""

    generation: list[int] = field(default_factory=list)
    best: list[float] = field(default_factory=list)
    best_so_far: list[float] = field(default_factory=list)
    measures: dict[str, list[float | None]] = field(default_factory=dict)

    def add(self, generation: int, best: float, measures: dict[str, float] | None = None,
            best_so_far: float | None = None) -> bool:
        """Append a generation after the last one (an older or repeated one is ignored); True if appended."""
        if generation <= 0 or (self.generation and generation <= self.generation[-1]):
            return False
        n = len(self.generation)
        self.generation.append(int(generation))
        self.best.append(float(best))
        prev = self.best_so_far[-1] if self.best_so_far else float("-inf")
        self.best_so_far.append(float(best_so_far) if best_so_far is not None else max(prev, float(best)))
        for k in measures or {}:
            self.measures.setdefault(k, [None] * n)
        for k, col in self.measures.items():
            v = (measures or {}).get(k)
            col.append(None if v is None else float(v))
        return True

    def __len__(self) -> int:
        return len(self.generation)


@dataclass(frozen=True)
class Dynamics:
    """A finished run's ``coevo dynamics`` pictures (RUN/dynamics): what they were played with (its dynamics.json)
    and each PNG, base64, by name: per pair the master tournament, then the CIAO matrix."""

    played: dict[str, Any]
    pictures: tuple[tuple[str, str], ...]
    stamp: float  # dynamics.json's time of change: a new coevo dynamics redraws the page

    @staticmethod
    def read(run: Path) -> Dynamics | None:
        done = run / "dynamics" / "dynamics.json"
        played = _read_json(done)
        if played is None:
            return None
        pngs = [run / "dynamics" / f"{kind}-{'-'.join(map(str, pair))}.png"
                for pair in played.get("pairs") or [] for kind in ("master", "ciao")]
        return Dynamics(played, _pictures(pngs), mtime(done))


@dataclass(frozen=True)
class AcrossDynamics:
    """A folder of runs' ``coevo dynamics`` summary (DIR/dynamics): how many runs in which groups, each pair's
    master tournament across runs (its PNG, base64, by name) and its rise (rise.json's rows: per pair and group, each
    run's score at the last generation minus the first, mean with interval, runs that rose)."""

    runs: int
    groups: tuple[str, ...]
    pictures: tuple[tuple[str, str], ...]
    rise: tuple[dict[str, Any], ...]
    stamp: float  # runs.json's time of change (written last): a new summary redraws the page

    @staticmethod
    def read(folder: Path) -> AcrossDynamics | None:
        done = folder / "dynamics" / "runs.json"
        said = _read_json(done)
        if said is None:
            return None
        pictures = _pictures(sorted((folder / "dynamics").glob("summary-*.png")))
        rise = (_read_json(folder / "dynamics" / "rise.json") or {}).get("rise")
        runs, groups = said.get("runs"), said.get("groups")  # what a damaged file holds instead is shown as none
        return AcrossDynamics(len(runs) if isinstance(runs, list) else 0,
                              tuple(sorted({str(g) for g in groups.values()})) if isinstance(groups, dict) else (),
                              pictures, tuple(r for r in rise if isinstance(r, dict))
                              if isinstance(rise, list) else (), mtime(done))


@dataclass
class RunView:
    """One run as the page shows it."""

    run: str
    source: str  # "bus", "files" or "bus+files"
    task: str = "?"
    regime: str = "?"
    state: str = "?"  # running, done, stopped, failed
    workers: list[dict[str, Any]] = field(default_factory=list)  # StatusBoard.snapshot()'s dicts
    robots: list[dict[str, Any]] = field(default_factory=list)  # a CEL run's execution module
    broker: dict[str, Any] | None = None  # StatusBoard.broker_view()'s dict (from files: what the store holds)
    curves: dict[str, tuple[str, Curve]] = field(default_factory=dict)  # worker id -> (behaviour, curve)
    external: Curve | None = None  # a CEL run's external performance per generation
    final: dict[str, float] = field(default_factory=dict)  # summary.json's measures of the combined robot
    problems: list[str] = field(default_factory=list)
    dynamics: Dynamics | None = None  # what coevo dynamics drew of a finished run (RUN/dynamics), if it has


@dataclass
class View:
    """Everything on the page at one moment."""

    title: str
    runs: list[RunView] = field(default_factory=list)
    comparison: dict[str, Any] | None = None
    study: dict[str, Any] | None = None  # coevo.dashboard.study.StudyFiles.read()'s dict
    problems: list[str] = field(default_factory=list)
    robot: RobotPicture | None = None  # of the run whose robot is drawn, if one is
    robot_note: str = ""  # else why none is, and how to have one (empty: none asked for, --no-robot)
    across: AcrossDynamics | None = None  # a folder of runs' coevo dynamics summary, once played

    def fingerprint(self) -> str:
        """What the page shows, in short: equal fingerprints draw the same page (heartbeat ages left out)."""
        def worker(w: dict[str, Any]) -> dict[str, Any]:
            return {k: v for k, v in w.items() if k != "heartbeat_age"}

        runs = [{"run": r.run, "source": r.source, "state": r.state, "workers": [worker(w) for w in r.workers],
                 "robots": [worker(w) for w in r.robots], "broker": r.broker, "final": r.final, "problems": r.problems,
                 "curves": {k: len(c) for k, (_, c) in r.curves.items()},
                 "external": len(r.external) if r.external else 0,
                 "dynamics": r.dynamics.stamp if r.dynamics else None} for r in self.runs]
        def short(c: dict[str, Any] | None) -> dict[str, Any] | None:  # a comparison's "lengths" stand for its
            # panels: a panel changes only when a curve grows or a run's state moves
            return {k: v for k, v in c.items() if k != "panels"} if c else None

        study = None
        if self.study:
            study = {k: v for k, v in self.study.items() if k != "shown"}
            study["shown"] = {cell: short(c) for cell, c in self.study["shown"].items()}
        return json.dumps({"runs": runs, "comparison": short(self.comparison), "study": study, "problems": self.problems,
                           "across": self.across.stamp if self.across else None,
                           "robot": self.robot.key() if self.robot is not None else self.robot_note}, sort_keys=True,
                          default=str)


# ---------------------------------------------------------------- files
def _pictures(pngs: list[Path]) -> tuple[tuple[str, str], ...]:
    """Each PNG that can be read, by name, as base64 (one missing or unreadable is left out: the page shows the rest)."""
    import base64

    out = []
    for png in pngs:
        try:
            out.append((png.name, base64.b64encode(png.read_bytes()).decode("ascii")))
        except OSError:
            continue
    return tuple(out)


def _read_json(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return data if isinstance(data, dict) else None


def _status_measures(task: str, behaviour: str, row: dict[str, Any]) -> dict[str, float]:
    """The task's few measures (%) of a behaviour, from a curve line (what its heartbeats carry)."""
    from coevo.tasks import TASKS, get_task

    if task not in TASKS:
        return {}
    try:
        return get_task(task).status_measures(behaviour, row)
    except (ValueError, KeyError, TypeError):
        return {}


def _task_of(behaviours: list[str]) -> str:
    """The task whose behaviours these are ('?' if none is known)."""
    from coevo.errors import ConfigError
    from coevo.tasks import task_of

    for b in behaviours:
        try:
            return task_of(b).name
        except ConfigError:
            continue
    return "?"


def classify_dir(path: Path) -> str:
    """``run``, ``comparison``, ``study`` or ``runs`` (a directory of runs), else a RunDirError saying what it is not."""

    p = Path(path)
    if not p.is_dir():
        raise RunDirError(f"{str(p)!r} is not a directory: give a run directory, a comparison directory, a study "
                          "directory or a directory of runs")
    if (p / "compare.json").exists():
        return "comparison"
    if (p / "study.json").exists():  # (coevo.experiments.study.experiment.MARKER: written first, before any cell)
        return "study"
    if is_run(p):
        return "run"
    if any(is_run(c) for c in _subdirs(p)):
        return "runs"
    raise RunDirError(f"{str(p)!r} is not a coevo run directory (no run.json or workers/*/worker.json), a comparison "
                      f"(no compare.json), a study (no study.json) or a directory of runs")


def is_run(p: Path) -> bool:
    from coevo.rundir.layout import RunPaths

    paths = RunPaths(p)
    return paths.run_json.exists() or any((w / "worker.json").exists() for w in _subdirs(paths.workers_dir))


def _subdirs(p: Path) -> list[Path]:
    try:
        return sorted(c for c in Path(p).iterdir() if c.is_dir())
    except OSError:
        return []


class _WorkerFiles:
    def __init__(self, dir: Path) -> None:
        from coevo.rundir.layout import WorkerPaths

        self.paths = WorkerPaths(dir)
        self.meta: dict[str, Any] | None = None
        self.curve = Curve()
        self.curve_tail = Tail(self.paths.curve)
        self.adoptions = Tail(self.paths.adoptions)
        self.partners: dict[str, int] = {}
        self.last: dict[str, Any] = {}

    def read(self, task: str) -> None:
        if self.meta is None:
            self.meta = _read_json(self.paths.worker_json)
        behaviour = str((self.meta or {}).get("behaviour", self.paths.dir.name))
        rows = self.curve_tail.read()
        if self.curve_tail.reset:
            self.curve = Curve()
        for row in rows:
            try:
                g, best = int(row["generation"]), float(row["best_fitness"])
            except (KeyError, TypeError, ValueError):
                self.curve_tail.bad += 1
                continue
            sofar = row.get("best_so_far")
            self.curve.add(g, best, _status_measures(task, behaviour, row), None if sofar is None else float(sofar))
            self.last = row
        for row in self.adoptions.read():
            if isinstance(row.get("partner"), str) and isinstance(row.get("version"), int):
                self.partners[row["partner"]] = row["version"]

    def view(self, now: float, stale: float) -> dict[str, Any]:
        meta = self.meta or {}
        behaviour = str(meta.get("behaviour", self.paths.dir.name))
        done = _read_json(self.paths.done) if self.paths.done.exists() else None
        fresh = now - max(self.curve_tail.mtime, self.adoptions.mtime, mtime(self.paths.worker_json)) < stale
        state = "done" if done is not None else "running" if fresh else "stopped"
        measures = {k: col[-1] for k, col in self.curve.measures.items() if col and col[-1] is not None}
        ga = meta.get("ga")
        if not isinstance(ga, dict):
            ga = {}
        rejected = (done or {}).get("rejected") or {}
        return {"behaviour": behaviour, "worker": str(meta.get("worker", behaviour)), "regime": str(meta.get("regime", "?")),
                "generation": self.curve.generation[-1] if self.curve else 0, "generations": int(ga.get("generations", 0)),
                "best_fitness": self.curve.best[-1] if self.curve else 0.0, "measures": measures,
                "partner_versions": dict(self.partners), "rejected": sum(rejected.values()) if isinstance(rejected, dict) else 0,
                "rejected_by_reason": dict(rejected) if isinstance(rejected, dict) else {},
                "buffered": len((done or {}).get("unconfirmed") or []), "open": bool((done or {}).get("open", False)),
                "state": state, "heartbeat_age": None}


class RunFiles:
    """A run directory, followed: its workers' curves and states, the store's counts, the final measures."""

    def __init__(self, dir: Path, *, stale: float = STALE) -> None:
        from coevo.rundir.layout import RunPaths

        self.paths = RunPaths(Path(dir))
        self.stale = stale
        self._workers: dict[str, _WorkerFiles] = {}
        self._store: dict[str, Tail] = {}
        self._stored: dict[str, int] = {}
        self._external = Curve()
        self._performance = Tail(self.paths.execution.performance)
        self.settings: dict[str, Any] | None = None
        self._dynamics: Dynamics | None = None

    @property
    def run(self) -> str:
        return str((self.settings or {}).get("run", self.paths.name))

    def read(self) -> RunView:
        now = time.time()
        if self.settings is None:
            self.settings = _read_json(self.paths.run_json)
        s = self.settings or {}
        from coevo.tasks import DEFAULT_TASK

        task = str(s.get("task", DEFAULT_TASK))
        for d in _subdirs(self.paths.workers_dir):
            if d.name not in self._workers and (d / "worker.json").exists():
                self._workers[d.name] = _WorkerFiles(d)
        problems = []
        workers = []
        curves = {}
        for w in self._workers.values():
            w.read(task)
            v = w.view(now, self.stale)
            workers.append(v)
            curves[v["worker"]] = (v["behaviour"], w.curve)
        for f in self.paths.store_files():
            tail = self._store.setdefault(f.stem, Tail(f))
            n = len(tail.read())
            self._stored[f.stem] = n if tail.reset else self._stored.get(f.stem, 0) + n
        tails = [t for w in self._workers.values() for t in (w.curve_tail, w.adoptions)] + list(self._store.values())
        problems += [f"{t.path}: {t.bad} damaged lines skipped" for t in tails if t.bad]
        for row in self._performance.read():
            if isinstance(row.get("generation"), int) and isinstance(row.get("external"), (int, float)):
                self._external.add(row["generation"], float(row["external"]))
        summary = _read_json(self.paths.summary) if self.paths.summary.exists() else None
        final = {k: float(v) for k, v in ((summary or {}).get("measures") or {}).items() if isinstance(v, (int, float))}
        if summary is not None:
            state = "done" if "measures" in summary and not summary.get("interrupted") else "stopped"
        elif any(w["state"] == "running" for w in workers):
            state = "running"
        elif workers and all(w["state"] == "done" for w in workers):
            state = "done"
        else:
            state = "stopped" if workers else "starting"
        if s == {} and not self.paths.run_json.exists() and not workers:
            problems.append(f"{self.paths.dir} holds no run.json and no workers yet")
        broker = {"state": "files", "open": bool((summary or {}).get("open", s.get("key_file") is None)),
                  "stored": dict(self._stored), "rejected": {}, "dropped": 0, "degraded": ""}
        stamp = mtime(self.paths.dir / "dynamics" / "dynamics.json")
        if stamp != (self._dynamics.stamp if self._dynamics else 0.0):
            self._dynamics = Dynamics.read(self.paths.dir) if stamp else None
        return RunView(run=self.run, source="files", task=task, regime=str(s.get("regime", "?")), state=state,
                       workers=sorted(workers, key=lambda w: w["worker"]), broker=broker, curves=curves,
                       external=self._external if self._external else None, final=final, problems=problems,
                       dynamics=self._dynamics if state == "done" else None)


# ---------------------------------------------------------------- the bus
class BusSource:
    """The runs on the bus, each through a StatusBoard; their curves grown from the heartbeats.

    Without ``run`` it finds runs by their workers' (and CEL robots') liveliness tokens; boards are
    made on the polling thread, never inside a Zenoh callback.
    """

    def __init__(self, session: Session, *, run: str | None = None, stall: float = 3.0) -> None:
        from coevo.bus import keys
        from coevo.bus.status import StatusBoard

        self._board_type = StatusBoard
        self.session, self.stall, self.only = session, stall, run
        self.boards: dict[str, StatusBoard] = {}
        self.curves: dict[str, dict[str, tuple[str, Curve]]] = {}
        self.external: dict[str, Curve] = {}
        self._found: set[str] = set()
        self._lock = threading.Lock()
        self._decls: list[CallbackSubscriber] = []
        self.started = time.time()
        self.waiting = "no run seen on the bus yet (no worker token): is a run connected to this broker?"
        if run is not None:
            self._found.add(run)
        else:
            live = session.liveliness()
            for key in (f"{keys.ROOT}/*/alive/*/*", f"{keys.ROOT}/*/robot_alive/*"):
                self._decls.append(live.declare_subscriber(key, self._on_token, history=True))

    def _on_token(self, sample: Sample) -> None:
        from coevo.bus import keys

        run = keys.parse(str(sample.key_expr)).get("run", "")
        if keys.valid_id(run) and not run.startswith("_"):
            with self._lock:
                self._found.add(run)

    def poll(self) -> list[RunView]:
        with self._lock:
            new = self._found - set(self.boards)
        for run in sorted(new):
            self.boards[run] = self._board_type(self.session, run, stall=self.stall)
            self.curves[run] = {}
        return [self._view(run, board) for run, board in sorted(self.boards.items())]

    def _view(self, run: str, board: StatusBoard) -> RunView:
        workers = board.snapshot()
        robots = board.robots_view()
        broker = board.broker_view()
        curves = self.curves[run]
        for w in workers:
            _, c = curves.setdefault(w["worker"], (w["behaviour"], Curve()))
            c.add(w["generation"], w["best_fitness"], w.get("measures"))
        for r in robots:
            self.external.setdefault(run, Curve()).add(r["generation"], r["performance"])
        states = [w["state"] for w in workers + robots]
        state = ("done" if states and all(s == "done" for s in states) else
                 "running" if any(s in ("alive", "stalled") for s in states) else "stopped" if states else "starting")
        regimes = {w["regime"] for w in workers} - {"?"}
        task = _task_of([w["behaviour"] for w in workers])
        problems = []
        if board.rejected:
            problems.append(f"{board.rejected} messages on run {run}'s status keys rejected: "
                            + ("the --key-file is not this run's key, or they come from outside its roster"
                               if not board.open else "malformed or from a newer coevo"))
        if broker["state"] in ("down", "degraded") and state != "done":  # a run that ended normally has no broker left: not a problem
            problems.append(f"no broker on the bus for run {run} (its token is gone)" if broker["state"] == "down"
                            else f"the broker's store cannot write: {broker['degraded']}")
        if self.only is not None and not workers and not robots and time.time() - self.started > 5:
            problems.append(f"no worker of run {run} seen on the bus yet (is it running, and connected to this broker?)")
        return RunView(run=run, source="bus", task=task, regime=", ".join(sorted(regimes)) or "?", state=state, workers=workers,
                       robots=robots, broker=broker, curves=dict(curves), external=self.external.get(run),
                       problems=problems)

    def close(self) -> None:
        for b in self.boards.values():
            b.close()
        for d in self._decls:
            try:
                d.undeclare()
            except Exception as exc:  # noqa: BLE001 - the session went first: its declarations went with it
                log.debug("undeclare: %s", exc)


class LocalRuns:
    """The runs under a directory, as :mod:`coevo.runs.discover` finds them (``coevo dashboard`` with no
    ``--connect``): each live run followed on its own broker (a session and a :class:`BusSource`), let go when
    its files say it ended.  Looked for again every ``every`` s, so a run started after the page is followed too;
    the dashboard shows every run under the directory from its files (``Dashboard(runs_dir=ROOT, bus=this)``)."""

    def __init__(self, root: Path, *, stall: float = 3.0, every: float = 1.0) -> None:
        self.root, self.stall, self.every = Path(root), stall, every
        self.started = time.time()
        self.waiting = f"no run under {self.root} yet (no RUN/run.json): start one with coevo run --root {self.root}"
        self._next = 0.0
        self._followed: dict[str, tuple[ExitStack, BusSource]] = {}  # run -> (its session's exit, its source)

    def poll(self) -> list[RunView]:
        if time.monotonic() >= self._next:
            self._look()
            self._next = time.monotonic() + self.every
        return [v for _, source in self._followed.values() for v in source.poll()]

    def _look(self) -> None:
        from coevo.runs.discover import LIVE, find_runs

        found = {f.run: f for f in find_runs(self.root, followed=frozenset(self._followed))}
        for run in [r for r in self._followed if r not in found or found[r].state != LIVE]:
            self._let_go(run)
        for f in found.values():
            if f.state == LIVE and f.run not in self._followed:
                self._follow(f)

    def _follow(self, found: FoundRun) -> None:
        from coevo.bus.session import open_session
        from coevo.errors import CoevoError
        from coevo.runs.discover import follow_settings

        stack = ExitStack()
        try:
            conf, gate = follow_settings(found, connect_timeout=2.0)
            session = stack.enter_context(open_session(conf, what=f"session to run {found.run}'s broker", gate=gate))
        except CoevoError as exc:  # gone since it answered, or a key file it cannot read: shown from its files
            log.info("run %s not followed on the bus: %s", found.run, exc)
            stack.close()
            return
        self._followed[found.run] = (stack, BusSource(session, run=found.run, stall=self.stall))

    def _let_go(self, run: str) -> None:
        stack, source = self._followed.pop(run)
        source.close()
        stack.close()

    def close(self) -> None:
        for run in list(self._followed):
            self._let_go(run)


# ---------------------------------------------------------------- both
def _merge(bus: RunView, files: RunView) -> RunView:
    """A run seen on the bus and in its directory: the bus's live states, the files' complete curves and settings."""
    curves = dict(bus.curves)
    for wid, (b, c) in files.curves.items():
        if len(c) >= len(curves.get(wid, ("", Curve()))[1]):
            curves[wid] = (b, c)
    state = files.state if files.state == "done" or bus.state == "stopped" else bus.state
    return RunView(run=bus.run, source="bus+files", task=files.task, regime=files.regime if files.regime != "?" else bus.regime,
                   state=state, workers=bus.workers or files.workers,
                   robots=bus.robots, broker=bus.broker, curves=curves, external=files.external or bus.external,
                   final=files.final, problems=(bus.problems if state != "done" else []) + files.problems,
                   dynamics=files.dynamics)


#: A study's cells whose comparison is read: those a page asked for (:meth:`Dashboard.want`) in the last WANTED_FOR
#: seconds, at most SHOWN_CELLS of them (the newest asked), besides the one a new page opens on.
WANTED_FOR, SHOWN_CELLS = 10.0, 4


class Dashboard:
    """The page's data: the bus's runs, the runs under ``runs_dir`` or in ``target`` (a run, a comparison, a study or
    a directory of runs), merged; :meth:`refresh` reads what is new and moves :attr:`version` when the page changes."""

    def __init__(self, *, bus: BusSource | LocalRuns | None = None, runs_dir: Path | None = None, target: Path | None = None,
                 stale: float = STALE, title: str = "coevo dashboard", robot: RobotPanel | None = None,
                 robot_note: str = "") -> None:
        """``robot``: a :class:`~coevo.dashboard.robot.RobotPanel` drawing one run's robot, or None and
        ``robot_note`` saying why (on the page, where the robot would be)."""
        self.bus, self.stale, self.title, self.robot, self.robot_note = bus, stale, title, robot, robot_note
        self.runs_dir = Path(runs_dir) if runs_dir else None
        self.target = Path(target) if target else None
        self.kind = classify_dir(self.target) if self.target else None
        self._files: dict[Path, RunFiles] = {}
        self._comparison: ComparisonFiles | None = None
        self._study: StudyFiles | None = None
        if self.kind == "study" and self.target is not None:
            from coevo.dashboard.study import StudyFiles

            self._study = StudyFiles(self.target, stale=stale)  # a study.json that cannot be read: said at once
        self._wanted: dict[str, float] = {}  # a study's cell -> when a page last asked for its comparison
        self._across_held: AcrossDynamics | None = None
        self.view = View(title)
        self.version = 0
        self._print = ""
        self._lock = threading.Lock()

    def _run_dirs(self) -> list[Path]:
        if isinstance(self.bus, LocalRuns):
            return [d for d in _subdirs(self.bus.root) if is_run(d)]
        target = self.target
        if target is None:  # the bus's runs alone
            return []
        if self.kind == "run":
            return [target]
        if self.kind == "runs":
            return [d for d in _subdirs(target) if is_run(d)]
        if self.kind == "comparison":
            from coevo.dashboard.compare import ComparisonFiles

            if self._comparison is None:
                self._comparison = ComparisonFiles(target, stale=self.stale)
            return self._comparison.run_dirs()
        return []

    def want(self, cell: str) -> None:
        """A page shows this cell of the study: read its comparison (from the next refresh, while asked for)."""
        with self._lock:
            self._wanted[cell] = time.monotonic()

    def _shown(self) -> list[str]:
        now = time.monotonic()
        with self._lock:
            self._wanted = {c: t for c, t in self._wanted.items() if now - t < WANTED_FOR}
            return sorted(self._wanted, key=self._wanted.__getitem__, reverse=True)[:SHOWN_CELLS]

    def _files_for(self, d: Path) -> RunFiles:
        f = self._files.get(d)
        if f is None:
            f = self._files[d] = RunFiles(d, stale=self.stale)
        return f

    def refresh(self) -> bool:
        """Read the bus and the files; True (and a new version) if the page changed."""
        problems: list[str] = []
        runs: dict[str, RunView] = {}
        for d in self._run_dirs():
            v = self._files_for(d).read()
            runs[v.run] = v
        if self.bus is not None:
            for v in self.bus.poll():
                f = runs.get(v.run)
                if f is None and self.runs_dir is not None and is_run(self.runs_dir / v.run):
                    f = self._files_for(self.runs_dir / v.run).read()
                runs[v.run] = _merge(v, f) if f is not None else v
            if not runs and time.time() - self.bus.started > 5:
                problems.append(self.bus.waiting)
        comparison = self._comparison.read() if self._comparison is not None else None
        study = None
        if self._study is not None:
            study = self._study.read(self._shown())
            problems += study["problems"]
        robot = None
        if self.robot is not None:
            self.robot.update()
            robot = self.robot.picture
        view = View(self.title, runs=[runs[k] for k in sorted(runs)], comparison=comparison, study=study,
                    problems=problems,
                    robot=robot, robot_note=self.robot_note, across=self._across())
        fp = view.fingerprint()
        with self._lock:
            self.view = view
            if fp == self._print:
                return False
            self._print = fp
            self.version += 1
            return True

    def _across(self) -> AcrossDynamics | None:
        """The target folder's dynamics summary (a comparison or a directory of runs), read again when it changes."""
        if self.target is None or self.kind not in ("comparison", "runs"):
            return None
        stamp = mtime(self.target / "dynamics" / "runs.json")
        if stamp != (self._across_held.stamp if self._across_held else 0.0):
            self._across_held = AcrossDynamics.read(self.target) if stamp else None
        return self._across_held

    def current(self) -> tuple[int, View]:
        with self._lock:
            return self.version, self.view


def follow(dash: Dashboard, every: float, stop: threading.Event,
           on_error: Callable[[str | None], None] | None = None) -> None:
    """Refresh ``dash`` every ``every`` s until ``stop`` is set (the server's polling thread); ``on_error`` hears
    what went wrong, and None once a refresh succeeds again."""
    while not stop.is_set():
        try:
            dash.refresh()
            if on_error:
                on_error(None)
        except Exception as exc:  # noqa: BLE001 - the page says what went wrong and the dashboard goes on
            log.exception("dashboard refresh failed")
            if on_error:
                on_error(f"{type(exc).__name__}: {exc}")
        stop.wait(every)
