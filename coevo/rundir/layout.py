"""The run directory: its layout (every path, in one place), its readers, and atomic writes.

    RUN/run.json                 the run's settings (coevo.rundir.settings.RunSettings)
    RUN/secret.key               the run's secret key, mode 0600 (coevo.bus.auth.RunKey; absent in an open run)
    RUN/store/BEHAVIOUR.jsonl    the broker's store: every PolicyUpdate of a behaviour, in arrival order
    RUN/store/cases/BEHAVIOUR.jsonl   the case base in the store: every CaseUpdate (a CEL run)
    RUN/execution/               a CEL run's execution module (:class:`ExecutionPaths`)
    RUN/workers/BEHAVIOUR/       one worker's directory (:class:`WorkerPaths`)
    RUN/logs/PROCESS.log         each process's output, appended over restarts
    RUN/summary.json, measures.json, curves.csv     written by coevo run at the end

A ``coevo learn`` directory (:class:`LearnPaths`) holds config.json, curve.csv/json,
best.rules, measures.json, timing.json, best.png and its partners' rules.

A directory written in one go (``coevo learn``) is built in a temporary sibling and
renamed into place when complete, so a failed or interrupted command leaves no
half-written directory under the name asked for; files are written atomically
(temp file, fsync, rename).
"""

from __future__ import annotations

import csv
import glob
import json
import os
import shutil
import signal
import socket
import tempfile
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from coevo.errors import ConfigError, RunDirError

if TYPE_CHECKING:
    from pydantic import BaseModel

    from coevo.policy.rules import RuleSet


__all__ = ["RunPaths", "WorkerPaths", "ExecutionPaths", "LearnPaths", "read_store", "read_cases", "line_problems", "not_a_file", "append_durably", "cut_back", "staged_dir", "sigterm_stops", "ensure_dir", "read_jsonl", "json_object", "read_json", "write_bytes",
           "write_json",
           "write_text", "write_csv"]


def _umask() -> int:
    mask = os.umask(0)  # read at import, before any thread runs: umask can only be read by setting it
    os.umask(mask)
    return mask


_UMASK = _umask()
_FILE_MODE = 0o666 & ~_UMASK


@dataclass(frozen=True)
class WorkerPaths:
    """A worker's directory (``RUN/workers/BEHAVIOUR/``; see :mod:`coevo.agents.worker` for what each holds)."""

    dir: Path

    #: The append-only logs a checkpoint records the sizes of (cut back to them on --resume).
    LOGS = ("curve.jsonl", "adoptions.jsonl", "published.jsonl")
    #: A CEL learner's two more (:mod:`coevo.cel_service.learner`).
    CEL_LOGS = ("changes.jsonl", "cases.jsonl")

    @property
    def worker_json(self) -> Path:
        return self.dir / "worker.json"

    @property
    def curve(self) -> Path:
        return self.dir / "curve.jsonl"

    @property
    def adoptions(self) -> Path:
        return self.dir / "adoptions.jsonl"

    @property
    def published(self) -> Path:
        return self.dir / "published.jsonl"

    @property
    def checkpoint(self) -> Path:
        return self.dir / "checkpoint.msgpack"

    @property
    def machines(self) -> Path:
        """The machine the worker ran on, one line per start (:mod:`coevo.rundir.machine`)."""
        return self.dir / "machines.jsonl"

    @property
    def changes(self) -> Path:
        """A CEL learner's capability changes: after how many generations it took which list, and its restart."""
        return self.dir / "changes.jsonl"

    @property
    def cases(self) -> Path:
        """A CEL learner's case base: the cases it found in the store at its start, then the ones it stored."""
        return self.dir / "cases.jsonl"

    @property
    def best_rules(self) -> Path:
        return self.dir / "best.rules"

    @property
    def done(self) -> Path:
        return self.dir / "done.json"

    #: What every worker.json holds (more fields may follow).
    META_KEYS = ("behaviour", "regime", "run", "worker", "seed", "model", "world", "ga")

    def meta(self) -> dict[str, Any]:
        """The worker's settings (worker.json), checked for the fields the run tools read."""
        meta = read_json(self.worker_json, what="worker directory (its worker.json)")
        missing = [k for k in self.META_KEYS if k not in meta]
        if missing or not isinstance(meta.get("ga"), dict) or not isinstance(meta.get("world"), dict):
            raise RunDirError(f"{str(self.worker_json)!r} is not a worker's settings: "
                              f"{'missing ' + ', '.join(missing) if missing else 'ga and world must be objects'}")
        from coevo.tasks import saved_settings  # the tasks, only when a worker's settings are read

        try:
            return saved_settings(meta)  # as the worker learned, if saved before a setting existed or where it was
        except ConfigError as exc:
            raise RunDirError(f"{str(self.worker_json)!r}: {exc}") from None


