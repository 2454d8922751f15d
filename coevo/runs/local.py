"""``coevo run``: a whole asynchronous run on one machine.

Writes the run's settings once to ``run.json`` (:class:`~coevo.rundir.settings.RunSettings`),
starts ``coevo broker`` and one ``coevo worker --settings RUN/run.json`` per behaviour
of the task as separate processes (``subprocess``: fork+exec, never a fork of a
process with a session), shows the live status, and at the end measures the run's
final policies together from the store's latest.  Ctrl-C or SIGTERM, to it or to its
process group (its children are in a group of their own and die with it: they hear only
``coevo run``), asks the workers to stop, then ends every child; nothing is left running.  ``coevo run
--resume RUN_DIR`` starts a new broker (its store reloads the run's policies from
disk; run.json records where it now listens) and every worker with ``--resume``
(each continues from its last checkpoint).

**Its processes are supervised** (:meth:`LocalRun.supervise`): the workers and the store
are built to outlive a broker (workers keep their versions and republish what the store
lacks; the store reloads from disk), and a worker to outlive itself (its checkpoint, written
before anything of a generation leaves it, and its logs cut back to it).  So a broker that
dies is started again on the same endpoint and data directory, and a worker that dies (any
exit but the run's own stop, status 0; a SIGTERM from outside too) again with ``--resume``, each at most
:data:`MAX_RESTARTS` times in a run (one that keeps dying has a cause to look at: its log,
``RUN/logs/NAME.log``), and the run goes on.  A worker that cannot start (it died before a
generation twice in a row with the same last words, e.g. a checkpoint it refuses) ends the
run at once with those words.  Before a resumed run starts anything, every checkpoint and
store file of the run is read as its worker and broker would (:meth:`LocalRun.verify`).

Trust: ``coevo run`` makes the run's secret key (``RUN/secret.key``, mode 0600;
:class:`~coevo.bus.auth.RunKey`) and a roster (each behaviour's worker id) before
anything starts; ``run.json`` names the key file, so every worker reads the key
from the file and nothing secret is on a command line; the broker finds it in its
data directory.  ``coevo run --open`` makes no key: the run accepts anyone's
messages and says so (a warning, ``"open": true`` in summary.json).  A run ends
*interrupted* (summary.json, exit status non-zero) whenever a worker stopped
before its last generation, whoever asked it to.

:class:`LocalRun` owns the processes of one run directory; ``coevo chaos`` uses it
to kill and restart them.
"""

from __future__ import annotations

import logging
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

from coevo.bus import keys
from coevo.bus.auth import RunKey
from coevo.bus.lifecycle import DIE_WITH_PARENT
from coevo.bus.messages import Control, PolicyUpdate
from coevo.bus.session import fetch_latest, make_config, open_session, put_control, Session
from coevo.bus.status import StatusBoard
from coevo.bus.trust import Gate
from coevo.errors import CoevoError, ConfigError, RunDirError, ServiceError
from coevo.rundir.layout import (RunPaths, cut_back, not_a_file, read_cases, read_json, read_jsonl, read_store,
                                 sigterm_stops, staged_dir, write_csv, write_json)
from coevo.rundir.code import record_code, refuse_other_code
from coevo.rundir.settings import RunSettings

__all__ = ["MAX_RESTARTS", "STOP_EXITS", "default_run_id", "free_port", "loopback_endpoint", "check_listen", "wait_until",
           "end_processes", "LocalRun", "run_local", "fetch_latest"]

log = logging.getLogger(__name__)

#: Times ``coevo run`` starts one of its processes (the broker, a worker) again after it died, in one run (then it
#: ends the run and says why).
MAX_RESTARTS = 5

#: A worker's exit statuses that are a stop, not a death: done, or stopped by the run's stop message (0).  Never
#: restarted.  A worker's SIGTERM or SIGINT can only come from outside the run (its children are in a process group
#: of their own, and ``coevo run`` stops them with its message): a death like any other, so it is started again.
STOP_EXITS = (0,)


