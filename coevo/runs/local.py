"""``coevo run``: a whole asynchronous run on one machine.

Starts ``coevo broker`` and one ``coevo worker`` per behaviour as separate
processes (``subprocess``: fork+exec, never a fork of a process with a session),
shows the live status, and at the end measures the final combined robot from the
store's latest policies.  Ctrl-C (or SIGTERM) asks the workers to stop, then ends
every child; nothing is left running.  ``coevo run --resume RUN_DIR`` starts a
new broker (its store reloads the run's policies from disk) and every worker with
``--resume`` (each continues from its last checkpoint), with the settings of the
run's ``run.json``.

:class:`LocalRun` owns the processes of one run directory; ``coevo chaos`` uses it
to kill and restart them.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coevo.bus import keys
from coevo.agents.pacing import DEFAULT_MAX_LEAD
from coevo.bus.session import make_config, open_session, sigterm_as_exit
from coevo.config import GAConfig
from coevo.tasks.fuel.settings import WorldConfig
from coevo.errors import RunDirError
from coevo.bus.messages import Control, PolicyUpdate, decode, encode
from coevo.runs.layout import read_jsonl, write_csv, write_json
from coevo.bus.status import StatusBoard
from coevo.tasks import get_task

__all__ = ["free_port", "wait_until", "end_processes", "LocalRun", "run_local", "fetch_latest", "read_run_json"]

log = logging.getLogger(__name__)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_until(check: Callable[[], Any], timeout: float, what: str | Callable[[], str]) -> Any:
    """Poll ``check`` every 50 ms until it returns something true (returned), or fail after ``timeout`` s."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = check()
        if value:
            return value
        time.sleep(0.05)
    raise RunDirError(f"timed out after {timeout:.0f} s waiting for {what() if callable(what) else what}")


def _settings_args(world: WorldConfig, ga: GAConfig) -> list[str]:
    out: list[str] = []
    for k, v in world.model_dump(exclude_defaults=True).items():
        out += ["--world", f"{k}={json.dumps(v)}"]
    for k, v in ga.model_dump(exclude_defaults=True).items():
        out += ["--ga", f"{k}={json.dumps(v)}"]
    return out


def fetch_latest(session: Any, run: str, timeout: float = 5.0) -> dict[str, PolicyUpdate]:
    out: dict[str, PolicyUpdate] = {}
    for reply in session.get(keys.store_latest(run), timeout=timeout):
        if reply.ok is None:
            continue
        msg = decode(bytes(reply.ok.payload.to_bytes()))
        if isinstance(msg, PolicyUpdate) and msg.run == run:
            out[msg.behaviour] = msg
    return out


def read_run_json(run_dir: Path) -> dict[str, Any]:
    """The settings of an existing run directory (for ``--resume``), checked."""
    f = Path(run_dir) / "run.json"
    if not f.exists():
        raise RunDirError(f"{str(run_dir)!r} holds no run.json: not a coevo run directory")
    try:
        meta = json.loads(f.read_text(encoding="utf-8"))
        meta["world"], meta["ga"] = WorldConfig(**meta["world"]), GAConfig(**meta["ga"])
        for k in ("run", "regime", "seed", "model", "max_lead"):
            meta[k]  # noqa: B018 - present?
    except (ValueError, KeyError, TypeError) as exc:
        raise RunDirError(f"{str(f)!r} cannot be read: {type(exc).__name__}: {exc}") from None
    if meta["run"] != Path(run_dir).name:
        raise RunDirError(f"{str(f)!r} is for run {meta['run']!r}, but the directory is named {Path(run_dir).name!r}")
    return meta


