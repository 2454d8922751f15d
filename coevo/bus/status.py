"""``coevo status``: follow the workers of a run (heartbeats plus liveliness tokens) and its broker.

A worker is *starting* from its token or first heartbeat until it has finished its first
generation (loading, waiting for its broker and partners), *alive* while its liveliness
token exists and its last heartbeat is recent, *stalled* when the token exists but no
heartbeat came for ``stall`` seconds (a token proves the process exists, not that it
progresses; a worker heartbeats about every second, even in the middle of a generation),
*dead* when its token is gone (its process died: seen within milliseconds on a LAN, or its
link stayed silent for a lease), *stopped* when its token went short of its last generation once
the board was told the run was asked to stop (:meth:`StatusBoard.stopping`: ``coevo run`` on a Ctrl-C) or the worker's
last heartbeat said it stops in order (``stopped``: what a board in another terminal, not told, goes by),
and *done* when it said so or when its token went after its heartbeats showed it at its last
generation (a worker that finished its generations and ends: its final heartbeat and its token
travel apart and may arrive in either order, so a finishing worker is never shown dead, in the
table, the plain lines or JSON).  Before its first heartbeat a worker's generations are the
run's, when the board was told them (``generations``).  The broker is
*starting* until its token is first seen (for at most ``BROKER_GRACE`` s: its router opens
before its store), *up* while its token exists; its last :class:`~coevo.bus.messages.BrokerStatus`
says what it stored and rejected for this run; it is *degraded* while its store cannot write
(it then holds ``coevo/_broker/degraded`` instead, and its status says why).

Heartbeats wait in a ring inside Zenoh and are decoded when the board is read, so
a flood on the status keys costs nothing until then and never stalls the session.
They pass the session's gate (:mod:`coevo.bus.trust`): with the run's key and
roster, a forged heartbeat or one from a worker id outside the roster is counted
(``rejected``) and shown nowhere, and so is a liveliness token of a worker outside
the roster.  Without a key the board is *open*: it shows what arrives, unverified.
"""

from __future__ import annotations

import json
import logging
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from coevo.bus import keys
from coevo.bus.messages import BrokerStatus, ExecutionStatus, Status
from coevo.bus.session import drain_messages, is_put, ring_subscriber, Sample, Session, SessionGone
from coevo.errors import MessageError

if TYPE_CHECKING:  # rich is imported where a table is drawn, not by every process that reads a board
    from rich.console import Console, ConsoleOptions, RenderableType, RenderResult
    from rich.live import Live

    from coevo.bus.session import Config
    from coevo.bus.trust import Gate

__all__ = ["DEFAULT_STALL", "WorkerView", "RobotView", "StatusBoard", "status_table", "PlainStatus", "StatusDisplay", "StatusTable", "PlainLines", "follow"]

log = logging.getLogger(__name__)

DEFAULT_STALL = 3.0  # seconds without a heartbeat; workers send one about every second
BROKER_GRACE = 10.0  # seconds a broker never seen yet is "starting" (its store opens after its router), then "down"


def _process_state(view: WorkerView | RobotView, now: float, stall: float) -> str:
    """What a worker or an execution module is doing, as its heartbeats and its liveliness token show it."""
    if view.done:
        return "done"
    if not view.token:
        return "done" if view.finished() else "stopped" if view.stopping else "dead"
    if view.generation == 0:
        return "starting"  # no generation done yet: loading, or waiting for its broker or partners
    if view.last_heartbeat and now - view.last_heartbeat > stall:
        return "stalled"
    return "alive"


