"""The runs under a directory (``./runs`` unless told), each said to be live, finished or unreachable at once.

``coevo status`` and ``coevo dashboard`` without ``--connect`` start here.  A run directory's ``run.json``
names where its broker listens (``endpoint``: ``coevo run`` writes it at every start, a hand-started
worker the endpoint it connects to).  A run is

* **finished** when its files say it ended: ``summary.json`` (``coevo run`` and ``coevo cel`` write it
  at their end, interrupted or not), or every worker's ``done.json``.  It is shown from its files.
* **live** when it has not finished and its broker's endpoint accepts a connection within ``timeout``
  seconds (a refused connection on this machine is known in a millisecond).  It is followed on the bus.
* **unreachable** otherwise: its broker is gone before the run ended (killed, or the machine restarted),
  or it listens where this host cannot reach.

Nothing waits longer than ``timeout``, and the endpoints are tried side by side.
"""

from __future__ import annotations

import json
import socket
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.rundir.layout import RunPaths

__all__ = ["PROBE_TIMEOUT", "LIVE", "FINISHED", "UNREACHABLE", "FoundRun", "ended", "find_runs", "find_run", "answers", "follow_hint", "follow_settings"]

PROBE_TIMEOUT = 1.0  # seconds an endpoint gets to accept a connection
LIVE, FINISHED, UNREACHABLE = "live", "finished", "unreachable"


@dataclass(frozen=True)
class FoundRun:
    """One run directory, as found: its state and, finished, how it ended (``done`` or ``stopped``)."""

    dir: Path
    run: str
    endpoint: str | None
    state: str
    ended: str = ""
    generations: str = ""  # each worker's generations done of its total, "tracking 50/50, docking 50/50"
    modified: float = 0.0  # run.json's time: the newest run is the one most recently (re)started

    def line(self) -> str:
        """What it is, in one line: finished from its files, or why it cannot be followed."""
        gens = f" ({self.generations})" if self.generations else ""
        if self.state == FINISHED:
            return f"run {self.run}: {self.ended}{gens}, from its files in {self.dir}"
        if self.state == UNREACHABLE:
            where = f"its broker at {self.endpoint} does not answer" if self.endpoint else "its run.json names no broker"
            return f"run {self.run}: unreachable, {where} and its files show no end{gens}"
        return f"run {self.run}: live, its broker at {self.endpoint}{gens} (coevo status --run {self.run})"

    def as_dict(self) -> dict[str, Any]:
        return {"run": self.run, "dir": str(self.dir), "endpoint": self.endpoint, "state": self.state,
                "ended": self.ended or None, "generations": self.generations}


def _json(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _lines(path: Path) -> int:
    try:
        with open(path, "rb") as f:
            return sum(1 for line in f if line.strip())
    except OSError:
        return 0


def _progress(paths: RunPaths) -> tuple[str, bool]:
    """Each worker's generations done of its total, and whether every worker wrote its done.json."""
    parts, all_done = [], True
    try:
        workers = paths.workers()
    except RunDirError:  # none started yet
        return "", False
    for w in workers:
        ga = _json(w.worker_json).get("ga")
        total = ga.get("generations") if isinstance(ga, dict) else None
        parts.append(f"{w.dir.name} {_lines(w.curve)}/{total if total is not None else '?'}")
        all_done = all_done and bool(_json(w.done).get("finished"))
    return ", ".join(parts), bool(parts) and all_done


def ended(d: Path) -> str:
    """``done`` or ``stopped`` when the files of run directory ``d`` say it ended, else ``''``."""
    paths = RunPaths(d)
    if paths.summary.exists():
        return "stopped" if _json(paths.summary).get("interrupted") else "done"
    return "done" if _progress(paths)[1] else ""


def answers(endpoint: str | None, timeout: float = PROBE_TIMEOUT) -> bool:
    """Whether something accepts a connection at ``endpoint`` within ``timeout`` s (tcp/ and tls/ endpoints are tried;
    any other kind counts as reachable: the session that follows it says if it is not)."""
    if not endpoint:
        return False
    proto, _, address = endpoint.partition("/")
    if proto not in ("tcp", "tls"):
        return True
    host, _, port = address.split("#")[0].rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            return True
    except (OSError, ValueError):
        return False


def _found(d: Path, timeout: float, followed: frozenset[str] = frozenset()) -> FoundRun:
    paths = RunPaths(d)
    settings = _json(paths.run_json)
    endpoint = settings.get("endpoint") if isinstance(settings.get("endpoint"), str) else None
    generations = _progress(paths)[0]
    how = ended(d)
    run = str(settings.get("run", d.name))
    state = FINISHED if how else LIVE if run in followed or answers(endpoint, timeout) else UNREACHABLE
    try:
        modified = paths.run_json.stat().st_mtime
    except OSError:
        modified = 0.0
    return FoundRun(dir=d, run=run, endpoint=endpoint, state=state, ended=how,
                    generations=generations, modified=modified)


def find_runs(root: Path, *, timeout: float = PROBE_TIMEOUT, followed: frozenset[str] = frozenset()) -> list[FoundRun]:
    """Every run directory under ``root`` (one with a run.json), oldest first; [] if ``root`` is not a directory.
    The runs named in ``followed`` (already followed on their broker) are live until their files say they ended."""
    try:
        dirs = sorted(d for d in Path(root).iterdir() if RunPaths(d).run_json.is_file())
    except OSError:
        return []
    with ThreadPoolExecutor(max_workers=min(16, len(dirs) or 1)) as pool:
        found = list(pool.map(lambda d: _found(d, timeout, followed), dirs))
    return sorted(found, key=lambda f: (f.modified, f.run))


def find_run(root: Path, run: str, *, timeout: float = PROBE_TIMEOUT) -> FoundRun | None:
    """Run ``run`` under ``root`` (``root/run/run.json``), or None."""
    d = Path(root) / run
    return _found(d, timeout) if RunPaths(d).run_json.is_file() else None


def follow_hint(run: str, root: Path) -> list[str]:
    """The two commands that follow ``run`` made under ``root``, as ``coevo run`` prints them."""
    flag = "" if Path(root) == Path("runs") else f" --runs-dir {root}"
    return [f"coevo status --run {run}{flag}", f"coevo dashboard{flag}"]


def follow_settings(found: FoundRun, *, key_file: Path | None = None, connect_timeout: float = 5.0) -> tuple[Any, Any]:
    """(zenoh client config, gate) to follow a live run found here: its endpoint, and its key (``key_file``, else the
    one its directory holds) so that only its authenticated heartbeats are shown; no key: (config, None), unverified."""
    from coevo.bus.auth import RunKey
    from coevo.bus.session import make_config
    from coevo.bus.trust import Gate

    conf = make_config(mode="client", connect=[str(found.endpoint)], connect_timeout=connect_timeout)
    key = key_file or RunPaths(found.dir).key_file
    return conf, Gate(key=RunKey.load(key, run=found.run)) if key.exists() else None
