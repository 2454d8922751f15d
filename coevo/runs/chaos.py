"""``coevo chaos``: a whole run on this machine while random processes are killed and restarted.

One fault at a time, at random (seeded) moments while the workers evolve:

* ``kill-worker``: SIGKILL a running worker, wait a moment, restart it with
  ``--resume`` (it continues from its last checkpoint);
* ``kill-broker``: SIGKILL the broker, wait a moment, restart it on the same
  endpoint (its store reloads from disk; the workers reconnect and republish what
  it missed);
* ``pause-worker``: SIGSTOP a worker for a moment, then SIGCONT (a frozen process);
* ``broker-dies``: SIGKILL the broker and leave it to the run's supervisor
  (:meth:`~coevo.runs.local.LocalRun.supervise`, what ``coevo run`` does) to start it again.

A process that dies on its own (not by chaos) is started again by that supervisor too, and reported.

For every worker kill it measures how long the status board took to show the
worker dead.  A run of a kind with modules of its own (a CEL run: ``coevo chaos --learner cel``) has a third kind of
process among the workers, its execution module (``execution``), killed, paused and
restarted like a worker.  At the end it checks the run directory (:mod:`coevo.runs.check`: every
generation, every published version in the store, replay exact) and writes
``chaos.json`` beside the run's other files.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coevo.bus.session import open_session, sigterm_as_exit
from coevo.bus.status import StatusBoard
from coevo.errors import ConfigError, RunDirError, ServiceError
from coevo.runs.check import check_run
from coevo.runs.kinds import kind_of_settings
from coevo.rundir.layout import write_json
from coevo.runs.local import LocalRun, end_processes, fetch_latest, wait_until
from coevo.rundir.settings import RunSettings

__all__ = ["FAULTS", "ChaosPlan", "run_chaos", "summary_lines"]

log = logging.getLogger(__name__)

FAULTS = ("kill-worker", "kill-broker", "pause-worker", "broker-dies")
CHAOS_REPORT = "chaos.json"  # in the run directory


@dataclass(frozen=True)
class ChaosPlan:
    faults: int = 8  # how many to inject (fewer if the run ends first)
    kinds: tuple[str, ...] = FAULTS
    gap: tuple[float, float] = (1.0, 4.0)  # seconds between one fault's recovery and the next fault
    down: tuple[float, float] = (0.5, 3.0)  # seconds a killed process stays down / a paused one stays stopped
    seed: int = 0

    def __post_init__(self) -> None:
        if self.faults < 0:
            raise ConfigError(f"--faults must be 0 or more, got {self.faults}")
        bad = [k for k in self.kinds if k not in FAULTS]
        if bad or not self.kinds:
            raise ConfigError(f"unknown fault kind {bad[0] if bad else '(none)'!r} (use {', '.join(FAULTS)})")
        for name, (lo, hi) in (("--gap", self.gap), ("--down", self.down)):
            if not 0 <= lo <= hi:
                raise ConfigError(f"{name} {lo} {hi}: need 0 <= MIN <= MAX seconds")


@dataclass
class ChaosLog:
    events: list[dict[str, Any]] = field(default_factory=list)
    counts: Counter[str] = field(default_factory=Counter)

    def add(self, kind: str, **info: Any) -> None:
        self.counts[kind] += 1
        self.events.append({"time": time.time(), "fault": kind, **info})
        log.info("chaos: %s %s", kind, info)


def run_chaos(settings: RunSettings, *, root: Path, plan: ChaosPlan, measure_epochs: int = 20,
              on_event: Callable[[str], None] | None = None, log_level: str = "WARNING") -> dict[str, Any]:
    """A whole run of ``settings`` under ``root`` while ``plan``'s faults strike; then checked (chaos.json)."""
    if measure_epochs < 1:
        raise ConfigError(f"--measure-epochs must be at least 1, got {measure_epochs}")
    lr: LocalRun = kind_of_settings(settings).run()(settings, root=root, log_level=log_level)
    lr.create()
    run = lr.run
    rng = np.random.default_rng([plan.seed, 4242])
    chaos = ChaosLog()
    say = on_event or (lambda text: None)
    t0 = time.time()
    previous = sigterm_as_exit()
    try:
        lr.start(resume=False)
        with open_session(lr.client_config(), what="chaos status session") as s:
            board = StatusBoard(s, run)
            n = len(lr.task.behaviours)
            wait_until(lambda: len([w for w in board.snapshot() if w["generation"] >= 1]) == n or not lr.workers_running(),
                       120, "every worker's first generation")
            next_fault = time.monotonic() + rng.uniform(*plan.gap)
            while lr.workers_running():
                for who in lr.supervise():
                    say(f"{who} died on its own; the run's supervisor started it again")
                if chaos.counts.total() < plan.faults and time.monotonic() >= next_fault:
                    _inject(lr, board, rng, plan, chaos, say)
                    next_fault = time.monotonic() + rng.uniform(*plan.gap)
                time.sleep(0.1)
            latest = fetch_latest(s, run)
            board.close()
        if lr.broker is not None:
            end_processes([lr.broker])
    finally:
        signal.signal(signal.SIGTERM, previous)
        lr.end_all()
    seconds = time.time() - t0
    say("checking the run directory")
    check = check_run(lr.dir)
    report = {
        "run": run, "regime": settings.regime, "seconds": seconds, "faults": dict(chaos.counts), "events": chaos.events,
        "unplanned_restarts": dict(lr.restarts), "starts": dict(lr.starts), "complete": check.ok, "problems": check.problems,
        "facts": check.facts,
    }
    lr.finish(latest, seconds=seconds, interrupted=False, measure_epochs=measure_epochs, extra={"chaos": dict(chaos.counts)})
    write_json(lr.dir / CHAOS_REPORT, report)
    return report


