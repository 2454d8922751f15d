"""The kinds of learner a run may hold, found by name (:mod:`coevo.rundir.kinds`), and coevo's default one.

``coevolution`` is the co-evolution worker of ``coevo run``: a GA fed its partners' policies
(:class:`coevo.agents.worker.Worker`), supervised by :class:`coevo.runs.local.LocalRun`.  It is declared here and
installed as an entry point like any other kind; a run whose settings hold no kind's block is of this kind.  The
functions here tell a run's kind from its settings, a worker's from its worker.json, and which kinds' own modules
a run directory holds; none of them names a kind.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from coevo.rundir.kinds import KINDS, LearnerKind, Published, later_class
from coevo.rundir.layout import RunPaths

if TYPE_CHECKING:
    from coevo.rundir.settings import RunSettings

__all__ = ["LearnerKind", "KINDS", "COEVOLUTION", "Published", "kind_of_settings", "kind_of_worker", "run_kinds"]

#: The kind of a run whose settings hold no kind's block: workers fed their partners' policies (``coevo run``).
COEVOLUTION = LearnerKind("coevolution", "a co-evolution run", later_class("coevo.agents.worker", "Worker"),
                          later_class("coevo.runs.local", "LocalRun"))


def kind_of_settings(settings: RunSettings) -> LearnerKind:
    """The kind a run's settings make its workers: the kind whose block they hold, else co-evolution."""
    return next((KINDS.get(name) for name in settings.blocks), COEVOLUTION)


def kind_of_worker(meta: dict[str, Any]) -> LearnerKind:
    """The kind of the worker whose ``worker.json`` is ``meta`` (it holds its kind's block, under the kind's name)."""
    return next((KINDS.get(name) for name in KINDS.names() if name in meta and isinstance(meta[name], dict)),
                COEVOLUTION)


def run_kinds(run: RunPaths) -> list[LearnerKind]:
    """The kinds whose own modules a run directory holds (their check and replay hooks apply)."""
    return [k for k in KINDS.usable().values() if k.present is not None and k.present(run)]
