"""What a kind of learner is, and the kinds installed: plugins found by name (the entry-point group ``coevo.kinds``).

A run's workers are of one kind.  coevo's own kinds are declared as entry points in its pyproject.toml, like any
other package's (``coevo plugins`` lists them).  A :class:`LearnerKind` says which worker class ``coevo worker``
starts, which run class starts, supervises and resumes its processes (and so which command continues it), its own
settings (a block of ``run.json`` under the kind's name, which checks itself against the run), how ``coevo
replay`` plays a worker's curve again, and what ``coevo check`` and ``coevo replay`` read that only that kind
writes.  Everything it names is imported when first used, so a kind's code loads only where one of its runs is met.

A new kind is a package of its own (above :mod:`coevo.runs`, whose run class it may extend) and an entry point;
the worker, the run, chaos, check and replay name no kind.  This module sits with the run directory because a
run's settings are where a kind is told apart (:class:`coevo.rundir.settings.RunSettings` reads each kind's block).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from coevo.plugins import KINDS_GROUP, Plugins

if TYPE_CHECKING:
    from pydantic import BaseModel

    from coevo.config import GAConfig
    from coevo.rundir.layout import RunPaths

__all__ = ["LearnerKind", "KINDS", "Published", "later", "get_kind", "kind_names"]

#: (behaviour, version) -> (worker id, digest of its rules): what the run's workers published, by their own logs.
Published = dict[tuple[str, int], tuple[str, str]]


@dataclass(frozen=True)
class LearnerKind:
    name: str
    label: str  # in messages, e.g. "a co-evolution run"
    worker: Callable[[], type[Any]]  # the Worker class (imported only when a worker of this kind starts)
    run: Callable[[], type[Any]]  # the LocalRun class that starts, supervises and resumes a run's processes
    #: the model of the kind's own settings, kept in run.json (and worker.json) under the kind's name; None: none
    #: (the model has ``check_fits(task=, generations=, worker_ids=)``; a ``robot`` field, if any, is the run's robot)
    settings: Callable[[], type[BaseModel]] | None = None
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

    @property
    def block(self) -> str | None:
        """The key of run.json (and worker.json) that holds this kind's settings and so marks its runs."""
        return self.name if self.settings is not None else None


def _make_kind(name: str, obj: object) -> LearnerKind:
    if not isinstance(obj, LearnerKind):
        raise TypeError(f"{obj!r} is not a coevo kind of learner (a coevo.rundir.kinds.LearnerKind)")
    if obj.name != name:
        raise TypeError(f"it is installed as {name!r} but calls itself {obj.name!r}")
    return obj


#: Every kind of learner installed or registered, by name; imported when first named.
KINDS: Plugins[LearnerKind] = Plugins(KINDS_GROUP, "kind of learner", _make_kind)


def get_kind(name: str) -> LearnerKind:
    return KINDS.get(name)


def kind_names() -> list[str]:
    return KINDS.names()


def later(module: str, name: str) -> Callable[..., Any]:
    """``module.name`` called, imported when first called (a kind's code loads only where that kind is met)."""
    def call(*args: Any) -> Any:
        return getattr(importlib.import_module(module), name)(*args)

    return call


def later_class(module: str, name: str) -> Callable[[], Any]:
    """``module.name`` itself, imported when first asked for (a kind's worker, run or settings class)."""
    def get() -> Any:
        return getattr(importlib.import_module(module), name)

    return get
