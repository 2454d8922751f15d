"""One replicate: what it runs, what it writes and reads, and how it is run where it lands.

A replicate is a whole run (a ``coevo run`` with its own broker and workers on the loopback of the
host it lands on, its own run key) or a function; it writes one folder, ``output``, relative to the
experiment's folder.  :func:`execute` runs it under a *root*: the experiment's folder itself (this
machine, or a cluster with a shared directory), or a fresh temporary folder on a Dask worker, into
which its inputs are unpacked and from which its output comes back as a tar payload.

What a replicate runs is decided where it runs (``command(root)``), so a replicate run again after its
Dask worker died continues from the checkpoints it finds there (``coevo run --resume``) when the root
is shared, and starts afresh when they were lost with the worker's disk.
"""

from __future__ import annotations

import ctypes
import io
import shutil
import signal
import socket
import subprocess
import tarfile
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Replicate", "Outcome", "execute", "pack", "unpack", "running"]


@dataclass(frozen=True)
class Replicate:
    """One of an experiment's replicates.  Every callable must be picklable (module-level functions or
    :func:`functools.partial` of them): on a cluster they travel to the worker."""

    name: str  # unique in the experiment; its log is logs/NAME.log
    output: str  # the folder it writes, relative to the experiment's folder
    finished: Callable[[Path], bool]  # does the folder under this root hold it finished?
    command: Callable[[Path], list[str]] | None = None  # root -> argv, decided where it runs
    function: Callable[..., Any] | None = None  # function(root, **kwargs), writes under root/output
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    inputs: tuple[str, ...] = ()  # what it reads, relative to the experiment's folder (shipped to a worker)
    after: tuple[str, ...] = ()  # replicates that must have finished first
    weight: int = 2  # half-slots of --jobs it takes on this machine (a live run 2, an offline learner 1)
    cost: int = 1  # units of progress it is worth (e.g. worker generations)
    progress: Callable[[Path], int] | None = None  # units done so far, read from the folder under a root

    def __post_init__(self) -> None:
        if (self.command is None) == (self.function is None):
            raise ValueError(f"replicate {self.name}: give a command or a function, not both or neither")


@dataclass
class Outcome:
    """What came of running a replicate once."""

    name: str
    ok: bool
    reason: str = ""  # why not, in one line
    returncode: int | None = None
    seconds: float = 0.0  # inside execute, where it ran
    host: str = ""
    wall: float = 0.0  # from submission to its output back in the experiment's folder (set by the runner)
    log: bytes | None = None  # the log, when it was written away from the experiment's folder
    payload: bytes | None = None  # the output folder as a tar, when it was written away from it


#: Processes the replicates of this process are running (to stop them when the experiment is interrupted).
running: set[subprocess.Popen[bytes]] = set()


def _die_with_parent() -> None:
    """In the child: SIGTERM it when the thread that started it dies (a Dask worker killed mid-run takes its
    run with it: ``coevo run`` turns SIGTERM into a clean stop of its broker and workers)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def _last_line(log: bytes) -> str:
    lines = [ln.strip() for ln in log.decode("utf-8", "replace").splitlines() if ln.strip()]
    return lines[-1][:300] if lines else "no output"


def _run(rep: Replicate, root: Path, log_file: Path) -> tuple[bool, int | None, str]:
    """Run it under ``root``, its output to ``log_file``; (finished, exit status, why not).  ``root`` is made
    absolute first: a command runs with ``root`` as its working directory, so a relative one would be read twice
    (``--out runs/x`` wrote into ``runs/x/runs/x``)."""
    root = Path(root).resolve()
    try:
        log_file.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # said as the replicate's failure, not as a traceback from inside a Dask worker
        return False, None, f"cannot make its log's folder: {type(exc).__name__}: {exc}"
    if rep.function is not None:
        with open(log_file, "w", encoding="utf-8") as fh:
            try:
                rep.function(root, **rep.kwargs)
            except Exception as exc:  # the replicate's own failure: reported, not retried
                fh.write(f"{type(exc).__name__}: {exc}\n")
                return False, None, f"{type(exc).__name__}: {exc}"
        return (True, None, "") if rep.finished(root) else (False, None, "it returned without finishing its output")
    if rep.command is None:
        raise TypeError(f"replicate {rep.name} has neither a function nor a command to run")
    argv = rep.command(root)
    with open(log_file, "wb") as fh:
        p = subprocess.Popen(argv, stdout=fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, cwd=root,
                             preexec_fn=_die_with_parent)
        running.add(p)
        try:
            code = p.wait()
        finally:
            running.discard(p)
    if code == 0 and rep.finished(root):
        return True, code, ""
    why = f"exit status {code}" if code != 0 else "it exited 0 without finishing its output"
    return False, code, f"{why}: {_last_line(log_file.read_bytes())}"


def execute(rep: Replicate, root: str | None = None, inputs: bytes | None = None) -> Outcome:
    """Run ``rep`` once.  With ``root`` (a folder this host shares with the experiment), in place, its log in
    ``root/logs``; without, in a temporary folder holding ``inputs`` (a tar), and its output and log come back
    in the :class:`Outcome`."""
    t0 = time.perf_counter()
    host = socket.gethostname()
    if root is not None:
        ok, code, why = _run(rep, Path(root), Path(root) / "logs" / f"{rep.name}.log")
        return Outcome(rep.name, ok, why, code, time.perf_counter() - t0, host)
    with tempfile.TemporaryDirectory(prefix=f"coevo-{rep.name}-") as tmp:
        work = Path(tmp) / "exp"
        work.mkdir()
        if inputs:
            unpack(inputs, work)
        log_file = Path(tmp) / "replicate.log"
        ok, code, why = _run(rep, work, log_file)
        payload = pack(work, rep.output) if (work / rep.output).exists() else None
        return Outcome(rep.name, ok, why, code, time.perf_counter() - t0, host, log=log_file.read_bytes(), payload=payload)


def pack(root: Path, *relative: str) -> bytes:
    """The named files and folders under ``root`` as an uncompressed tar (run folders are small; gzip would cost
    more CPU than it saves on a LAN)."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w") as tar:
        for rel in relative:
            if (Path(root) / rel).exists():
                tar.add(Path(root) / rel, arcname=rel)
    return buf.getvalue()


def unpack(data: bytes, root: Path, *, replace: str | None = None) -> None:
    """Unpack a :func:`pack` tar under ``root``; ``replace``: a folder or file removed first (a half-done copy)."""
    old = None if replace is None else Path(root) / replace
    if old is not None and old.is_dir():
        shutil.rmtree(old)
    elif old is not None and old.exists():
        old.unlink()
    with tarfile.open(fileobj=io.BytesIO(data), mode="r") as tar:
        tar.extractall(root, filter="data")