class LocalRun:
    """The broker and worker processes of one run directory on this machine."""

    def __init__(self, *, regime: str, run: str, root: Path, world: WorldConfig, ga: GAConfig, seed: int,
                 model: str = "best", max_lead: int | None = DEFAULT_MAX_LEAD, log_level: str = "WARNING",
                 endpoint: str | None = None, worker_env: dict[str, str] | None = None) -> None:
        self.regime, self.run, self.root = regime, keys.check_id("run id", run), Path(root)
        self.world, self.ga, self.seed, self.model, self.max_lead = world, ga, seed, model, max_lead
        self.dir = self.root / run
        self.endpoint = endpoint or f"tcp/127.0.0.1:{free_port()}"
        self.log_level = log_level
        self.worker_env = worker_env or {}
        self.broker: subprocess.Popen[bytes] | None = None
        self.task = get_task("fuel")
        self.workers: dict[str, subprocess.Popen[bytes]] = {}
        self._all: list[subprocess.Popen[bytes]] = []
        self.starts: dict[str, int] = {}  # process name -> times started

    def create(self) -> None:
        """Make the run directory with its ``run.json``; refuses one that is already in use."""
        if self.dir.exists() and any(self.dir.iterdir()):
            raise RunDirError(f"run directory {str(self.dir)!r} already exists; choose another --run or --root, "
                              f"or continue it with coevo run --resume {self.dir}")
        self.dir.mkdir(parents=True, exist_ok=True)
        write_json(self.dir / "run.json", {
            "run": self.run, "regime": self.regime, "seed": self.seed, "model": self.model, "max_lead": self.max_lead,
            "endpoint": self.endpoint, "world": self.world.model_dump(), "ga": self.ga.model_dump(), "started": time.time()})

    def _spawn(self, name: str, args: list[str], env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
        logs = self.dir / "logs"
        logs.mkdir(parents=True, exist_ok=True)
        self.starts[name] = self.starts.get(name, 0) + 1
        with open(logs / f"{name}.log", "ab") as f:  # appended: a restarted process keeps its predecessor's log
            f.write(f"--- start {self.starts[name]} at {time.strftime('%H:%M:%S')}\n".encode())
            f.flush()
            p = subprocess.Popen([sys.executable, "-m", "coevo", "--log-level", self.log_level, *args], stdout=f,
                                 stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                 env={**os.environ, **(env or {})})
        self._all.append(p)
        return p

    def start_broker(self) -> subprocess.Popen[bytes]:
        self.broker = self._spawn("broker", ["broker", "--listen", self.endpoint, "--data-dir", str(self.root)])
        return self.broker

    def worker_dir(self, b: str) -> Path:
        return self.dir / "workers" / b

    def start_worker(self, b: str, *, resume: bool, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
        i = self.task.behaviours.index(b)
        args = ["worker", "--behaviour", b, "--regime", self.regime, "--run", self.run, "--connect", self.endpoint,
                "--connect-timeout", "-1", "--seed", str(self.seed + i), "--model", self.model,
                "--out", str(self.worker_dir(b)), "--max-lead", "off" if self.max_lead is None else str(self.max_lead),
                *_settings_args(self.world, self.ga)]
        if resume:
            args.append("--resume")
        self.workers[b] = self._spawn(f"worker-{b}", args, {**self.worker_env, **(env or {})})
        return self.workers[b]

    def start(self, *, resume: bool) -> None:
        self.start_broker()
        for b in self.task.behaviours:
            self.start_worker(b, resume=resume)

    def workers_running(self) -> bool:
        return any(p.poll() is None for p in self.workers.values())

    def ask_stop(self, session: Any) -> None:
        session.put(keys.control(self.run), encode(Control(run=self.run, command="stop", sent_at=time.time())))

    def end_all(self) -> None:
        """Terminate whatever still runs (SIGTERM, then SIGKILL after 10 s)."""
        end_processes(self._all)

    def client_config(self) -> Any:
        return make_config(mode="client", connect=[self.endpoint], connect_timeout=30)

    def finish(self, latest: dict[str, PolicyUpdate], *, seconds: float, interrupted: bool,
               measure_epochs: int, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Measure the combined robot and write ``measures.json``, ``curves.csv`` and ``summary.json``."""
        summary: dict[str, Any] = {"run": self.run, "regime": self.regime, "seconds": seconds, "interrupted": interrupted,
                                   "versions": {b: m.version for b, m in latest.items()},
                                   "best_fitness": {b: m.fitness for b, m in latest.items()}, **(extra or {})}
        m = self.task.run_measures({b: u.ruleset() for b, u in latest.items()}, world=self.world, epochs=measure_epochs,
                                   seed=self.seed + 99)
        if m is not None:
            summary["measures"] = m
            write_json(self.dir / "measures.json", m)
        rows = [{"behaviour": b, **row} for b in self.task.behaviours
                for row in read_jsonl(self.worker_dir(b) / "curve.jsonl", missing_ok=True)]
        write_csv(self.dir / "curves.csv", rows)
        write_json(self.dir / "summary.json", summary)
        return summary


def run_local(
    *,
    regime: str,
    run: str,
    root: Path,
    world: WorldConfig,
    ga: GAConfig,
    seed: int,
    model: str = "best",
    max_lead: int | None = DEFAULT_MAX_LEAD,
    measure_epochs: int = 100,
    on_status: Callable[[StatusBoard], None] | None = None,
    log_level: str = "WARNING",
    resume: bool = False,
) -> dict[str, Any]:
    lr = LocalRun(regime=regime, run=run, root=root, world=world, ga=ga, seed=seed, model=model, max_lead=max_lead,
                  log_level=log_level)
    if resume:
        if not (lr.dir / "run.json").exists():
            raise RunDirError(f"{str(lr.dir)!r} holds no run.json: nothing to resume")
        (lr.dir / "summary.json").unlink(missing_ok=True)  # written again at the end
    else:
        lr.create()
    t0 = time.time()
    interrupted = False
    previous = sigterm_as_exit()
    try:
        lr.start(resume=resume)
        with open_session(lr.client_config(), what="status session") as s:
            board = StatusBoard(s, run)
            try:
                while lr.workers_running():
                    board.changed.wait(0.5)
                    board.changed.clear()
                    if on_status:
                        on_status(board)
                    if lr.broker is not None and lr.broker.poll() is not None:
                        raise RunDirError(f"the broker exited with status {lr.broker.returncode}; "
                                          f"see {lr.dir / 'logs' / 'broker.log'}")
            except KeyboardInterrupt:
                interrupted = True
                lr.ask_stop(s)
                _wait(list(lr.workers.values()), 15.0)
            if on_status:
                on_status(board)
            board.close()
            latest = fetch_latest(s, run)
        failed = {b: p.returncode for b, p in lr.workers.items() if p.returncode not in (0, None)}
        if failed and not interrupted:
            raise RunDirError(f"workers failed {failed}; see {lr.dir / 'logs'} (continue with --resume {lr.dir})")
    finally:
        signal.signal(signal.SIGTERM, previous)
        lr.end_all()
    return lr.finish(latest, seconds=time.time() - t0, interrupted=interrupted, measure_epochs=measure_epochs,
                     extra={"resumed": resume})


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
            pass
