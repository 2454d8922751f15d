"""``coevo run``: a whole asynchronous run on one machine.

Starts ``coevo broker`` and one ``coevo worker`` per behaviour as separate
processes (``subprocess``: fork+exec, never a fork of a process with a session),
shows the live status, and at the end measures the final combined robot from the
store's latest policies.  Ctrl-C (or SIGTERM) asks the workers to stop, then ends
every child; nothing is left running.
"""

from __future__ import annotations

import json
import logging
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from coevo import keys
from coevo.agents.pacing import DEFAULT_MAX_LEAD
from coevo.behaviours import Behaviour
from coevo.bus import make_config, open_session, sigterm_as_exit
from coevo.config import GAConfig, WorldConfig
from coevo.errors import RunDirError
from coevo.messages import Control, PolicyUpdate, decode, encode
from coevo.robot import measure_robot
from coevo.rundir import write_csv, write_json
from coevo.status import StatusBoard

__all__ = ["free_port", "run_local", "fetch_latest"]

log = logging.getLogger(__name__)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _settings_args(world: WorldConfig, ga: GAConfig) -> list[str]:
    out: list[str] = []
    for k, v in world.model_dump(exclude_defaults=True).items():
        out += ["--world", f"{k}={json.dumps(v)}"]
    for k, v in ga.model_dump(exclude_defaults=True).items():
        out += ["--ga", f"{k}={json.dumps(v)}"]
    return out


def fetch_latest(session: Any, run: str, timeout: float = 5.0) -> dict[Behaviour, PolicyUpdate]:
    out: dict[Behaviour, PolicyUpdate] = {}
    for reply in session.get(keys.store_latest(run), timeout=timeout):
        if reply.ok is None:
            continue
        msg = decode(bytes(reply.ok.payload.to_bytes()))
        if isinstance(msg, PolicyUpdate) and msg.run == run:
            out[msg.behaviour] = msg
    return out


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
) -> dict[str, Any]:
    keys.check_id("run id", run)
    run_dir = Path(root) / run
    if run_dir.exists() and any(run_dir.iterdir()):
        raise RunDirError(f"run directory {str(run_dir)!r} already exists; choose another --run or --root")
    run_dir.mkdir(parents=True, exist_ok=True)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    py = [sys.executable, "-m", "coevo", "--log-level", log_level]
    write_json(run_dir / "run.json", {"run": run, "regime": regime, "seed": seed, "model": model, "max_lead": max_lead,
                                      "endpoint": endpoint,
                                      "world": world.model_dump(), "ga": ga.model_dump(), "started": time.time()})
    children: list[subprocess.Popen[bytes]] = []
    logs = run_dir / "logs"
    logs.mkdir(exist_ok=True)

    def spawn(name: str, args: list[str]) -> subprocess.Popen[bytes]:
        f = open(logs / f"{name}.log", "wb")
        p = subprocess.Popen(py + args, stdout=f, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        f.close()
        children.append(p)
        return p

    t0 = time.time()
    interrupted = False
    previous = sigterm_as_exit()
    try:
        spawn("broker", ["broker", "--listen", endpoint, "--data-dir", str(root)])
        workers = {
            b: spawn(f"worker-{b.value}", [
                "worker", "--behaviour", b.value, "--regime", regime, "--run", run, "--connect", endpoint,
                "--seed", str(seed + i), "--model", model, "--out", str(run_dir / "workers" / b.value),
                "--max-lead", "off" if max_lead is None else str(max_lead),
                *_settings_args(world, ga),
            ])
            for i, b in enumerate(Behaviour)
        }
        conf = make_config(mode="client", connect=[endpoint], connect_timeout=30)
        with open_session(conf, what="status session") as s:
            board = StatusBoard(s, run)
            try:
                while any(p.poll() is None for p in workers.values()):
                    board.changed.wait(0.5)
                    board.changed.clear()
                    if on_status:
                        on_status(board)
                    if children[0].poll() is not None:
                        raise RunDirError(f"the broker exited with status {children[0].returncode}; see {logs / 'broker.log'}")
            except KeyboardInterrupt:
                interrupted = True
                s.put(keys.control(run), encode(Control(run=run, command="stop", sent_at=time.time())))
                _wait(list(workers.values()), 15.0)
            if on_status:
                on_status(board)
            board.close()
            latest = fetch_latest(s, run)
        failed = {b.value: p.returncode for b, p in workers.items() if p.returncode not in (0, None)}
        if failed and not interrupted:
            raise RunDirError(f"workers failed {failed}; see {logs}")
    finally:
        signal.signal(signal.SIGTERM, previous)
        for p in reversed(children):
            if p.poll() is None:
                p.terminate()
        _wait(children, 10.0)
        for p in children:
            if p.poll() is None:
                p.kill()
                p.wait()
    summary: dict[str, Any] = {"run": run, "regime": regime, "seconds": time.time() - t0, "interrupted": interrupted,
                               "versions": {b.value: m.version for b, m in latest.items()},
                               "best_fitness": {b.value: m.fitness for b, m in latest.items()}}
    if len(latest) == 3:
        m = measure_robot(world, executive=latest[Behaviour.EXECUTIVE].ruleset(), tracking=latest[Behaviour.TRACKING].ruleset(),
                          docking=latest[Behaviour.DOCKING].ruleset(), epochs=measure_epochs, seed=seed + 99)
        summary["measures"] = m.as_dict()
        write_json(run_dir / "measures.json", m.as_dict())
    rows = []
    for b in Behaviour:
        f = run_dir / "workers" / b.value / "curve.jsonl"
        if f.exists():
            for line in f.read_text().splitlines():
                rows.append({"behaviour": b.value, **json.loads(line)})
    write_csv(run_dir / "curves.csv", rows)
    write_json(run_dir / "summary.json", summary)
    return summary


def _wait(procs: list[subprocess.Popen[bytes]], timeout: float) -> None:
    end = time.monotonic() + timeout
    for p in procs:
        try:
            p.wait(timeout=max(0.0, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            pass
