"""The policy store: latest and full history of every published policy, per run and behaviour.

It appends each accepted update to ``<data_dir>/<run>/store/<behaviour>.jsonl``
(a CEL learner's cases, :class:`~coevo.bus.messages.CaseUpdate`, to
``<data_dir>/<run>/store/cases/<behaviour>.jsonl``: the case base, with the same rules),
flushed and fsynced, and only then keeps it in memory for queries: what the
store reports holding (``latest``, ``history``, ``versions``) is what is on disk,
never a write that failed.  A broker that restarts reloads what it had.  A broker
killed mid-write leaves at most a torn last line; the reload cuts it off (that
update was never confirmed to its worker, which publishes it again).  An update
whose (worker, version) is already stored is a duplicate (a worker republishing)
and is ignored.  Rejected messages are counted per run, by reason.

**Order: by version, not by arrival.**  After a broker outage the workers republish the
versions the store lacked, and those arrive after newer ones (measured: tracking 4, 1, 2, 3).
So the files keep arrival order (append only), but the store answers in version order:
:meth:`PolicyStore.latest` is the highest version (of the roster's worker, when the caller
names it), :meth:`PolicyStore.history` lists by (version, arrival).  An old policy never
displaces a newer one, however late it arrives.

**Write errors** (a full disk, a store directory that became a file, an I/O
error): the update is not kept, the file is cut back to its last whole line, and
the store is *degraded* (:attr:`PolicyStore.degraded` names the file and the
error) until a write to that file succeeds again.  It retries by itself: every
update that arrives for that file is a new attempt (workers put their newest
version every generation, and republish whatever the store lacks once it is up
again), so freeing the disk heals it without a restart.

**Quotas** (:class:`Quota`): run ids are plain directory names (checked before
any path is built); a broker stores policies of at most ``runs`` runs since it
started, each at most ``policies`` policies and ``bytes`` bytes on disk.  An
update beyond a quota is refused and counted (``quota``), not stored.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import threading
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coevo.bus import keys
from coevo.bus.messages import CaseUpdate, PolicyUpdate
from coevo.bus.rejections import Rejections
from coevo.errors import ConfigError, MessageError
from coevo.rundir.layout import RunPaths, cut_back, read_cases, read_store

Stored = PolicyUpdate | CaseUpdate
_CASES = "cases/"  # the stream of a behaviour's cases is "cases/BEHAVIOUR"; a behaviour's policies, "BEHAVIOUR"


def _stream(msg: Stored) -> str:
    return _CASES + msg.behaviour if isinstance(msg, CaseUpdate) else msg.behaviour

__all__ = ["PolicyStore", "Quota"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class Quota:
    """What one broker stores at most (see the module docstring; docs/faults.md says why these numbers).

    * ``runs``: runs it stores policies for since it started (32: a broker serves a few runs at a time;
      ``coevo run`` and ``coevo compare`` start one broker per run);
    * ``policies``: policies per run (10,000: a run publishes at most one version per worker and
      generation, 150 at the report's parameters);
    * ``bytes``: bytes per run on disk (64 MB: 10,000 of the largest policies, ~5.2 KB each, fit).

    So a broker's disk use is bounded by ``runs x bytes`` (2 GB) plus the runs it reloaded.
    """

    runs: int = 32
    policies: int = 10_000
    bytes: int = 64 << 20

    def __post_init__(self) -> None:
        for name in ("runs", "policies", "bytes"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ConfigError(f"store quota {name}={v!r}: give a whole number >= 1")


class PolicyStore:
    def __init__(self, data_dir: Path, *, quota: Quota | None = None) -> None:
        self.data_dir = Path(data_dir)
        self.quota = quota or Quota()
        self._lock = threading.Lock()
        self._history: dict[tuple[str, str], list[Stored]] = {}  # (run, stream) -> messages in arrival order
        self._seen: set[tuple[str, str, str, int]] = set()
        self._sizes: dict[tuple[str, str], int] = {}  # bytes of each store file known whole and fsynced
        self._rejected: dict[str, Rejections] = {}  # per run (the key's run chunk), for runs reported
        self._others = Rejections("broker (runs beyond the quota)", log)  # rejections of runs not reported
        self._dropped: Counter[str] = Counter()  # per run: dropped unread (flood)
        self._active: set[str] = set()  # runs heard of since this broker started (reported every few seconds)
        self._storing: set[str] = set()  # runs this broker stored a policy for since it started (the runs quota)
        self._failing: dict[tuple[str, str], str] = {}  # store files whose last write failed -> the error
        self._check_dir()
        self._load()

    def _check_dir(self) -> None:
        """Refuse a data directory that cannot hold a store, before anything listens."""
        d = self.data_dir
        if d.exists() and not d.is_dir():
            raise ConfigError(f"--data-dir {str(d)!r} is a file, not a directory: give a directory for the store")
        try:
            d.mkdir(parents=True, exist_ok=True)
            probe = d / f".coevo-write-test-{os.getpid()}"
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as exc:
            raise ConfigError(f"--data-dir {str(d)!r} cannot hold the store: {exc.strerror or exc}") from None

    def _file(self, run: str, stream: str) -> Path:
        paths = RunPaths.of(self.data_dir, run)
        return paths.case_file(stream[len(_CASES):]) if stream.startswith(_CASES) else paths.store_file(stream)

    def _load(self) -> None:
        files: list[tuple[Path, str, str, Callable[..., list[Any]]]]
        files = [(f, f.parent.parent.name, f.stem, read_store) for f in sorted(self.data_dir.glob("*/store/*.jsonl"))]
        files += [(f, f.parent.parent.parent.name, _CASES + f.stem, read_cases)
                  for f in sorted(self.data_dir.glob("*/store/cases/*.jsonl"))]
        for f, run, stream, reader in files:
            if not keys.valid_id(run):
                continue
            try:
                _cut_torn_tail(f)
                damaged: list[str] = []
                msgs = reader(f, problems=damaged)  # damaged in the middle: keep the rest
            except OSError as exc:
                log.error("store: %s cannot be read (%s); skipped", f, exc)
                continue
            for msg in msgs:
                self._remember(msg)
            for problem in damaged:
                log.warning("store: %s; skipped", problem)
            self._sizes[(run, stream)] = f.stat().st_size
        if self._seen:
            log.info("store reloaded %d policies from %s", len(self._seen), self.data_dir)

    def _remember(self, msg: Stored) -> bool:
        ident = (msg.run, _stream(msg), msg.worker, msg.version)
        if ident in self._seen:
            return False
        self._seen.add(ident)
        self._history.setdefault((msg.run, _stream(msg)), []).append(msg)
        return True

    @property
    def degraded(self) -> str:
        """Why the store cannot write ('' while every file's last write succeeded)."""
        with self._lock:
            return next(iter(self._failing.values()), "")

    def add(self, msg: Stored) -> bool:
        """Persist and then keep an update (a policy or a case); False if it was a duplicate or could not be written.

        A run id that is not a plain directory name, or an update beyond a quota, is a
        MessageError (``invalid``, ``quota``) for the caller to count.
        """
        if not keys.valid_id(msg.run):  # the models check it too; this guards the path below
            raise MessageError("invalid", f"run id {msg.run!r} is not a plain directory name")
        line = (json.dumps(msg.model_dump(mode="json"), sort_keys=True) + "\n").encode("utf-8")
        pair = (msg.run, _stream(msg))
        with self._lock:
            if (*pair, msg.worker, msg.version) in self._seen:
                self._active.add(msg.run)
                return False
            self._admit(msg.run, len(line))
            self._active.add(msg.run)
            try:
                self._sizes[pair] = self._append(self._file(*pair), line, self._sizes.get(pair, 0))
            except OSError as exc:
                first = pair not in self._failing
                self._failing[pair] = f"cannot write {self._file(*pair)}: {exc.strerror or exc}"
                if first:
                    log.error("store DEGRADED: %s; %s v%d not stored (retried with every update that arrives "
                              "for it; the workers republish what the store lacks)", self._failing[pair],
                              msg.behaviour, msg.version)
                return False
            if self._failing.pop(pair, None) is not None:
                log.warning("store writes to %s work again", self._file(*pair))
            self._storing.add(msg.run)
            self._remember(msg)
            return True

    def _admit(self, run: str, size: int) -> None:
        """Refuse an update beyond a quota (called with the lock held)."""
        q = self.quota
        if run not in self._storing and len(self._storing) >= q.runs:
            raise MessageError("quota", f"run {run!r} refused: this broker already stores {len(self._storing)} runs "
                                        f"(quota {q.runs}; coevo broker --quota-runs)")
        held = sum(len(h) for (r, _), h in self._history.items() if r == run)
        if held >= q.policies:
            raise MessageError("quota", f"run {run!r} holds {held} policies (quota {q.policies}; --quota-policies)")
        used = sum(n for (r, _), n in self._sizes.items() if r == run)
        if used + size > q.bytes:
            raise MessageError("quota", f"run {run!r} holds {used} bytes, +{size} > quota {q.bytes} (--quota-mb)")

    @staticmethod
    def _append(f: Path, line: bytes, size: int) -> int:
        """Append ``line`` to ``f`` after its first ``size`` bytes (a failed earlier write is cut off), fsynced;
        the new size."""
        f.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(f, os.O_WRONLY | os.O_CREAT, 0o666)
        try:
            have = os.fstat(fd).st_size
            if have > size:  # a torn line of a write that failed: cut it
                os.ftruncate(fd, size)
            elif have < size:  # shortened behind our back: append after what is there
                log.warning("store %s is shorter (%d bytes) than written (%d)", f, have, size)
                size = have
            os.lseek(fd, size, os.SEEK_SET)
            view = memoryview(line)
            while view:
                n = os.write(fd, view)
                if n <= 0:
                    raise OSError(errno.EIO, "short write")
                view = view[n:]
            os.fsync(fd)
        except OSError:
            try:
                os.ftruncate(fd, size)  # best effort: leave no torn line behind
            except OSError:
                pass  # the next append cuts it (it starts from the size known whole)
            raise
        finally:
            os.close(fd)
        return size + len(line)

    def reject(self, err: MessageError, key: str, *, dropped: bool = False) -> None:
        run = keys.parse(key).get("run", "?")
        with self._lock:
            known = run in self._rejected
            if not known and keys.valid_id(run) and len(self._rejected) < 2 * self.quota.runs:
                self._rejected[run] = Rejections(f"broker (run {run})", log)
                known = True
            if known:
                self._active.add(run)
                if dropped:
                    self._dropped[run] += 1
            counter = self._rejected[run] if known else self._others
        counter.note(err, key)

    def rejected(self, run: str) -> dict[str, int]:
        with self._lock:
            counter = self._rejected.get(run)
        return counter.as_dict() if counter is not None else {}

    def flush_log(self) -> None:
        with self._lock:
            counters = [*self._rejected.values(), self._others]
        for c in counters:
            c.flush()

    def accounts(self) -> dict[str, tuple[dict[str, int], dict[str, int], int]]:
        """For each run heard of since start: (policies stored per behaviour, rejections by reason, dropped)."""
        with self._lock:
            runs = sorted(r for r in self._active if keys.valid_id(r))
            stored = {r: {b: len(h) for (rr, b), h in self._history.items() if rr == r} for r in runs}
            dropped = {r: self._dropped[r] for r in runs}
        return {r: (stored[r], self.rejected(r), dropped[r]) for r in runs}

    def versions(self, run: str, behaviour: str) -> dict[str, list[int]]:
        """The versions held (on disk) of each worker's policies for (run, behaviour)."""
        out: dict[str, list[int]] = {}
        for m in self.history(run, behaviour):
            out.setdefault(m.worker, []).append(m.version)
        return {w: sorted(v) for w, v in out.items()}

    def latest(self, run: str, behaviour: str, *, worker: str | None = None) -> PolicyUpdate | None:
        """The highest version held for (run, behaviour), of ``worker`` when given (the roster's publisher);
        arrival order decides only between equal versions (of different workers, in an open run: the last)."""
        with self._lock:
            h = [m for m in self._history.get((run, behaviour), []) if worker is None or m.worker == worker]
        best: Stored | None = None
        for m in h:
            if best is None or m.version >= best.version:
                best = m
        return best  # type: ignore[return-value]

    def history(self, run: str, behaviour: str) -> list[PolicyUpdate]:
        """Every policy held for (run, behaviour), in version order (arrival order between equal versions);
        the file on disk keeps arrival order."""
        with self._lock:
            h = list(self._history.get((run, behaviour), []))
        return sorted(h, key=lambda m: m.version)  # type: ignore[arg-type]  # stable: arrival breaks ties

    def cases(self, run: str, behaviour: str) -> list[CaseUpdate]:
        """The case base of (run, behaviour): every case stored, in arrival order."""
        with self._lock:
            return list(self._history.get((run, _CASES + behaviour), []))  # type: ignore[arg-type]

    def matching(self, run_pattern: str, behaviour_pattern: str, *, cases: bool = False) -> list[tuple[str, str]]:
        """(run, behaviour) pairs of policies (``cases``: of cases) a query's chunks select (``*`` or a literal)."""
        with self._lock:
            streams = list(self._history)
        pairs = [(r, s[len(_CASES):]) for r, s in streams if s.startswith(_CASES)] if cases else \
            [(r, s) for r, s in streams if not s.startswith(_CASES)]
        return [(r, b) for r, b in pairs if run_pattern in ("*", "**", r) and behaviour_pattern in ("*", "**", b)]

    @staticmethod
    def key_of(run: str, behaviour: str, latest: bool) -> str:
        return keys.store_latest(run, behaviour) if latest else keys.store_history(run, behaviour)


def _cut_torn_tail(f: Path) -> None:
    """Cut a last line that a crash left without its newline (it was never fsynced as a whole), keeping it beside
    the file (``NAME.cut-N``): a file damaged otherwise loses nothing to the reload."""
    with open(f, "rb") as fh:
        data = fh.read()
    if data and not data.endswith(b"\n"):
        keep = data.rfind(b"\n") + 1
        kept = cut_back(f, keep)
        log.warning("store %s: cut a torn last line of %d bytes (a crash mid-write, or damage); kept in %s", f,
                    len(data) - keep, kept)