@dataclass(frozen=True)
class ExecutionPaths:
    """A CEL execution module's directory (``RUN/execution/``; see :mod:`coevo.cel_service.robot` for what each holds)."""

    dir: Path

    #: The append-only logs a checkpoint records the sizes of (cut back to them on --resume).
    LOGS = ("performance.jsonl", "changes.jsonl", "policies.jsonl")

    @property
    def performance(self) -> Path:
        return self.dir / "performance.jsonl"

    @property
    def changes(self) -> Path:
        return self.dir / "changes.jsonl"

    @property
    def policies(self) -> Path:
        return self.dir / "policies.jsonl"

    @property
    def checkpoint(self) -> Path:
        return self.dir / "checkpoint.msgpack"

    @property
    def machines(self) -> Path:
        """The machine the worker ran on, one line per start (:mod:`coevo.rundir.machine`)."""
        return self.dir / "machines.jsonl"

    @property
    def meta_json(self) -> Path:
        return self.dir / "execution.json"

    @property
    def done(self) -> Path:
        return self.dir / "done.json"


@dataclass(frozen=True)
class LearnPaths:
    """The directory of one ``coevo learn`` (written in one go, see :func:`staged_dir`)."""

    dir: Path

    @property
    def config(self) -> Path:
        return self.dir / "config.json"

    @property
    def curve_csv(self) -> Path:
        return self.dir / "curve.csv"

    @property
    def curve_json(self) -> Path:
        return self.dir / "curve.json"

    @property
    def best_rules(self) -> Path:
        return self.dir / "best.rules"

    @property
    def adoptions(self) -> Path:
        return self.dir / "adoptions.jsonl"

    @property
    def measures(self) -> Path:
        return self.dir / "measures.json"

    @property
    def timing(self) -> Path:
        return self.dir / "timing.json"

    @property
    def picture(self) -> Path:
        return self.dir / "best.png"

    def partner_rules(self, behaviour: str) -> Path:
        """The rule set a partner was played with (so ``coevo show DIR`` can replay them together)."""
        return self.dir / f"{behaviour}.rules"


