"""The kinds of learner a run may hold, in one place.

Two kinds exist: the co-evolution worker (:class:`coevo.agents.worker.Worker`: a GA fed its
partners' policies) and the CEL learner of ``coevo cel`` (:mod:`coevo.cel_service`: a GA
whose model follows a robot's capabilities, beside an execution module that is no worker).
For each this table says which worker class ``coevo worker`` starts, how ``coevo replay``
plays a worker's curve again, and what ``coevo check`` and ``coevo replay`` read that only
that kind writes.  A new kind of learner is a package of its own and an entry here; the
worker, the check and the replay name no kind.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from coevo.rundir.layout import RunPaths

if TYPE_CHECKING:
    from coevo.agents.worker import Worker
    from coevo.rundir.settings import RunSettings

__all__ = ["LearnerKind", "KINDS", "kind_of_settings", "kind_of_worker", "run_kinds"]

#: (behaviour, version) -> (worker id, digest of its rules): what the run's workers published, by their own logs.
Published = dict[tuple[str, int], tuple[str, str]]


@dataclass(frozen=True)
class LearnerKind:
    name: str
    worker: Callable[[], type[Worker]]  # the Worker class (imported only when a worker of this kind starts)
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


def _later(module: str, name: str) -> Callable[..., Any]:
    """``module.name``, imported when first called (a kind's code loads only where that kind is met)."""
    def call(*args: Any) -> Any:
        return getattr(importlib.import_module(module), name)(*args)

    return call


_AUDIT = "coevo.cel_service.audit"

KINDS: dict[str, LearnerKind] = {
    "coevolution": LearnerKind("coevolution", _coevolution_worker),
    "cel": LearnerKind("cel", _cel_worker, curve=_later(_AUDIT, "learner_curve"),
                       present=lambda run: run.execution.meta_json.exists(),
                       check_run=_later(_AUDIT, "check_execution"), replay_run=_later(_AUDIT, "replay_execution")),
}


def kind_of_settings(settings: RunSettings) -> LearnerKind:
    """The kind a run's settings make its workers (a ``cel`` block: the CEL learner)."""
    return KINDS["cel" if settings.cel is not None else "coevolution"]


def kind_of_worker(meta: dict[str, Any]) -> LearnerKind:
    """The kind of the worker whose ``worker.json`` is ``meta``."""
    return KINDS["cel" if "cel" in meta else "coevolution"]


def run_kinds(run: RunPaths) -> list[LearnerKind]:
    """The kinds whose own modules a run directory holds (their check and replay hooks apply)."""
    return [k for k in KINDS.values() if k.present is not None and k.present(run)]