def default_run_id(prefix: str) -> str:
    """A run id unless told: PREFIX-TIME (e.g. independent-20261123-154500)."""
    return f"{prefix}-{time.strftime('%Y%m%d-%H%M%S')}"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def loopback_endpoint() -> str:
    """A free loopback port as a Zenoh endpoint: where a run's broker listens unless told."""
    return f"tcp/127.0.0.1:{free_port()}"


def check_listen(endpoint: str) -> str:
    """``endpoint`` if a run's broker could listen there: a tcp/ or tls/ port that is free on this machine; else a
    ConfigError naming it (the broker would fail to start, and the run with it)."""
    from coevo.bus.session import check_endpoint

    check_endpoint(endpoint, listen=True)
    proto, _, address = endpoint.partition("/")
    if proto not in ("tcp", "tls"):  # coevo status and dashboard find a run by probing its broker's TCP port
        raise ConfigError(f"--listen {endpoint}: a run's broker listens on tcp/HOST:PORT or tls/HOST:PORT")
    host, _, port = address.split("#")[0].rpartition(":")
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        try:
            s.bind((host.strip("[]"), int(port)))
        except OSError as exc:
            raise ConfigError(f"--listen {endpoint}: cannot listen there ({exc.strerror or exc}); choose another "
                              "port, or leave --listen out for a free one") from None
    return endpoint