@dataclass(frozen=True)
class RunPaths:
    """A run directory's paths (the module docstring draws the layout)."""

    dir: Path

    @staticmethod
    def of(root: Path, run: str) -> RunPaths:
        """The run ``run`` under ``root`` (a broker's --data-dir or coevo run's --root)."""
        return RunPaths(Path(root) / run)

    @property
    def name(self) -> str:
        return self.dir.name

    @property
    def run_json(self) -> Path:
        return self.dir / "run.json"

    #: The key file's name, as run.json's ``key_file`` names it (relative to the run directory).
    KEY_FILE = "secret.key"

    @property
    def key_file(self) -> Path:
        return self.dir / self.KEY_FILE

    @property
    def store_dir(self) -> Path:
        return self.dir / "store"

    def store_file(self, behaviour: str) -> Path:
        return self.store_dir / f"{behaviour}.jsonl"

    def store_files(self) -> list[Path]:
        """The store's policy files (one per behaviour)."""
        return sorted(self.store_dir.glob("*.jsonl"))

    @property
    def seen_file(self) -> Path:
        """The broker's memory of the messages of this run it took (one line each: key, sender, sequence number),
        kept so that a broker started again still refuses a replay of them (:class:`coevo.bus.freshness.KeptSeen`)."""
        return self.store_dir / "seen.log"

    def case_file(self, behaviour: str) -> Path:
        return self.store_dir / "cases" / f"{behaviour}.jsonl"

    def case_files(self) -> list[Path]:
        return sorted((self.store_dir / "cases").glob("*.jsonl"))

    @property
    def execution(self) -> ExecutionPaths:
        return ExecutionPaths(self.dir / "execution")

    @property
    def workers_dir(self) -> Path:
        return self.dir / "workers"

    def worker(self, behaviour: str) -> WorkerPaths:
        return WorkerPaths(self.workers_dir / str(behaviour))

    def workers(self) -> list[WorkerPaths]:
        """The directories of the workers that started (those with a worker.json), by behaviour name;
        none at all is a RunDirError (not a run directory)."""
        if not self.dir.exists():
            raise RunDirError(f"no such directory: {str(self.dir)!r}")
        if not self.dir.is_dir():
            raise RunDirError(f"{str(self.dir)!r} is a file, not a run directory")
        found = [WorkerPaths(p) for p in sorted(self.workers_dir.glob("*")) if (p / "worker.json").exists()]
        if not found:
            raise RunDirError(f"{str(self.dir)!r} holds no workers/*/worker.json: not a coevo run directory")
        return found

    def final_rules(self, behaviours: Sequence[str], given: Mapping[str, RuleSet] | None = None) -> dict[str, RuleSet]:
        """The workers' final ``best.rules`` of ``behaviours`` (those in ``given`` taken from it instead): the
        run's whole robot. A missing one is a RunDirError naming every missing file."""
        from coevo.policy.text import read_rule_file

        given = given or {}
        rules: dict[str, RuleSet] = {}
        missing = []
        for b in behaviours:
            best = self.worker(b).best_rules
            if b in given:
                rules[b] = given[b]
            elif best.exists():
                rules[b] = read_rule_file(best, b)
            else:
                missing.append(str(best))
        if missing:
            raise RunDirError(f"run directory {str(self.dir)!r} holds no policies for its robot: missing "
                              f"{', '.join(missing)} (is the run finished?)")
        return rules

    @property
    def logs_dir(self) -> Path:
        return self.dir / "logs"

    def log(self, process: str) -> Path:
        return self.logs_dir / f"{process}.log"

    @property
    def summary(self) -> Path:
        return self.dir / "summary.json"

    @property
    def measures(self) -> Path:
        return self.dir / "measures.json"

    @property
    def curves_csv(self) -> Path:
        return self.dir / "curves.csv"


def read_store(path: Path, *, problems: list[str] | None = None, model: type[BaseModel] | None = None,
               torn_ok: bool = False) -> list[Any]:
    """The policies of one store file or publication log (``model``: the messages of another kind, e.g.
    CaseUpdate), in order, validated; damaged lines as :func:`read_jsonl` says (the broker reloading its
    store, and ``coevo check``, give ``problems`` and keep the rest).  ``torn_ok``: a torn last line that
    starts as a record (a crash mid-write, which the broker cuts when it opens the file) is not damage."""
    from coevo.bus.messages import PolicyUpdate

    return _read_lines(Path(path), model or PolicyUpdate, missing_ok=False, problems=problems, as_models=True,
                       torn_ok=torn_ok)


def read_cases(path: Path, *, problems: list[str] | None = None, torn_ok: bool = False) -> list[Any]:
    """The CaseUpdates of one case file (the store's, or a CEL learner's log), in order, validated."""
    from coevo.bus.messages import CaseUpdate

    return read_store(path, problems=problems, model=CaseUpdate, torn_ok=torn_ok)


