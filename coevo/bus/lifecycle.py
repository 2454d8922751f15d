"""One life for every long-running process on the bus: the worker, the broker and the CEL execution module.

::

    with Lifecycle(conf, what="docking worker session", gate=gate) as life:   # the session opens
        inbox = life.enter(Inbox(life.session, ...))          # a context manager, exited when the life ends
        life.start(self._drain, name="coevo-store", wake=...)  # a thread: told to stop (life.stop), then joined
        token = life.declare(life.session.liveliness().declare_token(key))    # undeclared when the life ends
        ...  the process's own loop, until it is done or life.stop is set ...
        life.linger()                                          # its last heartbeat on its way before the token ends
    # the end, in the reverse order of the above: declarations undeclared, threads stopped and joined, context
    # managers exited, the session closed.  close() may be called again; a session already gone is no error.

``main_of(work)`` is a process's entry around it: SIGTERM ends the work as Ctrl-C does (so every ``finally`` and
every life closes), and an interrupted work returns None for the command to turn into its exit status.  The signal
also sets every open life's :attr:`~Lifecycle.stop`: a KeyboardInterrupt that lands in a finaliser (pymunk frees
its objects in ``__del__``) is printed and dropped by Python, and the loops that watch ``stop`` end all the same.

The order matters twice.  A subscriber undeclared before the thread that drains what it queued is stopped loses
nothing (the broker's store).  And a liveliness token that ends right after the last heartbeat can reach a watcher
first, which then reads "dead" for a process that ended well: :meth:`Lifecycle.linger` waits :data:`DONE_LINGER`.
"""

from __future__ import annotations

import ctypes
import logging
import os
import signal
import threading
import time
import weakref
from collections.abc import Callable
from contextlib import AbstractContextManager, ExitStack
from typing import Any, Protocol, TypeVar

from coevo.bus.session import Config, Session, SessionGone, open_session
from coevo.bus.trust import Gate

__all__ = ["Lifecycle", "main_of", "DONE_LINGER", "JOIN_SECONDS", "SIGNALLED", "DIE_WITH_PARENT"]

log = logging.getLogger(__name__)

#: Seconds a process that ends normally keeps its liveliness token after its last heartbeat ("done").  The
#: heartbeat is a sample and the token's end a declaration: zenoh may deliver the second first, and a status board
#: that saw the token go before the "done" would show the process "dead" for a moment (seen at the end of a Quick
#: start run).  A killed process has no such delay: its token goes at once.
DONE_LINGER = 0.2
#: Seconds the end of a life waits for each of its threads.
JOIN_SECONDS = 5.0

T = TypeVar("T")

#: The environment variable by which a parent (``coevo run``'s supervisor) gives its pid to a process it starts in a
#: process group of its own: :func:`main_of` then has the kernel SIGKILL the process when that parent dies, as a
#: SIGKILL to the run's group did when they shared it (a lost machine, not a stop).
DIE_WITH_PARENT = "COEVO_DIE_WITH_PARENT"

#: Set by a stop signal that :func:`main_of` took (SIGTERM, or SIGINT unless it was ignored when the process began).
SIGNALLED = threading.Event()
_OPEN: weakref.WeakSet[Lifecycle] = weakref.WeakSet()  # the lives a stop signal ends


class Undeclarable(Protocol):
    def undeclare(self) -> None: ...


D = TypeVar("D", bound=Undeclarable)


class Lifecycle:
    """A process's session and everything that lives on it; see the module docstring."""

    def __init__(self, conf: Config, *, what: str, gate: Gate | None = None) -> None:
        self.conf = conf
        self.what = what
        self.gate = gate
        self.stop = threading.Event()  # set when the life ends; a loop or thread that watches it ends too
        self._stack = ExitStack()
        self._session: Session | None = None

    @property
    def session(self) -> Session:
        if self._session is None:
            raise RuntimeError(f"the {self.what} is not open (use the Lifecycle as a context manager)")
        return self._session

    def __enter__(self) -> Lifecycle:
        try:
            self._session = self._stack.enter_context(open_session(self.conf, what=self.what, gate=self.gate))
        except BaseException:
            self._stack.close()
            raise
        _OPEN.add(self)
        if SIGNALLED.is_set():
            self.stop.set()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """End the life: everything it holds, newest first, then the session.  Idempotent."""
        self.stop.set()
        try:
            self._stack.close()
        finally:
            self._session = None

    def enter(self, cm: AbstractContextManager[T]) -> T:
        """``cm`` entered now and exited when the life ends."""
        return self._stack.enter_context(cm)

    def at_end(self, fn: Callable[[], Any]) -> None:
        """``fn()`` when the life ends (in the reverse order of everything it holds)."""
        self._stack.callback(fn)

    def declare(self, declaration: D) -> D:
        """A token, publisher, subscriber or queryable, undeclared when the life ends."""
        self._stack.callback(self._undeclare, declaration)
        return declaration

    def start(self, target: Callable[[], Any], *, name: str, wake: Callable[[], None] | None = None) -> threading.Thread:
        """A daemon thread running ``target`` now; when the life ends, :attr:`stop` is set, ``wake`` is called (to
        unblock a thread that waits on something else, e.g. a queue) and the thread is joined."""
        t = threading.Thread(target=target, name=name, daemon=True)
        self._stack.callback(self._join, t, wake)
        t.start()
        return t

    @staticmethod
    def linger() -> None:
        """Wait :data:`DONE_LINGER` after a last heartbeat, before the token ends (see the module docstring)."""
        time.sleep(DONE_LINGER)

    def _undeclare(self, declaration: Undeclarable) -> None:
        try:
            declaration.undeclare()
        except SessionGone as exc:  # already gone with the session
            log.debug("%s: undeclare after the session went: %s", self.what, exc)

    def _join(self, thread: threading.Thread, wake: Callable[[], None] | None) -> None:
        self.stop.set()
        if wake is not None:
            wake()
        thread.join(timeout=JOIN_SECONDS)
        if thread.is_alive():
            log.warning("%s: thread %s did not end within %.0f s", self.what, thread.name, JOIN_SECONDS)


def _stop_signal(signum: int, frame: object) -> None:
    SIGNALLED.set()
    for life in list(_OPEN):
        life.stop.set()
    raise KeyboardInterrupt(f"signal {signum}")


def _die_with_parent() -> None:
    """SIGKILL from the kernel when the parent named by :data:`DIE_WITH_PARENT` dies (Linux's PR_SET_PDEATHSIG);
    at once if it is gone already.  Nothing without the variable, or where prctl is not."""
    parent = os.environ.pop(DIE_WITH_PARENT, "")
    if not parent.isdigit():
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != int(parent):  # it died before the prctl: the kernel would not tell us any more
        os.kill(os.getpid(), signal.SIGKILL)


def main_of(work: Callable[[], T]) -> T | None:
    """``work()`` as a process's main: SIGTERM stops it as Ctrl-C does (a KeyboardInterrupt, so that every
    ``finally`` runs and every :class:`Lifecycle` closes) and sets every open life's ``stop``; None when it was
    interrupted.  A SIGINT that was ignored when the process began (``coevo run &`` in a script) stays ignored."""
    _die_with_parent()
    SIGNALLED.clear()
    signal.signal(signal.SIGTERM, _stop_signal)
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, _stop_signal)
    try:
        result = work()
    except KeyboardInterrupt:
        return None
    return None if SIGNALLED.is_set() else result