@dataclass
class WorkerView:
    behaviour: str
    worker: str
    regime: str = "?"
    generation: int = 0
    generations: int = 0
    best_fitness: float = 0.0
    measures: dict[str, float] = field(default_factory=dict)
    partner_versions: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    buffered: int = 0
    open: bool = False
    token: bool = False
    done: bool = False
    stopping: bool = False  # the run was asked to stop: a token that goes is a stop, not a death
    last_heartbeat: float = 0.0
    died_at: float | None = None

    def finished(self) -> bool:
        """It said done, or it reached its last generation (what is left is its final store sync)."""
        return self.done or 0 < self.generations <= self.generation

    def state(self, now: float, stall: float) -> str:
        return _process_state(self, now, stall)

    def as_dict(self, now: float, stall: float) -> dict[str, Any]:
        return {
            "behaviour": self.behaviour, "worker": self.worker, "regime": self.regime,
            "generation": self.generation, "generations": self.generations, "best_fitness": self.best_fitness,
            "measures": dict(self.measures), "partner_versions": self.partner_versions, "rejected": sum(self.rejected.values()),
            "rejected_by_reason": dict(self.rejected), "buffered": self.buffered, "open": self.open,
            "state": self.state(now, stall),
            "heartbeat_age": round(now - self.last_heartbeat, 3) if self.last_heartbeat else None,
        }


@dataclass
class RobotView:
    """A CEL run's execution module, as its heartbeats and liveliness token show it."""

    robot: str
    trial: int = 0
    trials: int = 0
    generation: int = 0
    performance: float = 0.0
    rules_version: int = 0
    capabilities: list[str] = field(default_factory=list)
    changes: int = 0
    last_change: int | None = None
    rejected: dict[str, int] = field(default_factory=dict)
    open: bool = False
    token: bool = False
    done: bool = False
    stopping: bool = False  # the run was asked to stop: a token that goes is a stop, not a death
    last_heartbeat: float = 0.0
    died_at: float | None = None

    def finished(self) -> bool:
        """It said done, or it played its last trial."""
        return self.done or 0 < self.trials <= self.trial

    def state(self, now: float, stall: float) -> str:
        return _process_state(self, now, stall)

    def as_dict(self, now: float, stall: float) -> dict[str, Any]:
        return {"robot": self.robot, "trial": self.trial, "trials": self.trials, "generation": self.generation,
                "performance": self.performance, "rules_version": self.rules_version,
                "capabilities": list(self.capabilities), "changes": self.changes, "last_change": self.last_change,
                "rejected": sum(self.rejected.values()), "rejected_by_reason": dict(self.rejected), "open": self.open,
                "state": self.state(now, stall),
                "heartbeat_age": round(now - self.last_heartbeat, 3) if self.last_heartbeat else None}