def not_a_file(paths: Sequence[Path]) -> list[str]:
    """A problem for each of ``paths`` that something other than a regular file holds (a directory, a socket):
    what a command is about to write or replace there would fail half-way."""
    return [f"{p} is not a file (a directory or another kind of file is in its place); move it aside"
            for p in map(Path, paths) if (p.exists() or p.is_symlink()) and not p.is_file()]


def read_json(path: Path, *, what: str) -> dict[str, Any]:
    """A JSON object from ``path``; a missing, unreadable or non-object file is a RunDirError naming it."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"), parse_constant=_non_finite)
    except FileNotFoundError:
        raise RunDirError(f"{str(path)!r} is missing: not a complete {what}") from None
    except (OSError, ValueError, RecursionError) as exc:  # not UTF-8, not JSON (NaN included), nested too deeply
        raise RunDirError(f"{str(path)!r} cannot be read ({what}): {exc}") from None
    if not isinstance(data, dict):
        raise RunDirError(f"{str(path)!r} is not a JSON object ({what})")
    return data


#: In a staged directory, who is writing it: "HOST PID" (so that a later one can tell an abandoned copy).
_OWNER = ".owner"


def _abandoned(tmp: Path) -> bool:
    """Whether the staged directory ``tmp`` was left by a process of this host that no longer lives (killed, so
    it could not remove it).  One of another host, or without an owner, is never taken for abandoned."""
    try:
        host, pid = (tmp / _OWNER).read_text(encoding="utf-8").split()
        if host != socket.gethostname():
            return False
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return True
    except (OSError, ValueError):  # no owner file, unreadable, or a process of another user: leave it
        return False
    return False


@contextmanager
def staged_dir(final: Path) -> Iterator[Path]:
    """Yield a temporary directory that becomes ``final`` only if the block succeeds.

    A stop signal removes it; a killed process cannot, so the copies that killed processes of this host left
    beside ``final`` are removed when the next one starts."""
    final = Path(final)
    if final.exists() and not final.is_dir():
        raise RunDirError(f"output directory {str(final)!r} is a file; choose another --out")
    if final.exists() and any(final.iterdir()):
        raise RunDirError(f"output directory {str(final)!r} already exists and is not empty; choose another --out")
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        for old in final.parent.glob(f".{glob.escape(final.name)}.*.partial"):
            if old.is_dir() and _abandoned(old):
                shutil.rmtree(old, ignore_errors=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".partial", dir=final.parent))
        tmp.chmod(0o777 & ~_UMASK)  # mkdtemp makes it private; the finished directory is as open as any other
        (tmp / _OWNER).write_text(f"{socket.gethostname()} {os.getpid()}", encoding="utf-8")
    except OSError as exc:
        raise RunDirError(f"cannot create output directory {str(final)!r}: {exc.strerror or exc}") from exc
    try:
        with sigterm_stops():
            yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    (tmp / _OWNER).unlink()
    if final.exists():
        final.rmdir()
    os.replace(tmp, final)




_sigterm_depth = 0  # how many sigterm_stops blocks this process's main thread is inside


def _sigterm_stop(signum: int, frame: object) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise KeyboardInterrupt(f"signal {signum}")


def _sigterm_settle() -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)


@contextmanager
def sigterm_stops() -> Iterator[Callable[[], None]]:
    """SIGTERM as a stop (KeyboardInterrupt), as Ctrl-C is, while inside: a staged directory is removed, a run or an
    experiment stops in order.  The first SIGTERM raises; later ones are ignored until the block ends, so that the
    stop it started is not cut short (a group's SIGTERM and then a backend's own reach a run twice).  It yields
    ``settle()``: SIGTERM ignored from then on to the block's end (what is left is an orderly end, nothing to stop).
    Only where SIGTERM has its default action (a command's own handler is kept, and ``settle`` does nothing) and in
    the main thread (the only one that may set a handler); by default SIGTERM ends the process at once (and a staged
    ``.NAME.*.partial`` stays behind until the next command there).  A block inside another is the outer one's: its
    ``settle()`` holds to the outer block's end, which alone gives SIGTERM its default action back (so a command
    that stops from its first line to its last leaves no moment in between to a plain SIGTERM)."""
    global _sigterm_depth
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    if _sigterm_depth:
        yield _sigterm_settle
        return
    if signal.getsignal(signal.SIGTERM) != signal.SIG_DFL:
        yield lambda: None
        return
    signal.signal(signal.SIGTERM, _sigterm_stop)
    _sigterm_depth += 1
    try:
        yield _sigterm_settle
    finally:
        _sigterm_depth -= 1
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def ensure_dir(path: Path, *, what: str) -> Path:
    """``path`` as a directory, created if missing; a file there or a place that cannot hold one is a RunDirError
    naming ``what`` (e.g. ``--out``) and the path."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise RunDirError(f"{what} {str(path)!r} is a file, not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunDirError(f"{what} {str(path)!r}: cannot create the directory: {exc.strerror or exc}") from None
    return path


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``path`` atomically: a temporary sibling, fsynced, renamed over it, the directory fsynced.

    A crash at any moment leaves either the old file or the new one, never a torn one.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, _FILE_MODE)  # mkstemp makes it private (0600); a result file is as readable as any other
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    dfd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)