def wait_until(check: Callable[[], Any], timeout: float, what: str | Callable[[], str]) -> Any:
    """Poll ``check`` every 50 ms until it returns something true (returned), or fail after ``timeout`` s."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = check()
        if value:
            return value
        time.sleep(0.05)
    raise ServiceError(f"timed out after {timeout:.0f} s waiting for {what() if callable(what) else what}")


class LocalRun:
    """The broker and worker processes of one run directory on this machine."""

    COMMAND = "coevo run"  # what starts (and resumes) such a run

    def __init__(self, settings: RunSettings, *, root: Path, log_level: str = "WARNING",
                 worker_env: dict[str, str] | None = None, open_run: bool = False, listen: str | None = None) -> None:
        """``open_run``: make no key (the run accepts unauthenticated messages; for local experiments only);
        ``listen``: where the broker listens (default: a free loopback port)."""
        self.root = Path(root)
        self.paths = settings.paths(self.root)
        self.dir = self.paths.dir
        settings = settings.with_roster()
        self.settings = settings.restarted(listen or loopback_endpoint()) if settings.endpoint is None else settings
        self.open = open_run
        self.key: RunKey | None = None
        self.task = settings.the_task
        self.log_level = log_level
        self.worker_env = worker_env or {}
        self.broker: subprocess.Popen[bytes] | None = None
        self.workers: dict[str, subprocess.Popen[bytes]] = {}
        self._all: list[subprocess.Popen[bytes]] = []
        self.starts: dict[str, int] = {}  # process name -> times started
        self.restarts: Counter[str] = Counter()  # "broker" or behaviour -> times the supervisor started it again
        self._no_start: dict[str, str] = {}  # behaviour -> last words of its last start, if that did no generation
        self._progress_at_start: dict[str, int] = {}  # behaviour -> its progress when it was last started

    @property
    def run(self) -> str:
        return self.settings.run

    @property
    def endpoint(self) -> str:
        return str(self.settings.endpoint)  # never None: __init__ gives a run without one a free port

    @classmethod
    def resume(cls, run_dir: Path, *, log_level: str = "WARNING", worker_env: dict[str, str] | None = None,
               listen: str | None = None, force: bool = False) -> LocalRun:
        """The run in ``run_dir``, from its run.json, with a new broker endpoint (``listen``, default a free loopback
        port; recorded in run.json).  Every file the resume reads is read first (:meth:`verify`), and the code that
        ran it last (``code.json``) must be this code unless ``force``: a RunDirError naming the first problem leaves
        the directory byte for byte as it was."""
        lr = cls.resumable(run_dir, log_level=log_level, worker_env=worker_env, listen=listen)
        refuse_other_code(lr.dir, force=force, what="curves")
        lr.verify()  # before anything is written or started
        record_code(lr.dir)
        lr.settings.save(lr.paths.run_json)  # where its broker listens now: a stale endpoint would mislead status
        lr.paths.summary.unlink(missing_ok=True)  # written again at the end
        return lr

    @classmethod
    def resumable(cls, run_dir: Path, *, log_level: str = "WARNING", worker_env: dict[str, str] | None = None,
                  listen: str | None = None) -> LocalRun:
        """The run in ``run_dir`` as :meth:`resume` continues it (its run.json and key read), nothing changed or
        verified yet: :meth:`problems` says what would stop it."""
        paths = RunPaths(Path(run_dir))
        if paths.dir.exists() and not paths.dir.is_dir():
            raise RunDirError(f"{str(paths.dir)!r} is a file, not a run directory (nothing to resume)")
        if not paths.run_json.exists():
            raise RunDirError(f"{str(paths.dir)!r} holds no run.json: not a coevo run directory (nothing to resume)")
        settings = RunSettings.load(paths.run_json)
        if settings.run != paths.name:
            raise RunDirError(f"{str(paths.run_json)!r} is for run {settings.run!r}, but the directory is named {paths.name!r}")
        key_path = settings.key_path(paths.dir)
        # A new incarnation: every message of the previous one (a captured stop, old policies) is stale to this one.
        settings = settings.model_copy(update={"incarnation": settings.incarnation + 1})
        lr = cls(settings.restarted(listen or loopback_endpoint()), root=paths.dir.parent, log_level=log_level,
                 worker_env=worker_env, open_run=key_path is None)
        if key_path is not None:
            try:
                lr.key = RunKey.load(key_path, run=settings.run)
            except ConfigError as exc:
                raise RunDirError(f"cannot resume {str(paths.dir)!r}: {exc}") from None
        else:
            log.warning("run %s is OPEN (its run.json names no key): its messages are not authenticated", settings.run)
        return lr

    def create(self) -> None:
        """Make the run directory with its ``run.json``; refuses one that is already in use."""
        if self.dir.exists() and not self.dir.is_dir():
            raise RunDirError(f"{str(self.dir)!r} is a file, not a run directory; choose another --run or --root")
        if self.dir.exists() and any(self.dir.iterdir()):
            raise RunDirError(f"run directory {str(self.dir)!r} already exists; choose another --run or --root, "
                              f"or continue it with {self.resume_command}")
        self.settings = self.settings.model_copy(update={"incarnation": 1})
        if self.open:
            self.settings = self.settings.model_copy(update={"key_file": None})
            log.warning("run %s is OPEN (--open): no key, its messages are not authenticated; anyone who reaches its "
                        "bus can steer it", self.run)
        # Made beside it and renamed whole: a stop signal (or a kill) while it is made leaves no run directory that
        # neither resumes (no run.json) nor can be made again (not empty).
        with staged_dir(self.dir) as tmp:
            staged = RunPaths(tmp)
            if not self.open:
                self.key = RunKey.create(self.run)
                self.key.save(staged.key_file)  # mode 0600; run.json names it, the workers read it from there
                self.settings = self.settings.model_copy(update={"key_file": RunPaths.KEY_FILE})
            self.settings.save(staged.run_json)
            record_code(tmp)

    def _spawn(self, name: str, args: list[str], env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
        self.paths.logs_dir.mkdir(parents=True, exist_ok=True)
        self.starts[name] = self.starts.get(name, 0) + 1
        with open(self.paths.log(name), "ab") as f, _sigint_ignored():  # appended: a restart keeps its predecessor's log
            f.write(f"--- start {self.starts[name]} at {time.strftime('%H:%M:%S')}\n".encode())
            f.flush()
            p = subprocess.Popen([sys.executable, "-m", "coevo", "--log-level", self.log_level, *args], stdout=f,
                                 stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, process_group=0,
                                 env={**os.environ, **(env or {}), DIE_WITH_PARENT: str(os.getpid())})
        self._all.append(p)
        return p

    def gate(self) -> Gate:
        """What this run's own processes accept: its key (none if open), its roster, its generations."""
        return self.settings.gate(self.key)

    @property
    def resume_command(self) -> str:
        """The command line that continues this run from its checkpoints (every advice to resume quotes it)."""
        return f"{self.COMMAND} --resume {self.dir}"

    def start_broker(self) -> subprocess.Popen[bytes]:
        # The broker finds the run's key in its data directory (RUN/secret.key): nothing secret on its command line.
        self.broker = self._spawn("broker", ["broker", "--listen", self.endpoint, "--data-dir", str(self.root),
                                             *(["--open"] if self.open else [])])
        return self.broker

    def supervise(self) -> list[str]:
        """Start again each process of the run that died: the broker on any exit (same endpoint, same data
        directory), a worker on any exit but a stop (:data:`STOP_EXITS`), with ``--resume``.  Who was started
        again ("broker", behaviours).  A RunDirError ends the run: a process that died after :data:`MAX_RESTARTS`
        restarts, or a worker that cannot start."""
        again = []
        if self.broker is not None and self.broker.poll() is not None:
            self._may_restart("broker", self.broker.returncode)
            self.start_broker()
            again.append("broker")
        for b, p in list(self.workers.items()):
            if p.poll() is not None and p.returncode not in STOP_EXITS:
                self._may_restart(b, p.returncode)
                self.start_worker(b, resume=True)
                again.append(b)
        return again

    def _may_restart(self, who: str, status: int) -> None:
        """Count a restart of ``who`` (exited with ``status``), or raise the RunDirError that ends the run: it used
        up its restarts, or (a worker) it died before a generation twice in a row with the same last words."""
        name = self.log_name(who)
        what = "the broker" if who == "broker" else f"the {who} worker"
        words, exit_ = last_words(self.paths.log(name)), exit_text(status)
        if who != "broker":
            before = self._no_start.pop(who, None)
            if self._progress(who) <= self._progress_at_start.get(who, 0):  # it did no generation
                if before == words:
                    raise RunDirError(f"{what} cannot start: {words or exit_} (it {exit_} twice before a generation; "
                                      f"see {self.paths.log(name)})")
                self._no_start[who] = words
        if self.restarts[who] >= MAX_RESTARTS:
            raise RunDirError(f"{what} {exit_} after {self.restarts[who]} restarts{': ' + words if words else ''}; "
                              f"see {self.paths.log(name)} (continue with {self.resume_command})")
        self.restarts[who] += 1
        log.warning("run %s: %s %s; starting it again (restart %d of at most %d)", self.run, what, exit_,
                    self.restarts[who], MAX_RESTARTS)

    def verify(self) -> None:
        """Read every file of the run that its resume reads, as its processes will (:meth:`problems`), before a
        resume starts anything: a problem is a RunDirError naming the first (and how many more), and nothing is
        changed.  Then the one repair a resume makes: a damaged policy store file is a replica of what the workers
        published (their ``published.jsonl``), so it is set aside whole (``NAME.cut-N``, said in one line) and the
        workers publish its versions again.  A store file's torn last line (a crash mid-write, cut by the broker) is
        not damage."""
        problems = self.problems()
        if problems:
            more = f" ({len(problems) - 1} more problems: coevo check {self.dir} lists them)" if len(problems) > 1 else ""
            raise RunDirError(f"cannot resume {self.dir}: {problems[0]}; nothing was started or changed{more}")
        for f in self.paths.store_files():
            damaged = _damage(f, read_store)
            if damaged:
                kept = cut_back(f, 0)
                log.warning("%s; kept as %s, its versions are published again from the workers' published.jsonl",
                            damaged[0], kept)

    def processes(self) -> dict[str, Any]:
        """The run's processes that keep a directory of their own, as they would be made to resume (by the name
        :meth:`start_worker` takes): each has ``resume_problems()``.  Nothing is started or changed."""
        from coevo.runs.kinds import kind_of_settings

        worker = kind_of_settings(self.settings).worker()
        return {b: worker(self.settings, behaviour=b, out_dir=self.worker_dir(b), conf=self.client_config(),
                          resume=True, run_key=self.key) for b in self.task.behaviours}

    def problems(self) -> list[str]:
        """What would stop a resume of this run, one line a problem, found by reading every file it reads as its
        processes will and changing nothing: each process's directory (settings, checkpoint, the logs up to what the
        checkpoint saw: :meth:`Worker.resume_problems <coevo.agents.worker.Worker.resume_problems>`), the store's
        case files (the learners read them), and the places its processes and its end write to (logs/, summary.json,
        measures.json, curves.csv, the store's files), which must not be taken by something that is no file."""
        paths = self.paths
        problems = not_a_file([paths.summary, paths.measures, paths.curves_csv, *paths.store_files(),
                               *paths.case_files()])
        problems += [f"{d} is not a directory" for d in (paths.logs_dir, paths.store_dir, paths.workers_dir)
                     if (d.exists() or d.is_symlink()) and not d.is_dir()]
        if paths.logs_dir.is_dir():
            problems += not_a_file([paths.log(self.log_name(b)) for b in ["broker", *self.processes_names()]])
        if problems:
            return problems
        try:
            procs = self.processes()
        except CoevoError as exc:  # a roster or key that does not fit the run's workers
            return [str(exc)]
        for proc in procs.values():
            problems += proc.resume_problems()
        for f in paths.case_files():
            problems += _damage(f, read_cases)
        return problems

    def processes_names(self) -> list[str]:
        """The names of the run's processes beside its broker (:meth:`start_worker` takes them)."""
        return list(self.task.behaviours)

    def worker_dir(self, b: str) -> Path:
        return self.paths.worker(b).dir

    def log_name(self, b: str) -> str:
        """The name of a process of the run (the broker, or a behaviour's worker): its log is ``logs/NAME.log``."""
        return "broker" if b == "broker" else f"worker-{b}"

    def worker_args(self, b: str) -> list[str]:
        """The command line (after ``coevo``) of behaviour ``b``'s worker."""
        return ["worker", "--settings", str(self.paths.run_json), "--behaviour", b, "--connect", self.endpoint,
                "--connect-timeout", "-1", "--out", str(self.worker_dir(b))]

    def progress_log(self, b: str) -> Path:
        """The log a process of the run writes a line to per generation done (a worker's ``curve.jsonl``)."""
        return self.paths.worker(b).curve

    def _progress(self, b: str) -> int:
        """How far ``b``'s :meth:`progress_log` has grown (bytes): a start that did not grow it did no generation."""
        f = self.progress_log(b)
        return f.stat().st_size if f.exists() else 0

    def start_worker(self, b: str, *, resume: bool, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
        self._progress_at_start[b] = self._progress(b)
        args = [*self.worker_args(b), *(["--resume"] if resume else [])]
        self.workers[b] = self._spawn(self.log_name(b), args, {**self.worker_env, **(env or {})})
        return self.workers[b]

    def start(self, *, resume: bool) -> None:
        self.start_broker()
        for b in self.task.behaviours:
            self.start_worker(b, resume=resume)

    def workers_running(self) -> bool:
        return any(p.poll() is None for p in self.workers.values())

    def ask_stop(self, session: Session) -> None:
        key = keys.control(self.run)
        put_control(session, key, self.gate().seal(Control(run=self.run, command="stop", sent_at=time.time()), key))

    def unfinished(self) -> dict[str, int]:
        """Workers that stopped before their last generation: behaviour -> generations done (from done.json)."""
        out = {}
        for b in self.task.behaviours:
            w = self.paths.worker(b)
            done = read_json(w.done, what="worker directory (its done.json)") if w.done.exists() else {}
            if not done.get("finished"):
                out[b] = int(done.get("generations", len(read_jsonl(w.curve, missing_ok=True))))
        return out

    def unstored(self, latest: Mapping[str, PolicyUpdate]) -> dict[str, Any]:
        """Behaviours whose published versions the broker's store does not hold at the end (it lost or never took
        them): behaviour -> the versions its worker could not deliver (done.json), or "none stored"."""
        out: dict[str, Any] = {}
        for b in self.task.behaviours:
            w = self.paths.worker(b)
            done = read_json(w.done, what="worker directory (its done.json)") if w.done.exists() else {}
            if done.get("unconfirmed") or (b not in latest and done.get("versions_published")):
                out[b] = done.get("unconfirmed") or "none stored"
        return out

    def end_all(self) -> None:
        """Terminate whatever still runs (SIGTERM, then SIGKILL after 10 s)."""
        end_processes(self._all)

    def client_config(self) -> Any:
        return make_config(mode="client", connect=[self.endpoint], connect_timeout=30)

    def finish(self, latest: dict[str, PolicyUpdate], *, seconds: float, interrupted: bool,
               measure_epochs: int, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Measure the combined robot and write ``measures.json``, ``curves.csv`` and ``summary.json``."""
        summary: dict[str, Any] = {"run": self.run, "regime": self.settings.regime, "seconds": seconds, "interrupted": interrupted,
                                   "open": self.open,
                                   "versions": {b: m.version for b, m in latest.items()},
                                   "best_fitness": {b: m.fitness for b, m in latest.items()},
                                   "unstored": self.unstored(latest), **(extra or {})}
        m = self.task.run_measures({b: u.ruleset() for b, u in latest.items()}, world=self.settings.world_config(),
                                   epochs=measure_epochs, seed=self.settings.seed + 99)
        if m is not None:
            summary["measures"] = m
            write_json(self.paths.measures, m)
        rows = [{"behaviour": b, **row} for b in self.task.behaviours
                for row in read_jsonl(self.paths.worker(b).curve, missing_ok=True)]
        write_csv(self.paths.curves_csv, rows)
        write_json(self.paths.summary, summary)
        return summary


def run_local(
    lr: LocalRun,
    *,
    resume: bool,
    measure_epochs: int = 100,
    on_status: Callable[[StatusBoard], None] | None = None,
) -> dict[str, Any]:
    """Run ``lr`` (made with :class:`LocalRun` and created, or :meth:`LocalRun.resume`) to its end; its summary."""
    if measure_epochs < 1:
        raise ConfigError(f"--measure-epochs must be at least 1, got {measure_epochs}")
    run = lr.run
    t0 = time.time()
    interrupted = False
    with sigterm_stops() as settle:  # a SIGTERM (to coevo run, or to its process group: its children have their own) as Ctrl-C
        try:
            lr.start(resume=resume)
            with ExitStack() as stack:
                s, stop_at_once = _status_session(lr, stack)
                # the restarts shown beside each process's state; the run's generations until a worker's first heartbeat
                board = StatusBoard(s, run, restarts=lr.restarts, generations=lr.settings.ga.generations)
                try:
                    if stop_at_once:
                        raise KeyboardInterrupt  # asked while the session opened: stopped in order, as below
                    while True:
                        board.changed.wait(0.5)
                        board.changed.clear()
                        if on_status:
                            on_status(board)
                        lr.supervise()  # before asking who still runs: a worker that died last is started again
                        if not lr.workers_running():
                            break
                except KeyboardInterrupt:
                    settle()  # a Ctrl-C's stop is not cut short by a SIGTERM either
                    interrupted = True
                    board.stopping()  # the workers that end now stop, they do not die
                    lr.ask_stop(s)
                    _wait(list(lr.workers.values()), 15.0)
                settle()  # the run is ending in order from here: a SIGTERM has nothing left to stop
                if on_status:
                    on_status(board)
                board.close()
                latest = fetch_latest(s, run)
            failed = {b: p.returncode for b, p in lr.workers.items() if p.returncode not in (0, None)}
            if failed and not interrupted:
                raise RunDirError(f"workers failed {failed}; see {lr.paths.logs_dir} (continue with {lr.resume_command})")
        finally:
            lr.end_all()
        # Whoever stopped them (Ctrl-C here, or a stop message from elsewhere): a worker short of its
        # last generation makes the run interrupted, never a finished one.
        stopped_early = lr.unfinished()
        if stopped_early and not interrupted:
            log.warning("run %s: workers stopped before their last generation: %s", run, stopped_early)
        return lr.finish(latest, seconds=time.time() - t0, interrupted=interrupted or bool(stopped_early),
                         measure_epochs=measure_epochs,
                         extra={"resumed": resume, "stopped_early": stopped_early, "stopped_here": interrupted})


def _status_session(lr: LocalRun, stack: ExitStack) -> tuple[Session, bool]:
    """The run's status session, entered on ``stack``, and whether a Ctrl-C or SIGTERM came while it opened (its
    workers already run).  Their stop is a message on the bus, so such a stop waits for the session and is then made
    in order, each worker's done.json written; a second one while it still opens ends the wait."""
    asked = False
    while True:
        try:
            return stack.enter_context(open_session(lr.client_config(), what="status session", gate=lr.gate())), asked
        except KeyboardInterrupt:
            if asked:
                raise
            asked = True
            print("stopping: the run's workers are asked to stop once its status session is open", file=sys.stderr,
                  flush=True)


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while a child starts: it keeps that across exec (and Python then makes no KeyboardInterrupt of
    it).  A terminal's Ctrl-C reaches the whole process group; this way only ``coevo run`` takes it and stops its
    children in order (a stop message: each worker ends its generation and writes its done.json; then the final
    measures from the broker, still up; then SIGTERM), as after a Ctrl-C to it alone.  Only the main thread can
    change a signal's handler; started from another, a child takes SIGINT as usual."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _damage(f: Path, reader: Callable[..., Any]) -> list[str]:
    """What is wrong with store or case file ``f`` read by ``reader``, one line a problem; a torn last line that
    starts as a record is not (the broker cuts it)."""
    problems: list[str] = []
    reader(f, problems=problems, torn_ok=True)
    return problems


def last_words(log_file: Path) -> str:
    """The error a process's latest start ended with: the last line of its log after the last ``--- start`` mark,
    when it names an error (``RunDirError: ...``, a traceback's last line); else ''."""
    try:
        text = log_file.read_bytes().decode("utf-8", "replace")
    except OSError:
        return ""
    lines = [x.strip() for x in text.rsplit("--- start ", 1)[-1].splitlines()[1:] if x.strip()]
    return lines[-1] if lines and re.match(r"[\w.]*(Error|Exception)\b", lines[-1]) else ""


def exit_text(status: int) -> str:
    """A process's exit as words: 'exited with status 2', 'was killed by SIGKILL'."""
    if status >= 0:
        return f"exited with status {status}"
    try:
        return f"was killed by {signal.Signals(-status).name}"
    except ValueError:
        return f"was killed by signal {-status}"


def end_processes(procs: list[subprocess.Popen[bytes]], timeout: float = 10.0) -> None:
    """SIGTERM every one still running (last started first), then SIGKILL what is left after ``timeout`` s."""
    for p in reversed(procs):
        if p.poll() is None:
            p.terminate()
    _wait(procs, timeout)
    for p in procs:
        if p.poll() is None:
            p.kill()
            p.wait()


def _wait(procs: list[subprocess.Popen[bytes]], timeout: float) -> None:
    end = time.monotonic() + timeout
    for p in procs:
        try:
            p.wait(timeout=max(0.0, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            continue  # the caller kills what is left
