"""A worker's checkpoint: everything it needs to continue after a crash, in one file.

After every generation the worker writes ``checkpoint.msgpack`` in its directory:
the GA (population with learned strengths, control genes, best and current
policies, generator state), its models of the partners (policies, versions,
generator state), its publication counter, rejection counts, timings, and the
lengths of its append-only logs (``curve.jsonl``, ``adoptions.jsonl``,
``published.jsonl``) at that moment.  On ``--resume`` the logs are cut back to
those lengths, so whatever a crash left after the checkpoint (a curve line, an
adoption, a publication of a generation that is now done again) leaves the logs
(kept beside each, in ``NAME.cut-N``) and the logs agree with the restored state:
a replay reproduces the whole run.

The file is written atomically (:func:`coevo.rundir.layout.write_bytes`) and carries a
CRC-32 of its body, so a crash mid-write leaves the previous checkpoint intact and
a damaged file is refused with its name rather than half-read.

A worker writes its first checkpoint before its first generation, so a worker
directory whose logs hold anything but which has no checkpoint lost it.  Neither
that nor a damaged checkpoint is ever answered by starting afresh
(:func:`resume_state`): a fresh start cuts the logs and publishes new rules under
version numbers the partners and the store already hold.  The error says what
keeps the logs instead.
"""

from __future__ import annotations

import logging
import zlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import msgpack

from coevo.errors import ConfigError, RunDirError
from coevo.rundir.layout import WorkerPaths, cut_back, read_json, write_bytes, write_json

log = logging.getLogger(__name__)

__all__ = ["FORMAT", "save_checkpoint", "load_checkpoint", "resume_state", "truncate_log", "prepare_dir", "check_settings",
           "resume_problems", "cut_logs"]

FORMAT = "coevo-checkpoint/1"


def save_checkpoint(path: Path, ident: dict[str, Any], state: dict[str, Any]) -> None:
    """Write ``state`` for the worker ``ident`` (run, behaviour, worker, seed) atomically."""
    body = msgpack.packb(state, use_bin_type=True)
    write_bytes(Path(path), msgpack.packb({"format": FORMAT, "ident": ident, "crc32": zlib.crc32(body), "body": body},
                                          use_bin_type=True))


def load_checkpoint(path: Path, ident: dict[str, Any], *, advice: str = "") -> dict[str, Any] | None:
    """The state saved at ``path`` (None if there is none); refuses a damaged or foreign file (a damaged one
    with ``advice`` appended)."""
    path = Path(path)
    if not path.exists():
        return None
    try:
        outer = msgpack.unpackb(path.read_bytes(), raw=False)
        body = outer["body"]
        fmt, saved, crc = outer["format"], outer["ident"], outer["crc32"]
    except (OSError, msgpack.UnpackException, ValueError, TypeError, KeyError) as exc:
        raise RunDirError(f"checkpoint {str(path)!r} cannot be read ({type(exc).__name__}: {exc}){advice}") from None
    if fmt != FORMAT:
        raise RunDirError(f"checkpoint {str(path)!r} has format {fmt!r}; this coevo reads {FORMAT!r}")
    if zlib.crc32(body) != crc:
        raise RunDirError(f"checkpoint {str(path)!r} is damaged (CRC mismatch){advice}")
    if saved != ident:
        diff = ", ".join(f"{k} {saved.get(k)!r} (asked: {ident.get(k)!r})" for k in sorted(set(saved) | set(ident))
                         if saved.get(k) != ident.get(k))
        raise RunDirError(f"checkpoint {str(path)!r} belongs to another worker: {diff}")
    state: dict[str, Any] = msgpack.unpackb(body, raw=False, strict_map_key=False)
    return state


def resume_state(paths: WorkerPaths, ident: dict[str, Any]) -> dict[str, Any] | None:
    """The checkpoint to resume the worker in ``paths`` from; None for a fresh start, which only a directory
    with empty logs gets.  A damaged, unreadable or missing checkpoint beside logs is a RunDirError saying
    what to do that keeps them."""
    state = load_checkpoint(paths.checkpoint, ident, advice=f". {_keep_advice(paths)}")
    if state is None and any(f.exists() and f.stat().st_size for f in (paths.dir / n for n in WorkerPaths.LOGS)):
        raise RunDirError(f"worker directory {str(paths.dir)!r} holds logs but no checkpoint ({paths.checkpoint.name}: "
                          f"it was written before the first generation, so it was removed). {_keep_advice(paths)}")
    return state


def _keep_advice(paths: WorkerPaths) -> str:
    """What to do about a worker that cannot be resumed, keeping its logs (never: start it afresh in place)."""
    versions = 0
    if paths.published.exists():
        versions = sum(1 for line in paths.published.read_bytes().splitlines() if line.strip())
    keep = (f"Not resumed, nothing changed. Do not start this worker afresh in {str(paths.dir)!r}: that cuts its logs")
    if versions:
        return (f"{keep}, and it has published versions 1..{versions} (published.jsonl) that its partners and the "
                "store may hold: a fresh start would publish different rules under the same numbers. To go on, put "
                f"back an intact {paths.checkpoint.name} (a backup) and --resume; otherwise keep this run as it is "
                "(coevo check and coevo replay read its logs) and continue the experiment as a new run: "
                "coevo run --settings RUN_DIR/run.json --run NEW_ID")
    return (f"{keep}. It has published no version yet, so it can start afresh elsewhere: move the directory "
            f"aside (its logs stay there) and --resume, or put back an intact {paths.checkpoint.name} and --resume")