def write_text(path: Path, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def write_json(path: Path, data: Any) -> None:
    write_text(path, json.dumps(data, indent=2, sort_keys=True) + "\n")


def cut_back(path: Path, size: int) -> Path | None:
    """Cut ``path`` back to its first ``size`` bytes, keeping what is cut: it is first written (atomically) to
    the side file ``NAME.cut-N`` (the first N free).  That file, or None when nothing was past ``size``."""
    path = Path(path)
    with open(path, "r+b") as f:
        f.seek(size)
        cut = f.read()
        if not cut:
            return None
        n = 1
        while (kept := path.with_name(f"{path.name}.cut-{n}")).exists():
            n += 1
        write_bytes(kept, cut)
        f.truncate(size)
        os.fsync(f.fileno())
    return kept


def append_durably(log: IO[str], row: dict[str, Any]) -> None:
    """One JSON line on an append-only log, flushed and fsynced: it is on disk before anything of it leaves
    the process (a worker's publications, a CEL learner's cases)."""
    log.write(json.dumps(row) + "\n")
    log.flush()
    os.fsync(log.fileno())


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    if not rows:
        write_text(path, "")
        return
    import io

    buf = io.StringIO()
    # every row's columns, in the order first seen (the behaviours of a task may measure different things: a
    # column a row lacks is left empty)
    columns = list(dict.fromkeys(k for row in rows for k in row))
    w = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    write_text(path, buf.getvalue())


def read_jsonl(path: Path, *, schema: type[BaseModel] | None = None, missing_ok: bool = False,
               problems: list[str] | None = None) -> list[dict[str, Any]]:
    """The rows of a JSON-lines log, each a JSON object valid under ``schema`` (its file kind's, from
    :mod:`coevo.rundir.records`), in order; blank lines are skipped.

    A missing file is ``[]`` with ``missing_ok``, else a RunDirError.  A damaged line (not
    UTF-8, not JSON, NaN or Infinity, not an object, not of ``schema``, or a last line
    without its newline: a write cut short) is a RunDirError naming the file and line, or,
    when ``problems`` is given, noted there and skipped (``coevo check`` lists every one).
    """
    return _read_lines(Path(path), schema, missing_ok=missing_ok, problems=problems, as_models=False)


def line_problems(path: Path, *, upto: int, schema: type[BaseModel] | None) -> list[str]:
    """What is wrong with the first ``upto`` bytes of the log ``path`` (what a checkpoint saw of it, and what a
    resume keeps): one line a problem, none when they are whole lines valid under ``schema``.  Missing, not a
    file, or shorter than ``upto`` is a problem; what follows ``upto`` is not looked at (a resume cuts it aside)."""
    path = Path(path)
    if path.exists() and not path.is_file():
        return [f"{path} is not a file (a directory or another kind of file is in its place)"]
    problems: list[str] = []
    _read_lines(path, schema, missing_ok=False, problems=problems, as_models=False, upto=upto)
    return problems


def _read_lines(path: Path, schema: type[BaseModel] | None, *, missing_ok: bool, problems: list[str] | None,
                as_models: bool, torn_ok: bool = False, upto: int | None = None) -> list[Any]:
    """:func:`read_jsonl`'s rows, or with ``as_models`` the ``schema`` objects made of them; ``upto``: of the
    file's first ``upto`` bytes only (a file shorter than that is damaged)."""

    def damaged(msg: str) -> None:
        if problems is None:
            raise RunDirError(msg)
        problems.append(msg)

    try:
        data = path.read_bytes()
    except FileNotFoundError:
        if not missing_ok:
            damaged(f"{path} is missing: not a complete run directory")
        return []
    except OSError as exc:
        damaged(f"{path} cannot be read: {exc.strerror or exc}")
        return []
    if upto is not None:
        if len(data) < upto:
            damaged(f"{path} holds {len(data)} bytes but its checkpoint saw {upto}: it was cut short behind its "
                    "writer's back")
            return []
        data = data[:upto]
    lines = data.split(b"\n")
    torn = lines.pop()  # b"" when the file ends with its last line's newline
    out = []
    for n, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        try:
            row = json_object(raw)
            model = schema.model_validate(row) if schema is not None else None
        except ValueError as exc:  # pydantic's ValidationError is one
            damaged(f"{path} line {n} {_what_is_wrong(exc, schema)}")
            continue
        out.append(model if as_models else row)
    if torn and not (torn_ok and torn.startswith(b"{")):
        damaged(f"{path} line {len(lines) + 1} is torn: {len(torn)} bytes and no newline at the end (a write cut short)")
    return out


def json_object(raw: bytes) -> dict[str, Any]:
    """One line of a JSON-lines log as a JSON object; a ValueError saying what it is instead (not UTF-8, not
    JSON, NaN or Infinity, another JSON value)."""
    try:
        row = json.loads(raw.decode("utf-8"), parse_constant=_non_finite)
    except UnicodeDecodeError as exc:
        raise ValueError(f"is not UTF-8 text (byte {exc.object[exc.start]:#04x} at column {exc.start + 1})") from None
    except RecursionError:
        raise ValueError("is not JSON: nested too deeply") from None
    except ValueError as exc:
        raise ValueError(f"is not JSON: {exc}") from None
    if not isinstance(row, dict):
        raise ValueError(f"is not a JSON object (it is {_JSON_TYPES.get(type(row), 'a JSON value')})")
    return row


def _what_is_wrong(exc: ValueError, schema: type[BaseModel] | None) -> str:
    """A damaged line's fault in a few words: :func:`json_object`'s, or the first field ``schema`` refused."""
    from pydantic import ValidationError

    if not isinstance(exc, ValidationError) or schema is None:
        return str(exc)
    err = exc.errors()[0]
    return f"is not a {schema.__name__}: {'.'.join(map(str, err['loc'])) or 'the line'}: {err['msg']}"


_JSON_TYPES = {list: "an array", str: "a string", int: "a number", float: "a number", bool: "true or false",
               type(None): "null"}


def _non_finite(name: str) -> Any:
    raise ValueError(f"{name} (a non-finite number; JSON has none)")


def by_generation(rows: list[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    """Log rows (adoptions, changes) grouped by their ``generation``: what a worker took after that many generations."""
    out: dict[int, list[dict[str, Any]]] = {}
    for a in rows:
        out.setdefault(int(a["generation"]), []).append(a)
    return out


def span_text(values: list[int]) -> str:
    """Generation numbers as a reader wants them in a problem: ``1..50 (50 lines)`` when consecutive, else the list."""
    if not values:
        return "none"
    return f"{values[0]}..{values[-1]} ({len(values)} lines)" if values == list(range(values[0], values[-1] + 1)) else str(values)
