"""``coevo cel``'s live table: the run at a glance, from the same status board as ``coevo status``.

The learner's generation and best simulated success (its latest generation's best on the
model), the robot's external performance, capability list and last change, and whether each
process is alive.  On a terminal it is a small two-column table redrawn as it changes; in a
log or a pipe, one line whenever something in it changed.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from coevo.tasks.door import DOOR

if TYPE_CHECKING:
    from rich.console import Console, ConsoleOptions, RenderResult

    from coevo.bus.status import StatusBoard, StatusTable

__all__ = ["cel_facts", "cel_table", "CelPlain"]


def cel_facts(board: StatusBoard, trials_per_generation: int) -> list[tuple[str, str]]:
    """(what, value) rows of the run's state."""
    learner = next((w for w in board.snapshot() if w["behaviour"] == DOOR), None)
    robot = next(iter(board.robots_view()), None)
    broker = board.broker_view()
    rows = []
    if learner is None or not learner["generations"]:  # no heartbeat yet (a liveliness token alone)
        rows += [("generation", "learner starting")]
    else:
        rows += [("generation", f"{learner['generation']} / {learner['generations']}"),
                 ("best simulated", f"{learner['measures'].get('success', 0.0):.0f} % success on the learner's model")]
    if robot is None or not robot["trials"]:
        rows += [("external", "robot starting")]
    else:
        last = "none" if robot["last_change"] is None else \
            f"trial {robot['last_change']} (generation {robot['last_change'] // trials_per_generation}), change {robot['changes']}"
        rows += [("external", f"{robot['performance']:.0f} % of its last trials (trial {robot['trial']} / {robot['trials']}, "
                              f"rules v{robot['rules_version']})"),
                 ("capabilities", ", ".join(robot["capabilities"]) or "none"),
                 ("last change", last)]
    rejected = sum((learner or {}).get("rejected_by_reason", {}).values()) + (robot or {}).get("rejected", 0)
    rows += [("processes", f"learner {(learner or {}).get('state', '?')}, robot {(robot or {}).get('state', '?')}, "
                           f"broker {broker['state']}"),
             ("rejected", str(rejected + getattr(board, "rejected", 0)))]
    return rows


class _View:
    def __init__(self, rows: list[tuple[str, str]], title: str) -> None:
        self.rows, self.title = rows, title

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        from rich import box
        from rich.table import Table

        t = Table(title=self.title, box=box.SIMPLE, show_header=False, title_justify="left", pad_edge=False)
        t.add_column("what", style="bold", no_wrap=True)
        t.add_column("value", overflow="fold")
        for what, value in self.rows:
            style = "bold red" if what == "processes" and "dead" in value else None
            t.add_row(what, value, style=style)
        yield t


def cel_table(trials_per_generation: int) -> StatusTable:
    """A ``table(board, title)`` for :class:`~coevo.bus.status.StatusDisplay`."""
    return lambda board, title: _View(cel_facts(board, trials_per_generation), title)


class CelPlain:
    """The run's state as one plain line whenever it changed (for a log or a pipe)."""

    def __init__(self, trials_per_generation: int) -> None:
        self.K = trials_per_generation
        self._last = ""

    def lines(self, board: StatusBoard) -> list[str]:
        text = "; ".join(f"{what} {value}" for what, value in cel_facts(board, self.K))
        if text == self._last:
            return []
        self._last = text
        return [f"{time.strftime('%H:%M:%S')} {text}"]