def prepare_dir(directory: Path, *, what: str, meta_file: Path, meta: dict[str, Any], logs: Sequence[Path],
                checkpoint: Path, resume: bool, saved: Callable[[dict[str, Any]], dict[str, Any]] | None = None,
                hint: str = "") -> None:
    """Make a process's directory (a worker's, an execution module's: ``what``) with its settings file and empty
    logs; a directory that already holds a run is refused (``hint``: where else to go).  With ``resume``, check
    instead that its settings file says ``meta`` (``saved`` reads an older file as it is meant today, e.g. filling
    in fields it lacks; the ``coevo`` version may differ): any other setting is a ConfigError naming each
    difference.  The caller then loads the checkpoint and cuts the logs back to it (:func:`cut_logs`)."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RunDirError(f"cannot create the {what} directory {str(directory)!r}: {exc.strerror or exc}") from None
    if not resume:
        used = [f for f in (meta_file, checkpoint, *logs) if f.exists()]
        if used:
            raise RunDirError(f"{what} directory {str(directory)!r} already holds a {what}'s run ({used[0].name}); "
                              f"add --resume to continue it{hint}")
        write_json(meta_file, meta)
        for f in logs:
            f.touch()
        return
    if meta_file.exists():
        check_settings(directory, meta_file, meta, saved=saved, what=what)
    elif checkpoint.exists():
        raise RunDirError(f"{str(meta_file)!r} is missing beside the checkpoint {checkpoint.name}: the {what} "
                          "directory lost its settings; put them back (a backup) before resuming")
    else:  # resumed before its first start made anything (it died on the way): as a fresh start
        write_json(meta_file, meta)
    if not checkpoint.exists():  # it never reached its first checkpoint: its logs start empty, and must be there
        for f in logs:
            f.touch()


def check_settings(directory: Path, meta_file: Path, meta: dict[str, Any], *, what: str,
                   saved: Callable[[dict[str, Any]], dict[str, Any]] | None = None) -> None:
    """That the settings file ``meta_file`` of a process's directory says ``meta`` (but for the ``coevo`` version):
    a RunDirError if it cannot be read, a ConfigError naming each difference."""
    held = read_json(meta_file, what=f"{what} directory (its {meta_file.name})")
    if saved is not None:
        try:
            held = saved(held)
        except ConfigError as exc:
            raise RunDirError(f"{str(meta_file)!r}: {exc}") from None
    diff = [f"{k} was {held.get(k)!r}, now {meta[k]!r}" for k in meta if k != "coevo" and held.get(k) != meta[k]]
    if diff:
        raise ConfigError(f"--resume of {str(directory)!r} with other settings: {'; '.join(diff)}")


def resume_problems(directory: Path, *, what: str, meta_file: Path, meta: dict[str, Any], logs: Sequence[Path],
                    checkpoint: Path, load: Callable[[], dict[str, Any] | None], sizes: Callable[[dict[str, Any]], Mapping[str, int]],
                    writes: Sequence[Path] = (), saved: Callable[[dict[str, Any]], dict[str, Any]] | None = None) -> list[str]:
    """What would stop a ``--resume`` of the process whose directory this is, found by reading every file it
    reads as it will (:func:`prepare_dir`, ``load`` for its checkpoint, :func:`cut_logs` with the sizes ``sizes``
    finds in it) and changing nothing: one line a problem.  ``writes``: the files it replaces or appends to, which
    must be files if they are there.  Empty: the resume can start."""
    from coevo.rundir.layout import line_problems, not_a_file
    from coevo.rundir.records import LOG_SCHEMAS

    if not directory.exists():
        return []  # a process that never started: it starts afresh
    if not directory.is_dir():
        return [f"{what} directory {str(directory)!r} is not a directory"]
    problems = not_a_file([meta_file, checkpoint, *logs, *writes])
    if problems:
        return problems
    if meta_file.exists():
        try:
            check_settings(directory, meta_file, meta, saved=saved, what=what)
        except (ConfigError, RunDirError) as exc:
            return [str(exc)]
    elif checkpoint.exists():
        return [f"{str(meta_file)!r} is missing beside the checkpoint {checkpoint.name}: the {what} directory lost "
                "its settings; put them back (a backup) before resuming"]  # as prepare_dir refuses it
    try:
        state = load()
    except RunDirError as exc:
        return [str(exc)]
    if state is None:
        return []  # it never reached its first checkpoint: it starts afresh with empty logs
    saw = sizes(state)
    for f in logs:
        problems += line_problems(f, upto=int(saw.get(f.name, 0)), schema=LOG_SCHEMAS.get(f.name))
    return problems


def cut_logs(logs: Sequence[Path], sizes: Mapping[str, int]) -> None:
    """Cut each log back to the size its checkpoint saw (0 for one it does not name)."""
    for f in logs:
        truncate_log(f, int(sizes.get(f.name, 0)))


def truncate_log(path: Path, size: int) -> None:
    """Cut an append-only log back to ``size`` bytes (what it held at the checkpoint); what is cut is kept beside
    it (:func:`~coevo.rundir.layout.cut_back`)."""
    path = Path(path)
    have = path.stat().st_size if path.exists() else 0
    if have < size:
        raise RunDirError(f"{str(path)!r} holds {have} bytes but the checkpoint saw {size}: the worker directory was "
                          "changed behind the worker's back; it cannot be resumed")
    if have > size:
        kept = cut_back(path, size)
        log.info("%s: cut back to the checkpoint's %d bytes; the %d bytes after it are kept in %s", path, size,
                 have - size, kept)
