"""The kinds of learner a run may hold, in one place.

Two kinds exist: the co-evolution worker (:class:`coevo.agents.worker.Worker`: a GA fed its
partners' policies) and the CEL learner of ``coevo cel`` (:mod:`coevo.cel_service`: a GA
whose model follows a robot's capabilities, beside an execution module that is no worker).
For each this table says which worker class ``coevo worker`` starts, which run class starts
and supervises its processes and which command starts and resumes it, what marks a run of
that kind (a block of its own in ``run.json``, which checks itself against the run), how
``coevo replay`` plays a worker's curve again, and what ``coevo check`` and ``coevo replay``
read that only that kind writes.  A new kind of learner is a package of its own and an entry
here; the worker, the run, chaos, check and replay name no kind.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from coevo.rundir.layout import RunPaths

if TYPE_CHECKING:
    from coevo.agents.worker import Worker
    from coevo.config import GAConfig
    from coevo.rundir.settings import RunSettings
    from coevo.runs.local import LocalRun

__all__ = ["LearnerKind", "KINDS", "COEVOLUTION", "CEL", "kind_of_settings", "kind_of_worker", "run_kinds"]

#: (behaviour, version) -> (worker id, digest of its rules): what the run's workers published, by their own logs.
Published = dict[tuple[str, int], tuple[str, str]]


@dataclass(frozen=True)
class LearnerKind:
    name: str
    label: str  # in messages: "a CEL run"
    worker: Callable[[], type[Worker]]  # the Worker class (imported only when a worker of this kind starts)
    run: Callable[[], type[LocalRun]]  # the class that starts, supervises and resumes a run's processes
    #: the field of RunSettings (and key of worker.json) that makes a run this kind; None: the kind with none
    block: str | None = None
    default_task: str | None = None  # the task its commands run unless told (None: coevo.tasks.DEFAULT_TASK)
    #: the run settings ``coevo chaos`` adds for a run of this kind, given its GA settings (its block, pacing)
    chaos_settings: Callable[[GAConfig], dict[str, Any]] | None = None
    #: a worker's learning curve again (worker paths, worker.json, world, GAConfig); None: the co-evolution GA's
    curve: Callable[..., Iterator[dict[str, Any]]] | None = None
    #: does a run directory hold this kind's own modules (beyond its workers)?
    present: Callable[[RunPaths], bool] | None = None
    #: problems and facts of those modules, given what the workers published
    check_run: Callable[[RunPaths, Published], tuple[list[str], dict[str, Any]]] | None = None
    #: those modules played again: (what, generations, first mismatch or None, detail)
    replay_run: Callable[[RunPaths], tuple[str, int, int | None, str]] | None = None


def _coevolution_worker() -> type[Worker]:
    from coevo.agents.worker import Worker

    return Worker


def _cel_worker() -> type[Worker]:
    from coevo.cel_service.learner import CelLearner

    return CelLearner


def _local_run() -> type[LocalRun]:
    from coevo.runs.local import LocalRun

    return LocalRun


def _cel_run() -> type[LocalRun]:
    from coevo.runs.cel import CelRun

    return CelRun


def _cel_chaos_settings(ga: GAConfig) -> dict[str, Any]:
    """A CEL run under ``coevo chaos``: Figure 3's failure halfway through, the learner in lockstep with the robot."""
    from coevo.cel.settings import FIGURE3_SCHEDULE

    return {"cel": {"schedule": [[ga.generations // 2, list(FIGURE3_SCHEDULE[0][1])]]}, "max_lead": 0}


def _later(module: str, name: str) -> Callable[..., Any]:
    """``module.name``, imported when first called (a kind's code loads only where that kind is met)."""
    def call(*args: Any) -> Any:
        return getattr(importlib.import_module(module), name)(*args)

    return call


_AUDIT = "coevo.cel_service.audit"

KINDS: dict[str, LearnerKind] = {
    "coevolution": LearnerKind("coevolution", "a co-evolution run", _coevolution_worker, _local_run),
    "cel": LearnerKind("cel", "a CEL run", _cel_worker, _cel_run, block="cel", default_task="door",
                       chaos_settings=_cel_chaos_settings,
                       curve=_later(_AUDIT, "learner_curve"), present=lambda run: run.execution.meta_json.exists(),
                       check_run=_later(_AUDIT, "check_execution"), replay_run=_later(_AUDIT, "replay_execution")),
}
#: The kind of a run whose settings hold no kind's block: workers fed their partners' policies (``coevo run``).
COEVOLUTION = KINDS["coevolution"]
#: A CEL run's learner (``coevo cel``; ``coevo chaos --cel``).
CEL = KINDS["cel"]


def kind_of_settings(settings: RunSettings) -> LearnerKind:
    """The kind a run's settings make its workers: the kind whose block they hold, else co-evolution."""
    return next((k for k in KINDS.values() if k.block is not None and getattr(settings, k.block, None) is not None),
                COEVOLUTION)


def kind_of_worker(meta: dict[str, Any]) -> LearnerKind:
    """The kind of the worker whose ``worker.json`` is ``meta`` (it holds its kind's block)."""
    return next((k for k in KINDS.values() if k.block is not None and k.block in meta), COEVOLUTION)


def run_kinds(run: RunPaths) -> list[LearnerKind]:
    """The kinds whose own modules a run directory holds (their check and replay hooks apply)."""
    return [k for k in KINDS.values() if k.present is not None and k.present(run)]
