"""Freshness: what makes a replayed genuine message detectable (envelope format 2, :mod:`coevo.bus.auth`).

The MAC proves a message came from a member of the run, not that it is new.  So every
sealed message also carries, inside the authenticated bytes, a *freshness header*::

    [epoch, born, inc, seq, at]

* ``epoch``: the run's incarnation (``run.json``'s ``incarnation``: 1 when ``coevo run``
  makes the run, +1 with every ``coevo run --resume``; 0 in a run by hand without one);
* ``born``, ``inc``: the sending process's start time and a random id (its incarnation);
* ``seq``: the process's message counter (1, 2, ...; every message it seals);
* ``at``: when it was sealed (``time.time()``).

A receiver with the run's key refuses (:meth:`Freshness.admit`):

* ``stale``: a message of an earlier incarnation of the run than one it belongs to or has
  heard (a resumed run is not stopped by the previous one's stop, nor fed its policies); a
  message of an older incarnation of its sender, after messages of a newer one on that key;
  a message sealed more than :data:`MAX_AGE` seconds ago, or as far in the future (hosts'
  clocks must agree to within that);
* ``replayed``: a sequence number it has already taken on that key (or one older than the
  :data:`WINDOW` it remembers below the newest).

Each receiver (every ring, the broker's store thread, the queries of a process) keeps its
own table, per key expression, so a message two receivers of one process both read is
new to each.  The broker's table of a run is also kept in a file beside the run's store
(:class:`KeptSeen`), so a broker started again still refuses a replay of what it took
before (a table in memory only would forget it with the process).  An open run (no key) has no envelopes, so nothing of this: anyone can steer
it anyway.
"""

from __future__ import annotations

import itertools
import json
import logging
import os
import secrets
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgpack

from coevo.errors import MessageError

__all__ = ["MAX_AGE", "WINDOW", "Freshness", "Seen", "KeptSeen", "header"]

log = logging.getLogger(__name__)

MAX_AGE = 600.0  # seconds: a message sealed longer ago than this is stale (messages are sealed when put)
WINDOW = 256  # sequence numbers remembered below a key's newest (messages of one sender may cross on the way)

_BORN = time.time()  # this process's incarnation: its start time and a random id
_INC = secrets.token_hex(8)
_SEQ = itertools.count(1)
_SEQ_LOCK = threading.Lock()


def header(epoch: int) -> bytes:
    """The next freshness header of this process, for a message of run incarnation ``epoch``."""
    with _SEQ_LOCK:
        seq = next(_SEQ)
    packed: bytes = msgpack.packb([int(epoch), _BORN, _INC, seq, time.time()], use_bin_type=True)
    return packed


def parse(raw: bytes) -> tuple[int, float, str, int, float]:
    try:
        epoch, born, inc, seq, at = msgpack.unpackb(raw, raw=False)
        if not (isinstance(epoch, int) and isinstance(seq, int) and isinstance(inc, str)
                and isinstance(born, (int, float)) and isinstance(at, (int, float))):
            raise ValueError("wrong types")
    except (ValueError, TypeError, msgpack.UnpackException) as exc:
        raise MessageError("invalid", f"a malformed freshness header: {exc}") from None
    return epoch, float(born), inc, seq, float(at)


@dataclass
class _Key:
    sender: tuple[int, float, str]  # (epoch, born, inc) of the sender incarnation heard last on the key
    top: int  # its newest sequence number taken
    recent: set[int] = field(default_factory=set)  # sequence numbers taken within WINDOW below top


class Seen:
    """One receiver's memory of what it took, per key expression."""

    def __init__(self) -> None:
        self._keys: dict[str, _Key] = {}
        self._lock = threading.Lock()

    def admit(self, key: str, sender: tuple[int, float, str], seq: int) -> None:
        with self._lock:
            k = self._keys.get(key)
            if k is None or sender > k.sender:
                self._keys[key] = _Key(sender, seq, {seq})
                return
            if sender < k.sender:
                raise MessageError("stale", f"from an older incarnation of its sender (started {sender[1]:.3f}) after "
                                            f"messages of a newer one (started {k.sender[1]:.3f}) on {key!r}")
            if seq in k.recent or seq <= k.top - WINDOW:
                raise MessageError("replayed", f"message {seq} of its sender on {key!r} was taken already")
            k.recent.add(seq)
            if seq > k.top:
                k.top = seq
                if len(k.recent) > 2 * WINDOW:
                    k.recent = {s for s in k.recent if s > k.top - WINDOW}


