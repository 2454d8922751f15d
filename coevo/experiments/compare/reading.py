"""How a comparison of one task is read: the panels of curves it draws, the classes it sorts runs into, the
behaviour whose curve its summary quotes, the rule files its report reads and the report that writes it all down.

A task names its reading by a dotted path (``Task.comparison``, "module:NAME", imported when a comparison of it is
read, as an entry point is), or none: then it is read the way any task can be, by :data:`generic`'s rules — each
behaviour's learning curve, every measure of the runs' final policies together (its ``run_measures``) compared
between the regimes (:mod:`coevo.experiments.compare.any_task`).  The fuel task's reading is the report's own:
Table 1's classes, the Executive's curve and the Docking probe (:mod:`coevo.experiments.compare.table1`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from coevo.errors import ConfigError

__all__ = ["Panel", "Reading", "reading_of", "write_report"]


class Panel(NamedTuple):
    """One panel of curves: its title, the behaviour and curve column it draws, its y label and the top of its axis
    (None: as high as the curves go).  A panel with a top draws a measure whose range is 0 to that top (a rate in %,
    a payoff): its axis starts at 0 and its bands are cut at that range."""

    title: str
    behaviour: str
    column: str
    ylabel: str
    top: float | None

    @property
    def bounds(self) -> tuple[float, float] | None:
        """The range of the measure it draws, what its bands are cut at: 0 to its top; None without a top."""
        return None if self.top is None else (0.0, float(self.top))


@dataclass(frozen=True)
class Reading:
    """How comparisons of a task are read (the module docstring)."""

    #: The panels of the regimes' curves (each regime's figure, regimes.png, the dashboard's comparison page).
    panels: tuple[Panel, ...]
    #: "module:function" writing the report: ``function(out, spec, *, elapsed) -> results`` (results.json's data).
    report: str = "coevo.experiments.compare.any_task:write_report"
    #: A finished run's class from its measures (the fuel task's Table 1), or None: runs are not classed.
    classify: Callable[[Mapping[str, float]], str] | None = None
    classes: tuple[str, ...] = ()
    #: The counts of classes the original study found, by regime, shown beside ours.
    report_counts: Mapping[str, Mapping[str, int]] = field(default_factory=dict)
    #: The behaviour whose generation's best the summary and the dashboard quote, or None.
    curve: str | None = None
    #: Behaviours whose final best.rules the report reads of every finished run (checked before a resume).
    rules_read: tuple[str, ...] = ()


def generic(behaviours: tuple[str, ...]) -> Reading:
    """The reading of a task that names none: each behaviour's generation's best and best so far."""
    return Reading(panels=tuple(Panel(f"{b.capitalize()} learning curve", b, column, ylabel, None)
                                for column, ylabel in (("best_fitness", "generation's best fitness"),
                                                       ("best_so_far", "best fitness so far"))
                                for b in behaviours))


def _load(path: str, what: str) -> Any:
    module, _, name = path.partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"{what} {path!r} cannot be loaded: {exc}") from None


def reading_of(task: Any) -> Reading:
    """The reading ``task`` names (``Task.comparison``), or the generic one."""
    path = getattr(task, "comparison", None)
    if not path:
        return generic(tuple(task.behaviours))
    reading = _load(path, f"the {task.name} task's comparison reading")
    if not isinstance(reading, Reading):
        raise ConfigError(f"the {task.name} task's comparison reading {path!r} is not a Reading")
    return reading


def write_report(out: Any, spec: Any, *, elapsed: float | None = None) -> dict[str, Any]:
    """The report of the comparison in ``out`` as its task's reading writes it; returns the results."""
    reading = reading_of(spec.the_task)
    writer: Callable[..., dict[str, Any]] = _load(reading.report, f"the {spec.task} task's comparison report")
    return writer(out, spec, elapsed=elapsed)