class StatusBoard:
    """Subscribes to a run's heartbeats, liveliness and broker status; thread-safe snapshot for display."""

    def __init__(self, session: Session, run: str, *, stall: float = DEFAULT_STALL,
                 restarts: Mapping[str, int] | None = None, generations: int = 0) -> None:
        """``generations``: the run's, shown as a worker's until its first heartbeat says its own (0: unknown)."""
        self.run = run
        self.stall = stall
        self.generations = generations
        self._stopping = False
        self._lock = threading.Lock()
        self.workers: dict[str, WorkerView] = {}
        self.robots: dict[str, RobotView] = {}  # a CEL run's execution module
        self.rejected = 0  # bad messages on the status keys themselves
        self.broker_up = False
        self.broker_seen = False  # its token was ever seen: before that, and for BROKER_GRACE s, it is "starting"
        self.created = time.monotonic()
        self.broker_degraded = False  # its degraded token is up: the store cannot write
        self.broker: BrokerStatus | None = None
        self.changed = threading.Event()
        # Times the run's supervisor (coevo run) started a process again, by behaviour and "broker"; shown by its
        # state.  The supervisor's own counter, read live.
        self.restarts: Mapping[str, int] = restarts if restarts is not None else {}
        gate = getattr(session, "gate", None)
        self.open = gate is None or gate.open  # unverified: anyone on the bus can show up here
        self._roster = None if gate is None else gate.roster
        self._robot = None if gate is None else gate.robot
        self._rings = [ring_subscriber(session, keys.status(run), 256), ring_subscriber(session, keys.broker_status(run), 16),
                       ring_subscriber(session, keys.execution(run), 64)]
        self._decls = [
            session.liveliness().declare_subscriber(keys.alive(run), self._on_token, history=True),
            session.liveliness().declare_subscriber(keys.robot_alive(run), self._on_robot_token, history=True),
            session.liveliness().declare_subscriber(keys.BROKER, self._on_broker, history=True),
            session.liveliness().declare_subscriber(keys.BROKER_DEGRADED, self._on_degraded, history=True),
        ]
        # The broker's state now, before the first display: the subscribers' history arrives a moment later, and
        # until then a broker that is up would be shown down (then up) in the first second.
        for key, take in ((keys.BROKER, self._on_broker), (keys.BROKER_DEGRADED, self._on_degraded)):
            for reply in session.liveliness().get(key, timeout=1.0):
                if reply.ok is not None:
                    take(reply.ok)

    def close(self) -> None:
        for d in self._decls + self._rings:
            try:
                d.undeclare()
            except SessionGone as exc:  # the session was closed first: its declarations went with it
                log.debug("undeclare after the session closed: %s", exc)

    def _view(self, behaviour: str, worker: str) -> WorkerView:
        v = self.workers.get(worker)
        if v is None:
            v = self.workers[worker] = WorkerView(behaviour, worker, generations=self.generations,
                                                  stopping=self._stopping)
        return v

    def stopping(self) -> None:
        """The run was asked to stop (its supervisor sent the stop): a process whose token goes from now on short of
        its end is *stopped*, not dead (one already gone stays dead)."""
        with self._lock:
            self._stopping = True
            views: list[WorkerView | RobotView] = [*self.workers.values(), *self.robots.values()]
            for v in views:
                v.stopping = v.stopping or v.token
        self.changed.set()

    def poll(self) -> None:
        """Take in the heartbeats and broker reports that arrived since the last call."""
        for ring in self._rings:
            for _, msg in drain_messages(ring, 4096, self._reject):
                with self._lock:
                    if isinstance(msg, BrokerStatus):
                        self.broker = msg
                    elif isinstance(msg, Status):
                        self._take(msg)
                    elif isinstance(msg, ExecutionStatus):
                        self._take_robot(msg)

    def _reject(self, err: MessageError, key: str) -> None:
        with self._lock:
            self.rejected += 1

    def _take(self, msg: Status) -> None:
        v = self._view(msg.behaviour, msg.worker)
        if msg.generation < v.generation and not v.died_at:
            return  # an older heartbeat overtaken by a newer one
        v.regime, v.generation, v.generations = msg.regime, msg.generation, msg.generations
        v.best_fitness, v.partner_versions, v.measures = msg.best_fitness, msg.partner_versions, dict(msg.measures)
        v.rejected, v.buffered, v.done, v.open = dict(msg.rejected), msg.buffered, msg.done, msg.open
        v.last_heartbeat = time.time()
        if msg.stopped:  # its last words: it stops in order, before or after its token went
            v.stopping = True
            return
        if v.died_at is None:
            v.token = True  # a heartbeat proves the process is there (its token may still be on its way)
        elif msg.sent_at > v.died_at:
            v.token, v.died_at = True, None  # sent after the death: a restarted worker
            v.stopping = self._stopping

    def _take_robot(self, msg: ExecutionStatus) -> None:
        v = self.robots.setdefault(msg.robot, RobotView(msg.robot))
        if msg.trial < v.trial and not v.died_at:
            return  # an older heartbeat overtaken by a newer one
        for name in ("trial", "trials", "generation", "performance", "rules_version", "changes", "last_change", "done",
                     "open"):
            setattr(v, name, getattr(msg, name))
        v.capabilities, v.rejected = list(msg.capabilities), dict(msg.rejected)
        v.last_heartbeat = time.time()
        if v.died_at is None:
            v.token = True
        elif msg.sent_at > v.died_at:
            v.token, v.died_at = True, None

    def _on_robot_token(self, sample: Sample) -> None:
        robot = keys.parse(str(sample.key_expr)).get("robot", "")
        if self._robot is not None and robot != self._robot:
            with self._lock:
                self.rejected += 1
            return
        alive = is_put(sample)
        with self._lock:
            v = self.robots.setdefault(robot, RobotView(robot, stopping=self._stopping))
            v.token = alive
            v.died_at = None if alive else time.time()
        self.changed.set()

    def _on_token(self, sample: Sample) -> None:
        parts = keys.parse(str(sample.key_expr))
        if "worker" not in parts:
            return
        if self._roster is not None and self._roster.get(parts.get("behaviour", "")) != parts["worker"]:
            with self._lock:
                self.rejected += 1  # a token of a worker outside the roster: a phantom
            return
        alive = is_put(sample)
        with self._lock:
            v = self._view(parts.get("behaviour", "?"), parts["worker"])
            if alive and not v.token:  # (again: a restarted worker) its stop is not its predecessor's
                v.stopping = self._stopping
            v.token = alive
            v.died_at = None if alive else time.time()
        self.changed.set()

    def _on_broker(self, sample: Sample) -> None:
        with self._lock:
            self.broker_up = is_put(sample)
            self.broker_seen = self.broker_seen or self.broker_up
        self.changed.set()

    def _on_degraded(self, sample: Sample) -> None:
        with self._lock:
            self.broker_degraded = is_put(sample)
        self.changed.set()

    def snapshot(self) -> list[dict[str, Any]]:
        self.poll()
        now = time.time()
        with self._lock:
            return [{**v.as_dict(now, self.stall), "restarts": self.restarts.get(v.behaviour, 0)}
                    for v in (self.workers[k] for k in sorted(self.workers))]

    def robots_view(self) -> list[dict[str, Any]]:
        self.poll()
        now = time.time()
        with self._lock:
            return [self.robots[k].as_dict(now, self.stall) for k in sorted(self.robots)]

    def broker_view(self) -> dict[str, Any]:
        self.poll()
        with self._lock:
            b = self.broker
            state = ("up" if self.broker_up else "degraded" if self.broker_degraded else
                     "starting" if not self.broker_seen and time.monotonic() - self.created < BROKER_GRACE else "down")
            return {"state": state, "open": b.open if b else False,
                    "stored": dict(b.stored) if b else {}, "rejected": dict(b.rejected) if b else {},
                    "dropped": b.dropped if b else 0, "degraded": b.degraded if b and state != "up" else "",
                    "restarts": self.restarts.get("broker", 0)}

    def json_line(self) -> str:
        workers = self.snapshot()
        return json.dumps({"run": self.run, "time": time.time(), "open": self.open, "workers": workers,
                           "robots": self.robots_view(), "broker": self.broker_view()})