class KeptSeen(Seen):
    """A :class:`Seen` that outlives its process: every message it takes is appended to ``path`` (a line ``[key,
    epoch, born, inc, seq]``) and read back when it is made, so a receiver started again (the broker) refuses a
    replay of what it took before as ``replayed`` or ``stale``.  A line that does not parse (a torn last one) is
    skipped; a file that cannot be read or written is said once in the log, and the memory goes on in the process.
    The lines are appended without fsync: a killed process loses none (the kernel holds them), a lost machine
    perhaps the last few.

    The file is bounded: what a :class:`Seen` remembers of a key is its newest sender and at most ``2 * WINDOW``
    sequence numbers, so once the file holds more than ``limit`` lines (and twice what the memory needs) it is
    written again with only those (:meth:`compact`), on making and while taking.  Written beside it, fsynced and
    renamed over it: a crash leaves either the old file or the new one, each refusing what the other does."""

    def __init__(self, path: Path, limit: int = 4096) -> None:
        super().__init__()
        self.path = path
        self.limit = limit
        self._warned = False
        self._write = threading.Lock()
        try:
            text = path.read_bytes().decode("utf-8", "replace") if path.is_file() else ""
        except OSError as exc:
            self._warn(exc)
            text = ""
        self._lines = 0
        for line in text.splitlines():
            self._lines += 1
            try:
                key, epoch, born, inc, seq = json.loads(line)
                super().admit(str(key), (int(epoch), float(born), str(inc)), int(seq))
            except (ValueError, TypeError, MessageError):
                continue
        self._maybe_compact()

    def admit(self, key: str, sender: tuple[int, float, str], seq: int) -> None:
        super().admit(key, sender, seq)
        with self._write:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                with open(self.path, "a", encoding="utf-8") as f:
                    f.write(json.dumps([key, *sender, seq]) + "\n")
                self._lines += 1
            except OSError as exc:
                self._warn(exc)
        self._maybe_compact()

    def lines(self) -> list[list[Any]]:
        """What the memory holds, as the file's lines: replayed in order they make the same memory."""
        with self._lock:
            return [[key, *k.sender, seq] for key, k in sorted(self._keys.items()) for seq in sorted(k.recent)]

    def _maybe_compact(self) -> None:
        if self._lines > self.limit:
            with self._lock:
                needed = sum(len(k.recent) for k in self._keys.values())
            if self._lines > 2 * needed:
                self.compact()

    def compact(self) -> None:
        """Write the file again with only what the memory holds: beside it, fsynced, renamed over it."""
        with self._write:
            lines = self.lines()
            tmp = self.path.with_name(self.path.name + ".new")
            try:
                with open(tmp, "w", encoding="utf-8") as f:
                    f.write("".join(json.dumps(line) + "\n" for line in lines))
                    f.flush()
                    os.fsync(f.fileno())
                os.replace(tmp, self.path)
                dir_fd = os.open(self.path.parent, os.O_RDONLY)
                try:
                    os.fsync(dir_fd)
                finally:
                    os.close(dir_fd)
                self._lines = len(lines)
            except OSError as exc:
                log.warning("%s: cannot write it again shorter (%s); it keeps growing", self.path, exc.strerror or exc)
                self._lines = 0  # not again at once: after another limit's worth of lines

    def _warn(self, exc: OSError) -> None:
        if not self._warned:
            self._warned = True
            log.warning("%s: %s; what this process takes is remembered in memory only (a replay after its restart "
                        "is not refused)", self.path, exc.strerror or exc)


class Freshness:
    """A gate's freshness state: the run incarnation it belongs to (raised by any newer one it hears, never
    lowered) and the table of the receivers that keep none of their own."""

    def __init__(self, epoch: int = 0) -> None:
        self.epoch = epoch
        self.seen = Seen()
        self._lock = threading.Lock()

    def seal_header(self) -> bytes:
        return header(self.epoch)

    def admit(self, key: str, raw: bytes, seen: Seen | None = None) -> None:
        """Refuse a stale or repeated message (``stale``, ``replayed``); remember it otherwise."""
        epoch, born, inc, seq, at = parse(raw)
        if epoch < self.epoch:
            raise MessageError("stale", f"sent in incarnation {epoch} of the run; it is in incarnation {self.epoch} "
                                        "(resumed since)")
        age = time.time() - at
        if abs(age) > MAX_AGE:
            raise MessageError("stale", f"sealed {age:.0f} s ago (more than {MAX_AGE:.0f} s either way; clocks apart?)")
        (seen or self.seen).admit(key, (epoch, born, inc), seq)
        if epoch > self.epoch:
            with self._lock:
                self.epoch = max(self.epoch, epoch)

    def __repr__(self) -> str:
        return f"Freshness(epoch={self.epoch})"


def describe(raw: Any) -> str:  # for logs and tests
    return str(parse(raw)) if isinstance(raw, bytes) else repr(raw)