def _view(board: StatusBoard, name: str) -> dict[str, Any]:
    """What the board shows of a worker (by behaviour) or of a CEL run's execution module ("execution")."""
    if name == "execution":
        return next(iter(board.robots_view()), {"state": "unknown", "generation": None})
    return next((w for w in board.snapshot() if w["behaviour"] == name), {"state": "unknown", "generation": None})


def _running_workers(lr: LocalRun) -> list[str]:
    return [b for b, p in lr.workers.items() if p.poll() is None]


def _inject(lr: LocalRun, board: StatusBoard, rng: np.random.Generator, plan: ChaosPlan, chaos: ChaosLog,
            say: Callable[[str], None]) -> None:
    kind = str(rng.choice(plan.kinds))
    down = float(rng.uniform(*plan.down))
    running = _running_workers(lr)
    broker_fault = kind in ("kill-broker", "broker-dies")
    if not broker_fault and not running:
        return
    broker = lr.broker if broker_fault else None
    if broker_fault and (broker is None or broker.poll() is not None):
        return  # no broker process to kill (it is being restarted)
    if broker is not None and kind == "broker-dies":
        broker.send_signal(signal.SIGKILL)
        broker.wait()
        t_kill = time.monotonic()
        lr.supervise()  # what coevo run's loop does when it sees it gone
        wait_until(lambda: board.broker_up, 60, "the broker the supervisor restarted")
        say(f"the broker died; the run's supervisor restarted it ({time.monotonic() - t_kill:.1f} s to up)")
        chaos.add(kind, up_after=round(time.monotonic() - t_kill, 2))
        return
    if broker is not None and kind == "kill-broker":
        gens = {w["behaviour"]: w["generation"] for w in board.snapshot()}
        broker.send_signal(signal.SIGKILL)
        broker.wait()
        say(f"killed the broker (workers at {gens}); down for {down:.1f} s")
        time.sleep(down)
        lr.start_broker()
        wait_until(lambda: board.broker_up, 60, "the restarted broker")
        chaos.add(kind, down=round(down, 2), generations=gens)
        return
    b = running[int(rng.integers(len(running)))]
    p = lr.workers[b]
    who = "execution module" if b == "execution" else f"{b} worker"
    gen = _view(board, b)["generation"]
    if kind == "pause-worker":
        p.send_signal(signal.SIGSTOP)
        say(f"paused the {who} at generation {gen} for {down:.1f} s")
        time.sleep(down)
        p.send_signal(signal.SIGCONT)
        chaos.add(kind, behaviour=b, generation=gen, down=round(down, 2))
        return
    t_kill = time.monotonic()
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    try:
        wait_until(lambda: _view(board, b)["state"] == "dead", 10, "dead")
        seen = time.monotonic() - t_kill
    except (RunDirError, ServiceError):  # wait_until says ServiceError: a loaded machine ended the run here
        seen = None  # the broker was restarting, or the board missed it: reported as not seen
    say(f"killed the {who} at generation {gen} (status showed it dead after "
        f"{'-' if seen is None else f'{seen * 1000:.0f} ms'}); down for {down:.1f} s")
    time.sleep(down)
    lr.start_worker(b, resume=True)
    wait_until(lambda: _view(board, b)["state"] in ("alive", "done"), 60, f"the restarted {who}")
    chaos.add(kind, behaviour=b, generation=gen, down=round(down, 2),
              dead_seen_ms=None if seen is None else round(seen * 1000, 1))


def summary_lines(report: dict[str, Any]) -> list[str]:
    lines = [f"chaos run {report['run']} ({report['regime']}): {report['seconds']:.0f} s, faults "
             + (", ".join(f"{n} {k}" for k, n in sorted(report["faults"].items())) or "none")]
    seen = [e["dead_seen_ms"] for e in report["events"] if e.get("dead_seen_ms") is not None]
    if seen:
        lines.append(f"worker deaths shown by status after {min(seen):.0f}-{max(seen):.0f} ms")
    lines.append("run directory complete: every generation, every published version stored, replay exact"
                 if report["complete"] else "run directory INCOMPLETE:\n  " + "\n  ".join(report["problems"]))
    lines.append(json.dumps(report["facts"]))
    return lines