# ---------------------------------------------------------------- display
def _reasons(counts: dict[str, int]) -> str:
    """Rejections by reason, 'flood 3, wrong_key 1' (a narrow column wraps it after a count, not inside a pair)."""
    return ", ".join(f"{r} {n}" for r, n in sorted(counts.items())) or "0"


_STATE_STYLE = {"starting": "cyan", "alive": "green", "done": "blue", "stalled": "yellow", "dead": "bold red", "stopped": "magenta", "up": "green", "down": "bold red",
                "degraded": "bold yellow"}


def _own(measures: dict[str, float], behaviour: str) -> str:
    """A worker's own measures, short, one word each: 'QT=62%', 'docks=71%', 'picks-D=23% docked=40%'."""
    from coevo.tasks import measure_labels

    labels = measure_labels([behaviour])
    return " ".join(f"{labels.get(k, k)}={v:.0f}%" for k, v in measures.items()) or "-"


def _state(view: dict[str, Any]) -> str:
    """A process's state, with the times the run's supervisor restarted it: 'alive', 'alive, restarted 2x'."""
    n = view.get("restarts", 0)
    return f"{view['state']}, restarted {n}x" if n else view["state"]


def _status_rows(board: StatusBoard) -> list[tuple[str, ...]]:
    """(who, gen, best, own, partners, unconfirmed, rejected, state) per worker, then the broker's row."""
    rows: list[tuple[str, ...]] = []
    for w in board.snapshot():
        who = w["worker"] if w["worker"].startswith(w["behaviour"]) else f"{w['worker']} ({w['behaviour']})"
        partners = " ".join(f"{k[0].upper()}v{v}" for k, v in sorted(w["partner_versions"].items())) or "-"
        rows.append((who, f"{w['generation']}/{w['generations']}", f"{w['best_fitness']:.3f}", _own(w.get("measures", {}), w["behaviour"]),
                     partners, str(w["buffered"]), _reasons(w["rejected_by_reason"]), _state(w)))
    for r in board.robots_view():  # a CEL run's execution module, short (coevo cel has its own table)
        rows.append((r["robot"], f"{r['generation']}", "", f"ext={r['performance']:.0f}%",
                     f"rules v{r['rules_version']}, {len(r['capabilities'])} sensors, {r['changes']} changes", "",
                     _reasons(r["rejected_by_reason"]), r["state"]))
    b = board.broker_view()
    stored = " ".join(f"{k[0].upper()}:{v}" for k, v in sorted(b["stored"].items())) or "-"
    why = f" ({b['degraded']})" if b.get("degraded") else ""  # a degraded store says why: the file and the error
    rows.append(("broker", "", "", "", f"stored {stored}{why}", "", _reasons(b["rejected"]), _state(b)))
    return rows


