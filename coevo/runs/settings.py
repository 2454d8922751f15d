"""A run's settings, passed once: written to ``run.json`` by the command that starts the run and
loaded by every process of it, instead of being turned into command-line text and parsed back.

``coevo run`` writes it (``coevo compare`` hands each of its runs one), each ``coevo worker``
it starts reads it with ``--settings RUN/run.json``, ``--resume`` reads it back, and
``coevo replay``/``check`` find everything they need beside it.  The world's settings are
those of the run's task, validated by the task's own model and stored in full.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, Field, field_validator, model_validator

from coevo.agents.models import MODELS
from coevo.agents.pacing import DEFAULT_MAX_LEAD
from coevo.bus.keys import check_id
from coevo.config import GAConfig, Settings, build
from coevo.errors import ConfigError, CoevoError, RunDirError
from coevo.runs.layout import RunPaths, read_json, write_json
from coevo.tasks import DEFAULT_TASK, Task, get_task

__all__ = ["RunSettings", "SETTINGS_VERSION"]

SETTINGS_VERSION = 1


class RunSettings(Settings):
    """Everything a run's processes share; see the module docstring."""

    settings_version: Literal[1] = SETTINGS_VERSION
    run: str = Field(description="run id: the run directory's name and the keys' run chunk")
    task: str = DEFAULT_TASK
    regime: str
    seed: int = Field(0, ge=0, lt=2**63, description="worker i of the task's behaviours uses seed + i")
    model: Literal["best", "current", "recent"] = Field("best", description=f"how partners are modelled: {', '.join(MODELS)}")
    max_lead: int | None = Field(DEFAULT_MAX_LEAD, ge=0, description="pacing: generations a worker may lead (None: unpaced)")
    world: dict[str, Any] = Field(default_factory=dict, description="the task's world settings")
    ga: GAConfig = GAConfig()
    endpoint: str | None = Field(None, description="where the run's broker listens (its latest start)")
    started: float | None = None

    @field_validator("run")
    @classmethod
    def _run_id(cls, v: str) -> str:
        return check_id("run id", v)

    @model_validator(mode="after")
    def _task_fits(self) -> RunSettings:
        task = get_task(self.task)
        task.check_regime(self.regime)
        full = build(task.world_settings, self.world).model_dump(mode="json")
        object.__setattr__(self, "world", full)  # stored in full: a later default change cannot alter the run
        return self

    @classmethod
    def make(cls, **values: Any) -> RunSettings:
        """Built from keyword values, every failure a ConfigError naming the field and value."""
        try:
            return build(cls, values)
        except CoevoError as exc:
            raise ConfigError(str(exc).replace("RunSettings: ", "run settings: ", 1)) from None

    @property
    def the_task(self) -> Task:
        return get_task(self.task)

    def world_config(self) -> BaseModel:
        """The world's settings as the task's model."""
        return build(self.the_task.world_settings, self.world)

    def worker_seed(self, behaviour: str) -> int:
        return self.seed + self.the_task.behaviours.index(behaviour)

    def paths(self, root: Path) -> RunPaths:
        return RunPaths.of(root, self.run)

    def save(self, path: Path) -> None:
        write_json(path, self.model_dump(mode="json"))

    @classmethod
    def load(cls, path: Path) -> RunSettings:
        """The settings in ``path`` (a run.json); anything wrong with it is a RunDirError naming it."""
        data = read_json(path, what="run directory (its run.json)")
        data.setdefault("settings_version", SETTINGS_VERSION)  # run.json of runs made before it was versioned
        try:
            return build(cls, data)
        except ConfigError as exc:
            raise RunDirError(f"{str(path)!r} does not hold valid run settings: {exc}") from None

    def restarted(self, endpoint: str) -> RunSettings:
        """The same run, its broker now at ``endpoint``."""
        return self.model_copy(update={"endpoint": endpoint, "started": time.time()})
