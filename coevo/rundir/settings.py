"""A run's settings, passed once: written to ``run.json`` by the command that starts the run and
loaded by every process of it, instead of being turned into command-line text and parsed back.

``coevo run`` writes it (``coevo compare`` hands each of its runs one), each ``coevo worker``
it starts reads it with ``--settings RUN/run.json``, ``--resume`` reads it back, and
``coevo replay``/``check`` find everything they need beside it.  The world's settings are
those of the run's task, validated by the task's own model and stored in full.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final, Literal

from pydantic import BaseModel, Field, SerializerFunctionWrapHandler, field_validator, model_serializer, model_validator

from coevo.bus.auth import KEY_ENV, RunKey
from coevo.bus.keys import check_id
from coevo.bus.trust import Gate
from coevo.config import DEFAULT_MAX_LEAD, HALL_SAMPLE, HALL_SHARE, MODELS, GAConfig, Settings, build
from coevo.errors import CoevoError, ConfigError, MessageError, RunDirError
from coevo.rundir.kinds import KINDS
from coevo.rundir.layout import RunPaths, read_json, write_json
from coevo.tasks import DEFAULT_TASK, Task, get_task, saved_settings
from coevo.tasks.base import check_ga, check_regime

__all__ = ["RunSettings", "SETTINGS_VERSION", "find_run_key"]

SETTINGS_VERSION: Final = 1
class RunSettings(Settings):
    """Everything a run's processes share; see the module docstring."""

    settings_version: Literal[1] = SETTINGS_VERSION
    run: str = Field(description="run id: the run directory's name and the keys' run chunk")
    task: str = DEFAULT_TASK
    regime: str
    seed: int = Field(0, ge=0, lt=2**63, description="worker i of the task's behaviours uses seed + i")
    model: Literal["best", "current", "recent", "hall"] = Field("best", description=f"how partners are modelled: "
                                                                f"{', '.join(MODELS)}")
    hall_sample: int = Field(HALL_SAMPLE, ge=1, le=1000, description="model hall: past bests of each partner sampled "
                             "for each generation")
    hall_share: float = Field(HALL_SHARE, gt=0.0, lt=1.0, description="model hall: the share of the population's "
                              "episodes played against the sampled past bests, split evenly among them")
    max_lead: int | None = Field(DEFAULT_MAX_LEAD, ge=0, description="pacing: generations a worker may lead (None: unpaced)")
    world: dict[str, Any] = Field(default_factory=dict, description="the task's world settings")
    ga: GAConfig = GAConfig()
    roster: dict[str, str] | None = Field(None, description="behaviour -> the worker id that publishes it; a policy or "
                                          "status from any other is rejected (None: any worker id, a run by hand)")
    key_file: str | None = Field(None, description="the run's secret key file, relative to run.json's directory "
                                 "(None: an open run, its messages unauthenticated)")
    blocks: dict[str, Any] = Field(default_factory=dict, description="a kind of learner's own settings, by the kind's "
                                   "name (coevo.rundir.kinds); run.json keeps each at its top level, under that name")
    endpoint: str | None = Field(None, description="where the run's broker listens (its latest start)")
    incarnation: int = Field(0, ge=0, description="the run's incarnation: 1 when coevo run makes it, +1 with every "
                             "coevo run --resume; sealed into every message, so a message of an earlier one (a "
                             "captured stop) is refused as stale (0: a run by hand, none)")
    started: float | None = None

    @field_validator("run")
    @classmethod
    def _run_id(cls, v: str) -> str:
        return check_id("run id", v)

    @model_validator(mode="before")
    @classmethod
    def _gather_blocks(cls, data: Any) -> Any:
        """run.json's top-level keys that name an installed kind of learner are that kind's settings."""
        if not isinstance(data, dict):
            return data
        named = {k: v for k, v in data.items() if k not in cls.model_fields and k in KINDS}
        if not named:
            return data
        blocks = {k: v for k, v in named.items() if v is not None}  # runs saved before kinds were plugins: a kind's key, null
        return {k: v for k, v in data.items() if k not in named} | {"blocks": {**(data.get("blocks") or {}), **blocks}}

    @model_serializer(mode="wrap")
    def _spread_blocks(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """Each kind's block back at run.json's top level, where the "blocks" field stands (as runs always kept it);
        the hall of fame's settings only where the partner model is the hall (other runs' run.json as it always was)."""
        out: dict[str, Any] = {}
        for k, v in handler(self).items():
            if k == "blocks":
                out.update(v)
            elif not (k.startswith("hall_") and self.model != "hall"):
                out[k] = v
        return out

    @field_validator("blocks")
    @classmethod
    def _known_blocks(cls, blocks: dict[str, Any]) -> dict[str, Any]:
        out = {}
        for name, block in blocks.items():
            kind = KINDS.get(name)
            if kind.settings is None:
                raise ValueError(f"{name}: the kind of learner {name!r} has no settings of its own")
            model = kind.settings()
            out[name] = block if isinstance(block, model) else build(model, block)
        if len(out) > 1:
            raise ValueError(f"settings of {len(out)} kinds of learner ({', '.join(out)}): a run is of one kind")
        return out

    def block(self, kind: str) -> Any:
        """The settings of kind of learner ``kind`` in this run (its model), or None if the run is not of that kind."""
        return self.blocks.get(kind)

    @model_validator(mode="after")
    def _task_fits(self) -> RunSettings:
        task = get_task(self.task)
        check_regime(task, self.regime)
        if self.roster is not None:
            if set(self.roster) != set(task.behaviours):
                raise ValueError(f"roster names {sorted(self.roster)}; it must name each of {list(task.behaviours)}")
            for b, w in self.roster.items():
                check_id(f"roster worker id for {b}", w)
        for block in self.blocks.values():  # a learner kind's own settings say what runs they fit (coevo.rundir.kinds)
            block.check_fits(task=self.task, generations=self.ga.generations, worker_ids=(self.roster or {}).values())
        try:
            check_ga(task, self.ga)  # every worker's GA settings as the task fills them in, before a run starts
        except ConfigError as exc:
            raise ValueError(str(exc)) from None
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

    def worker_ident(self, behaviour: str) -> dict[str, Any]:
        """Who the run's worker of ``behaviour`` is (run, behaviour, roster worker id, seed): what its checkpoint
        names (:func:`coevo.agents.checkpoint.load_checkpoint` refuses another's)."""
        roster = self.roster or self.default_roster()
        return {"run": self.run, "behaviour": behaviour, "worker": roster[behaviour], "seed": self.worker_seed(behaviour)}

    def default_roster(self) -> dict[str, str]:
        """Each behaviour's worker named as workers name themselves: BEHAVIOUR-SEED."""
        return {b: f"{b}-{self.worker_seed(b)}" for b in self.the_task.behaviours}

    def with_roster(self) -> RunSettings:
        """These settings with a roster (the default one if there is none yet)."""
        return self if self.roster is not None else self.model_copy(update={"roster": self.default_roster()})

    def gate(self, key: RunKey | None, *, reject: Callable[[MessageError, str], None] | None = None) -> Gate:
        """What the run's receivers accept: its key (None: open), its roster, the generations a policy can reach
        (when there is a roster) and, in a run whose kind's settings name a robot, that robot."""
        roster = self.roster
        robot = next((b.robot for b in self.blocks.values() if getattr(b, "robot", None) is not None), None)
        return Gate(key=key, roster=roster, generations=self.ga.generations if roster is not None else None,
                    robot=robot if roster is not None else None, reject=reject, epoch=self.incarnation)

    def key_path(self, base: Path) -> Path | None:
        """The key file's path (``key_file`` relative to ``base``, run.json's directory); None in an open run."""
        return None if self.key_file is None else Path(base) / self.key_file

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
            data = saved_settings(data)  # as the run learned: saved before some setting existed, or where it was
            return build(cls, data)
        except ConfigError as exc:
            raise RunDirError(f"{str(path)!r} does not hold valid run settings: {exc}") from None

    def fresh(self, run: str | None = None) -> RunSettings:
        """The same settings for a new run (named ``run``, else the same): no endpoint, key or roster of the old one."""
        data = self.model_dump(mode="json") | {"endpoint": None, "started": None, "key_file": None, "roster": None,
                                               "incarnation": 0}
        return RunSettings.make(**(data | ({"run": run} if run is not None else {})))

    def restarted(self, endpoint: str) -> RunSettings:
        """The same run, its broker now at ``endpoint``."""
        return self.model_copy(update={"endpoint": endpoint, "started": time.time()})


def find_run_key(flag: str | None, settings: RunSettings, base: Path | None) -> RunKey | None:
    """A process's run key: ``flag`` (its ``--key-file``), else ``$COEVO_RUN_KEY_FILE``, else the key file
    ``run.json`` names (``base``: run.json's directory); None: the run is open."""
    path = flag or os.environ.get(KEY_ENV) or (settings.key_path(base) if base is not None else None)
    return None if path is None else RunKey.load(Path(path), run=settings.run)