#: The table's columns: generations done of the run's, the best fitness so far (what a worker's heartbeat carries:
#: the best of every generation up to the latest, which the docs' glossary calls "best so far"), the task's own
#: measures, the partner versions in use, messages rejected by reason, and the state, followed by the count of
#: published versions the broker's store has not confirmed yet when there are any ("alive 12 unstored").
_STATUS_HEADERS = ("worker", "gen", "best", "measures", "partners", "rejected", "state")


def _fit(natural: list[int], minimum: list[int], budget: int) -> list[int]:
    """Column widths within ``budget``: the widest column above its minimum gives way first."""
    widths = list(natural)
    while sum(widths) > budget:
        slack = [w - m for w, m in zip(widths, minimum, strict=True)]
        if max(slack) <= 0:
            break  # even every column at its longest word is too wide; rich will have to fold
        i = max(range(len(widths)), key=lambda j: (widths[j] if slack[j] > 0 else -1, j))
        widths[i] -= 1
    return widths


class _StatusView:
    """Renders the status table at the width of the console it is printed on (see :func:`status_table`)."""

    def __init__(self, rows: list[tuple[str, ...]], title: str) -> None:
        self.title = title
        self.rows = [(*row[:5], row[6], row[7] + (f" {row[5]} unstored" if row[5] not in ("", "0") else ""))
                     for row in rows]
        self.styles = [_STATE_STYLE.get(row[7].split(",")[0]) for row in rows]  # 'alive, restarted 2x': alive's

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        from rich import box
        from rich.table import Table

        cols = list(zip(*self.rows, strict=True))
        natural = [max([len(h)] + [len(c) for c in col]) for h, col in zip(_STATUS_HEADERS, cols, strict=True)]
        minimum = [max([len(h)] + [len(w) for c in col for w in c.split()]) for h, col in zip(_STATUS_HEADERS, cols, strict=True)]
        gaps = 2 * (len(_STATUS_HEADERS) - 1)  # one space of padding either side of every inner column edge
        widths = _fit(natural, minimum, options.max_width - gaps)
        t = Table(title=self.title, box=box.SIMPLE_HEAD, show_edge=False, pad_edge=False, padding=(0, 1),
                  collapse_padding=True, title_justify="left")
        for h, w in zip(_STATUS_HEADERS, widths, strict=True):
            t.add_column(h, width=w, overflow="fold", justify="right" if h in ("gen", "best") else "left")
        for row, style in zip(self.rows, self.styles, strict=True):
            t.add_row(*row, style=style)
        yield t


def status_table(board: StatusBoard, title: str) -> RenderableType:
    """The live status as a rich renderable that fits the console, down to 80 columns: a row per worker and the broker.

    Short headers, no vertical rules, and cells that wrap only between words: no column
    is made narrower than its longest word (a worker id, a rejection reason such as
    ``wrong_behaviour``), the widest ones give way first.
    """
    return _StatusView(_status_rows(board), title)


#: What draws the live table of a board: ``table(board, title)``, a rich renderable.
StatusTable = Callable[["StatusBoard", str], "RenderableType"]


class PlainLines(Protocol):
    """What writes a board as plain lines for a log or a pipe: those that changed since the last call."""

    def lines(self, board: StatusBoard) -> list[str]: ...


class PlainStatus:
    """The status as plain lines for a log or a pipe: one line per worker (and the broker) when it changed."""

    def __init__(self) -> None:
        self._last: dict[str, str] = {}

    def lines(self, board: StatusBoard) -> list[str]:
        """A line per worker (and the broker) that changed; counts that are 0 are left out, to keep lines short."""
        out = []
        stamp = time.strftime("%H:%M:%S")
        for who, gen, best, own, partners, unc, rejected, state in _status_rows(board):
            also = (f" unstored {unc}" if unc not in ("", "0") else "") + (f" rejected {rejected}" if rejected != "0" else "")
            if who == "broker":
                text = f"broker {state} {partners}{also}"
            elif state == "starting":
                text = f"{who} starting{also}"  # nothing learned yet to show
            elif not best:  # a CEL run's execution module: no fitness, no partners of its own
                text = f"{who} gen {gen} {own} {partners}{also} {state}"
            else:
                measures = "" if own == "-" else f" {own}"
                using = "" if partners == "-" else f" with {partners}"  # the partner versions it learns against
                text = f"{who} gen {gen} best {best}{measures}{using}{also} {state}"
            if self._last.get(who) != text:
                self._last[who] = text
                out.append(f"{stamp} {text}")
        return out


class StatusDisplay:
    """Shows a board on the terminal as it changes: a live table on a terminal, plain lines in a log
    or a pipe (no box drawing, no redraws), JSON lines with ``json``, nothing with ``quiet``."""

    def __init__(self, title: str, *, json_lines: bool = False, quiet: bool = False, table: StatusTable | None = None,
                 plain: PlainLines | None = None) -> None:
        """``table(board, title)`` and ``plain.lines(board)`` draw it (default: :func:`status_table`, :class:`PlainStatus`)."""
        self.title, self.json_lines, self.quiet = title, json_lines, quiet
        self.live = not (json_lines or quiet) and sys.stdout.isatty()
        self._table: StatusTable = table or status_table
        self._plain: PlainLines = plain or PlainStatus()
        self._rich: Live | None = None

    def __enter__(self) -> StatusDisplay:
        if self.live:
            from rich.live import Live

            self._rich = Live(auto_refresh=False, transient=False)
            self._rich.start()
        return self

    def show(self, board: StatusBoard) -> None:
        if self.quiet:
            return
        if self.json_lines:
            print(board.json_line(), flush=True)
        elif self._rich is not None:
            self._rich.update(self._table(board, self.title.replace("{time}", time.strftime("%H:%M:%S"))), refresh=True)
        else:
            for line in self._plain.lines(board):
                print(line, flush=True)

    def __exit__(self, *exc: object) -> None:
        if self._rich is not None:
            self._rich.stop()
            self._rich = None


def follow(conf: Config, run: str, show: Callable[[StatusBoard], None], *, every: float, stall: float = DEFAULT_STALL,
           duration: float | None = None, gate: Gate | None = None, until: Callable[[], object] | None = None) -> None:
    """``coevo status``: follow ``run``'s workers, calling ``show(board)`` when something changed (or every
    ``every`` s), for ``duration`` s, until ``until()`` is true (checked every ``every`` s) or until SIGINT/SIGTERM."""
    from coevo.bus.session import open_session, sigterm_as_exit

    sigterm_as_exit()
    end = time.monotonic() + duration if duration else None
    with open_session(conf, what="status session", gate=gate) as s:
        board = StatusBoard(s, run, stall=stall)
        try:
            while end is None or time.monotonic() < end:
                board.changed.wait(every)
                board.changed.clear()
                show(board)
                if until is not None and until():
                    break
        except KeyboardInterrupt:
            pass
        finally:
            board.close()
