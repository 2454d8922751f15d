"""A study's declaration: its factors and fixed settings (a TOML file, then the command line); its cells and seeds.

Factors and settings share one set of names; a name with one level is a fixed setting, one with several a factor:

============== ======================================================== ===========================
name           levels                                                   the flag it stands for
============== ======================================================== ===========================
regime         mutual, independent, independent-offline                 ``coevo compare --regimes``
rate           rates of asynchrony of independent-offline (> 0)         ``--rates``
max_lead       pacing bound: generations a worker may lead, or ``off``  ``--max-lead``
model          partner model: best, current, recent                     ``--model``
runs           runs per regime in a cell (1-1000)                       ``--runs``
measure_epochs fresh epochs measuring each final robot                  ``--measure-epochs``
ga.NAME        any GA setting                                           ``--ga NAME=VALUE``
world.NAME     any world setting                                        ``--world NAME=VALUE``
learn          the behaviour every cell learns: docking or tracking     ``coevo study --learn``
============== ======================================================== ===========================

``regime`` and ``rate`` vary *inside* a cell: a cell is one ``coevo compare`` (its regimes paired by seed, its
offline Executives learning at every rate on the same recorded live runs), so they cost no extra live runs.  Every
other factor varies *between* cells: the cells are the cartesian product of those factors' levels, in the order
they were declared.  Each level is read by the very argument type of its flag, and every cell's settings are then
built and checked (``GAConfig``, ``WorldConfig``, ``CompareSpec``) before anything runs, so a bad name or value is
one line naming it.

Seeds: a cell's base seed is the first 48 bits of BLAKE2b-64 of ``"BASE|LEVELS"``, where BASE is the study's
``--seed`` and LEVELS the cell's between-cell levels as canonical JSON (keys sorted, no spaces); replicate *i* of
the cell then uses that seed + 1000 *i*, as ``coevo compare --seed CELL_SEED`` would.  So a cell's seeds depend
only on the base seed and on what the cell is, not on the cell's place in the study or on the other cells: a
level added to a factor leaves the other cells' seeds as they were.

**Learning-run cells.**  With ``learn = B`` (``--learn B``) every cell is a set of ``coevo learn --behaviour B``
runs instead of a comparison: ``runs`` of them, run *i* with the cell's base seed + 1000 *i* (the same rule), each
given the cell's ``ga.*`` and ``world.*`` levels and ``measure_epochs``.  ``regime``, ``rate``, ``max_lead`` and
``model`` are a comparison's and are refused by name (:data:`COMPARE_ONLY`); ``learn`` has one level (cells of two
behaviours would have no measure in common).  A comparison study's declaration, and so its seeds and its
``study.json``, is as it was: ``learn`` is a level only of the studies that declare it.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import math
import re
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, SerializeAsAny, ValidationInfo, field_validator, model_validator

from coevo.config import MODELS, DEFAULT_MAX_LEAD, GAConfig, build, did_you_mean
from coevo.console import Lead, count_arg, max_lead_arg, positive_float_arg, seed_arg
from coevo.errors import ConfigError
from coevo.experiments.compare.experiment import OFFLINE, SEED_STRIDE, CompareSpec
from coevo.tasks import DEFAULT_TASK, get_task, task_of
from coevo.tasks.base import Task, check_ga
from coevo.tasks.fuel import FuelTask

#: A comparison study's cells are the fuel task's comparisons (its reports read Table 1 in every cell); a study of
#: learning runs learns a behaviour of any task (its world settings are that task's).
REGIMES = FuelTask.regimes

__all__ = ["WITHIN_CELL", "NAMES", "COMPARE_ONLY", "LEARNABLE", "learnable", "task_learning", "StudySpec", "Cell", "LearnSpec", "LearnCell",
           "declare", "parse_factor", "read_toml", "cells", "learn_cells", "study_cells", "cell_seed", "level_text"]

#: Factors that vary inside a cell (one comparison): its regimes, and its offline Executive's rates.
WITHIN_CELL = ("regime", "rate")
#: The names that are not a GA or world setting, in the order the docs list them.
NAMES = ("regime", "rate", "max_lead", "model", "runs", "measure_epochs", "learn")
#: The names only a regime comparison has: a study of learning runs (``learn``) refuses them.
COMPARE_ONLY = ("regime", "rate", "max_lead", "model")
def learnable(task: Task[Any]) -> tuple[str, ...]:
    """The behaviours of ``task`` a learning-run cell may learn: those that learn with no partner rule set given in
    its Independent regime (the fuel task's Executive learns against fixed Tracking and Docking rule sets, which a
    study does not give)."""
    regime = "independent" if "independent" in task.regimes else task.regimes[0]
    return tuple(b for b in task.behaviours if not task.partners_needed(b, regime))


#: The fuel task's behaviours a learning-run cell may learn.
LEARNABLE = learnable(get_task(FuelTask.name))


def task_learning(behaviour: Any) -> Task[Any]:
    """The task of the behaviour a study learns (the fuel task when it names none, or none there is)."""
    if not isinstance(behaviour, str):
        return get_task(DEFAULT_TASK)
    try:
        return task_of(behaviour)
    except ConfigError:
        return get_task(DEFAULT_TASK)  # refused by name when its level is read
#: What each name is when nothing declares it: ``coevo compare``'s defaults (rate: its default rates, left to it).
DEFAULTS: dict[str, tuple[Any, ...]] = {"regime": ("mutual", "independent"), "runs": (10,),
                                        "max_lead": (DEFAULT_MAX_LEAD,), "model": ("best",), "measure_epochs": (100,)}
#: The argument types of the flags these names stand for: a level is read as the flag reads its value.
_FLAG_TYPES: dict[str, Any] = {"rate": positive_float_arg(maximum=1e6), "max_lead": max_lead_arg,
                               "runs": count_arg(1, 1000), "measure_epochs": count_arg(1, 100_000)}
_TOML_KEYS = ("name", "description", "seed", "settings", "factors")
#: The most cells a study may have (each is a whole comparison): beyond it a declaration is a typo, not a study,
#: and building and checking every cell would itself take minutes.
MAX_CELLS = 10_000


def _names_help() -> str:
    return ", ".join(NAMES) + ", ga.NAME or world.NAME"


def _check_name(name: str, where: str, task: Task[Any]) -> None:
    """A known factor or setting name (a world setting of ``task``), else one line with the names (and the nearest,
    for a typo)."""
    if name in NAMES:
        return
    head, _, sub = name.partition(".")
    models: dict[str, type[BaseModel]] = {"ga": GAConfig, "world": task.world_settings}
    if head in models and sub:
        fields = list(models[head].model_fields)
        if sub in fields:
            return
        if head == "ga" and sub in task.world_settings.model_fields:  # the fuel task's Docking settings (GA settings before November 2026)
            raise ConfigError(f"{where}: {name!r} is a world setting of the {task.name} task now: use world.{sub}")
        hint = did_you_mean(sub, fields, prefix=f"{head}.") or f" (see coevo compare --{head} and docs/spec.md)"
        raise ConfigError(f"{where}: unknown {'GA' if head == 'ga' else 'world'} setting {name!r}{hint}")
    raise ConfigError(f"{where}: unknown factor {name!r}: use {_names_help()}{did_you_mean(name, NAMES)}")


def _level(name: str, raw: Any, where: str, task: Task[Any]) -> Any:
    """One level of ``name`` as its flag would read it (``raw``: the command line's text or a TOML value); JSON."""
    if isinstance(raw, (dict, list)) or raw is None:
        raise ConfigError(f"{where}: {name} = {raw!r}: give a single value")
    if name in _FLAG_TYPES:
        if isinstance(raw, bool):
            raise ConfigError(f"{where}: {name} = {raw!r}: give a number")
        try:
            v = _FLAG_TYPES[name](str(raw))
        except argparse.ArgumentTypeError as exc:
            raise ConfigError(f"{where}: {name}: {exc}") from None
        return v.value if isinstance(v, Lead) else v
    if name == "regime":
        if raw not in (*REGIMES, OFFLINE):
            raise ConfigError(f"{where}: unknown regime {raw!r} (use {', '.join((*REGIMES, OFFLINE))})")
        return raw
    if name == "model":
        if raw not in MODELS:
            raise ConfigError(f"{where}: unknown partner model {raw!r} (use {', '.join(MODELS)})")
        return raw
    if name == "learn":
        if raw not in learnable(task):
            why = ("it learns against partner rule sets, which a study's cells do not give" if raw in task.behaviours
                   else "not a behaviour of an installed task (coevo plugins lists them)")
            raise ConfigError(f"{where}: learn = {raw!r}: {why}: learn {' or '.join(learnable(task))} (the {task.name} "
                              "task's), or a behaviour of another task")
        return raw
    if isinstance(raw, str):  # ga.NAME / world.NAME from the command line: JSON when it parses, as --ga does
        try:
            return json.loads(raw)
        except json.JSONDecodeError:
            return raw
    return raw


def _levels(name: str, raws: Sequence[Any], where: str, task: Task[Any]) -> tuple[Any, ...]:
    _check_name(name, where, task)
    if not raws:
        raise ConfigError(f"{where}: factor {name} has no levels: give at least one")
    levels = tuple(_level(name, r, where, task) for r in raws)
    seen = [json.dumps(v, sort_keys=True) for v in levels]
    if len(set(seen)) != len(seen):
        raise ConfigError(f"{where}: factor {name} repeats a level: {', '.join(level_text(name, v) for v in levels)}")
    return levels


def level_text(name: str, value: Any) -> str:
    """A level as the report and the cell's folder name show it (``off`` for an unpaced max_lead)."""
    if name == "max_lead" and value is None:
        return "off"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def parse_factor(text: str) -> tuple[str, list[str]]:
    """``NAME=V1,V2,...`` (``--factor``) -> (name, level texts); an empty name or level is refused by name."""
    name, eq, values = text.partition("=")
    name = name.strip()
    if not eq or not name:
        raise ConfigError(f"--factor {text!r}: expected NAME=VALUE[,VALUE...], e.g. max_lead=1,2,4,off")
    levels = [v.strip() for v in values.split(",")]
    if any(not v for v in levels):
        raise ConfigError(f"--factor {text!r}: an empty level (give NAME=VALUE[,VALUE...])")
    return name, levels


def read_toml(path: Path) -> dict[str, Any]:
    """A study file's table, its top-level keys checked; a file that is missing or not TOML is one line."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except OSError as exc:
        raise ConfigError(f"study file {str(path)!r}: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"study file {str(path)!r} is not valid TOML: {exc}") from None
    unknown = [k for k in data if k not in _TOML_KEYS]
    if unknown:
        raise ConfigError(f"study file {str(path)!r}: unknown key {unknown[0]!r} (use {', '.join(_TOML_KEYS)})")
    for table in ("settings", "factors"):
        if not isinstance(data.get(table, {}), dict):
            raise ConfigError(f"study file {str(path)!r}: {table} must be a table ([{table}])")
    return data


def _flatten(table: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """TOML's nested ``ga = {mutation_rate = ...}`` or ``ga.mutation_rate = ...`` as the name ``ga.mutation_rate``."""
    out: dict[str, Any] = {}
    for k, v in table.items():
        if isinstance(v, dict) and not prefix:
            out.update(_flatten(v, f"{k}."))
        else:
            out[prefix + k] = v
    return out


@dataclass(frozen=True)
class StudySpec:
    """What makes two studies the same study: its name, base seed, and every name's levels in declared order."""

    name: str
    seed: int
    levels: tuple[tuple[str, tuple[Any, ...]], ...]
    description: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "seed": self.seed, "description": self.description,
                "levels": [[k, list(v)] for k, v in self.levels]}  # a list: the order makes the cells

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> StudySpec:
        return cls(name=str(data["name"]), seed=int(data["seed"]), description=str(data.get("description", "")),
                   levels=tuple((str(k), tuple(v)) for k, v in data["levels"]))

    @property
    def factors(self) -> dict[str, tuple[Any, ...]]:
        """The names with more than one level."""
        return {k: v for k, v in self.levels if len(v) > 1}

    @property
    def between(self) -> dict[str, tuple[Any, ...]]:
        """The factors that make cells (all but regime and rate)."""
        return {k: v for k, v in self.factors.items() if k not in WITHIN_CELL}

    @property
    def fixed(self) -> dict[str, Any]:
        """The names with one level, and that level."""
        return {k: v[0] for k, v in self.levels if len(v) == 1}

    @property
    def learn(self) -> str | None:
        """The behaviour every cell learns (a study of learning runs), or None (every cell a regime comparison)."""
        learn = self.fixed.get("learn")
        return None if learn is None else str(learn)

    @property
    def task(self) -> Task[Any]:
        """The task its cells run: the learned behaviour's, or the fuel task's (a comparison study)."""
        return task_learning(self.learn)


def _learned(file_settings: Mapping[str, Any], file_factors: Mapping[str, Any], settings: Mapping[str, Any],
             factors: Sequence[str]) -> Any:
    """The behaviour a study learns, as last given (a ``--factor learn=...``, the command line's setting, the file's
    setting or factor), before anything is checked: its task decides which world names there are."""
    for text in reversed(factors):
        name, raws = parse_factor(text)
        if name == "learn" and raws:
            return raws[0]
    for v in (settings.get("learn"), file_settings.get("learn"), file_factors.get("learn")):
        if v is not None:
            return v[0] if isinstance(v, list) and v else v
    return None


def declare(*, toml: Mapping[str, Any] | None = None, source: str = "the study file", factors: Sequence[str] = (),
            settings: Mapping[str, Any] | None = None, seed: int | None = None) -> StudySpec:
    """The study from a TOML table (``source`` names it in messages), then the command line: its settings flags
    (``settings``: name -> value, replacing the file's settings) and ``--factor`` texts (replacing the file's factor
    or setting of that name).  Every cell is built and checked here (:func:`cells`); a ConfigError names what is bad."""
    toml = dict(toml or {})
    levels: dict[str, tuple[Any, ...]] = dict(DEFAULTS)
    declared: dict[str, str] = {}  # name -> where its levels were last given (a learning-run study's refusals)
    file_settings = _flatten(toml.get("settings", {}))
    file_factors = _flatten(toml.get("factors", {}))
    task = task_learning(_learned(file_settings, file_factors, settings or {}, factors))  # whose world names are read
    for name, v in file_settings.items():
        where = f"{source}, [settings]"
        if isinstance(v, list):
            raise ConfigError(f"{where}: {name} = {v!r} is a list: put it under [factors]")
        levels[name], declared[name] = _levels(name, [v], where, task), where
    for name, v in file_factors.items():
        where = f"{source}, [factors]"
        if name in file_settings:
            raise ConfigError(f"{where}: {name} is both a setting and a factor: keep one")
        levels[name], declared[name] = _levels(name, v if isinstance(v, list) else [v], where, task), where
    for name, v in (settings or {}).items():
        if name in file_factors and len(levels[name]) > 1:
            raise ConfigError(f"{name} is a factor in {source} and a setting on the command line: use --factor "
                              f"{name}=... to replace its levels")
        levels[name] = _levels(name, [v], "command line", task)
        declared[name] = f"--{name.replace('_', '-')}" if name in NAMES else "the command line"
    given: set[str] = set()
    for text in factors:
        name, raws = parse_factor(text)
        if name in given:
            raise ConfigError(f"--factor {name} is given twice: give all its levels in one --factor {name}=A,B")
        given.add(name)
        levels[name], declared[name] = _levels(name, raws, f"--factor {text}", task), f"--factor {text}"
    if "learn" in levels:
        _learning_runs(levels, declared)
    if "seed" in toml and seed is None:
        try:
            seed = seed_arg(str(toml["seed"]))
        except argparse.ArgumentTypeError as exc:
            raise ConfigError(f"{source}: seed: {exc}") from None
    name = str(toml.get("name", "study"))
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}", name):
        raise ConfigError(f"{source}: name {name!r}: use letters, digits, '.', '_' or '-' (at most 64)")
    spec = StudySpec(name=name, seed=0 if seed is None else int(seed), levels=tuple(levels.items()),
                     description=str(toml.get("description", "")))
    study_cells(spec)  # every cell's settings checked now, before anything runs
    return spec


def _learning_runs(levels: dict[str, tuple[Any, ...]], declared: Mapping[str, str]) -> None:
    """A study of learning runs: one behaviour, and none of a comparison's names (given ones refused by name, the
    defaults dropped from ``levels``)."""
    learn = levels["learn"]
    if len(learn) > 1:
        raise ConfigError(f"{declared['learn']}: learn = {', '.join(map(str, learn))}: a study learns one behaviour "
                          "(a cell's measures are its behaviour's, so cells of two have nothing to compare): run one "
                          "study for each")
    bad = [f"{n} ({declared[n]})" for n in COMPARE_ONLY if n in declared]
    if bad:
        raise ConfigError(f"learn = {learn[0]}: a study of learning runs takes no {', '.join(bad)}: "
                          f"{'that is' if len(bad) == 1 else 'those are'} a regime comparison's; remove "
                          f"{'it' if len(bad) == 1 else 'them'}")
    for n in COMPARE_ONLY:
        levels.pop(n, None)


@dataclass(frozen=True)
class _CellBase:
    """What every cell has: its folder's name and its between-cell levels."""

    id: str
    levels: tuple[tuple[str, Any], ...]

    def level(self, name: str) -> Any:
        return dict(self.levels)[name]

    @property
    def label(self) -> str:
        return ", ".join(f"{k} {level_text(k, v)}" for k, v in self.levels) or "(one cell)"


@dataclass(frozen=True)
class Cell(_CellBase):
    """One cell of a comparison study: its folder's name, its between-cell levels, and the comparison it runs."""

    spec: CompareSpec


class LearnSpec(BaseModel):
    """A learning-run cell's runs: ``runs`` times ``coevo learn --behaviour BEHAVIOUR``, run *i* with seed
    ``seed + 1000 i``, with these settings (checked as ``coevo learn`` would, before anything runs)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    behaviour: str
    runs: int = Field(10, ge=1, le=1000, description="runs (seeds) in the cell")
    seed: int = 0
    measure_epochs: int = Field(100, ge=1, le=100_000)
    world: SerializeAsAny[BaseModel] = Field(default=None, validate_default=False)  # type: ignore[assignment]
    ga: GAConfig = GAConfig()

    @model_validator(mode="before")
    @classmethod
    def _world(cls, data: Any) -> Any:
        """The world read as the learned behaviour's task's settings (checked there, naming a bad value)."""
        if not isinstance(data, dict):
            return data
        task = task_learning(data.get("behaviour"))
        world = data.get("world", {})
        if isinstance(world, dict):
            world = build(task.world_settings, world, what=f"world settings of the {task.name} task")
        return {**data, "world": world}

    @field_validator("behaviour")
    @classmethod
    def _behaviour(cls, v: str) -> str:
        task = task_learning(v)
        if v not in learnable(task):
            raise ValueError(f"a study's cells learn {' or '.join(learnable(task))} (the {task.name} task's) or a "
                             f"behaviour of another task, not {v!r}")
        return v

    @field_validator("ga")
    @classmethod
    def _ga(cls, v: GAConfig, info: ValidationInfo) -> GAConfig:
        try:
            return check_ga(task_learning(info.data.get("behaviour")), v)
        except ConfigError as exc:
            raise ValueError(str(exc)) from None

    @property
    def the_task(self) -> Task[Any]:
        return task_learning(self.behaviour)

    @property
    def seeds(self) -> list[int]:
        """Each run's seed, in run order (``coevo compare --seed``'s rule: + 1000 per replicate)."""
        return [self.seed + i * SEED_STRIDE for i in range(self.runs)]

    @classmethod
    def make(cls, **values: Any) -> LearnSpec:
        return build(cls, values, what="learning-run settings")


@dataclass(frozen=True)
class LearnCell(_CellBase):
    """One cell of a study of learning runs: its folder's name, its between-cell levels, its runs' settings, and the
    ``coevo learn`` arguments that give them (the declared ``ga.*`` and ``world.*`` levels and measure_epochs; what
    is not declared stays ``coevo learn``'s default, so Docking's own GA choices apply as they do there)."""

    spec: LearnSpec
    args: tuple[str, ...]


def cell_seed(base: int, levels: Mapping[str, Any]) -> int:
    """The cell's base seed (module docstring): 48 bits of BLAKE2b-64 of ``"BASE|LEVELS"`` (below 2**53, so that a
    browser reading the JSON keeps it exact)."""
    canonical = json.dumps(dict(levels), sort_keys=True, separators=(",", ":"))
    digest = hashlib.blake2b(f"{base}|{canonical}".encode(), digest_size=8).digest()
    return int.from_bytes(digest, "big") >> 16


def _cell_id(index: int, levels: Mapping[str, Any]) -> str:
    text = ",".join(f"{k}={level_text(k, v)}" for k, v in levels.items()) or "all"
    text = re.sub(r"[^A-Za-z0-9.,=+_-]", "-", text)
    if len(text) > 100:
        text = text[:80] + "~" + hashlib.blake2b(text.encode(), digest_size=4).hexdigest()
    return f"{index:02d}-{text}"


def _products(spec: StudySpec) -> Iterator[tuple[str, dict[str, Any], dict[str, Any], str, BaseModel, GAConfig]]:
    """Per cell, the cartesian product of the between-cell factors' levels in declared order: its id, its levels,
    every name's one level in it, how messages name it, and its world and GA settings (checked)."""
    between = spec.between
    fixed = {k: v for k, v in spec.levels}
    n = math.prod(len(v) for v in between.values())
    if n > MAX_CELLS:
        raise ConfigError(f"the factors make {n} cells ({' x '.join(str(len(v)) for v in between.values())}); a study "
                          f"may have at most {MAX_CELLS}: split it, or vary fewer factors at once")
    for i, combo in enumerate(itertools.product(*between.values())):
        levels = dict(zip(between, combo, strict=True))
        one = {k: v[0] for k, v in fixed.items() if k not in WITHIN_CELL} | levels
        cid = _cell_id(i, levels)
        where = f"cell {cid}" if levels else "study settings"
        try:
            world = build(spec.task.world_settings, _prefixed(one, "world."))
            ga = build(GAConfig, _prefixed(one, "ga."))
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        yield cid, levels, one, where, world, ga


def _prefixed(one: Mapping[str, Any], prefix: str) -> dict[str, Any]:
    return {k[len(prefix):]: v for k, v in one.items() if k.startswith(prefix)}


def cells(spec: StudySpec) -> list[Cell]:
    """A comparison study's cells: the cartesian product of the between-cell factors' levels, each built into a
    checked CompareSpec.  A study of learning runs has :func:`learn_cells` instead (a ConfigError here)."""
    if spec.learn is not None:
        raise ConfigError(f"study {spec.name!r} is a study of learning runs (learn = {spec.learn}): its cells are "
                          "learning runs, not comparisons")
    fixed = {k: v for k, v in spec.levels}
    out = []
    for cid, levels, one, where, world, ga in _products(spec):
        regimes = tuple(fixed["regime"])
        if "rate" in fixed and OFFLINE not in regimes:
            raise ConfigError(f"rate: the rates of asynchrony are {OFFLINE}'s: add it to the regimes "
                              f"(--factor regime=independent,{OFFLINE})")
        rates = {"rates": tuple(fixed["rate"])} if "rate" in fixed else {}
        try:
            cs = CompareSpec.make(regimes=regimes, **rates, runs=one["runs"], model=one["model"],
                                  max_lead=one["max_lead"], measure_epochs=one["measure_epochs"], world=world, ga=ga,
                                  seed=cell_seed(spec.seed, levels))
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        out.append(Cell(cid, tuple(levels.items()), cs))
    return out


def learn_cells(spec: StudySpec) -> list[LearnCell]:
    """A study of learning runs' cells (``learn``): as :func:`cells`, each built into a checked LearnSpec."""
    if spec.learn is None:
        raise ConfigError(f"study {spec.name!r} is a study of regime comparisons: its cells are comparisons")
    out = []
    for cid, levels, one, where, world, ga in _products(spec):
        try:
            ls = LearnSpec.make(behaviour=spec.learn, runs=one["runs"], measure_epochs=one["measure_epochs"],
                                world=world, ga=ga, seed=cell_seed(spec.seed, levels))
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        # JSON values, as coevo learn's --ga and --world read them back (a string stays a string, true a bool)
        args = (*(f"--ga={k}={json.dumps(v)}" for k, v in _prefixed(one, "ga.").items()),
                *(f"--world={k}={json.dumps(v)}" for k, v in _prefixed(one, "world.").items()),
                f"--measure-epochs={ls.measure_epochs}")
        out.append(LearnCell(cid, tuple(levels.items()), ls, args))
    return out


def study_cells(spec: StudySpec) -> list[Cell] | list[LearnCell]:
    """The study's cells, whichever kind they are: :func:`learn_cells` for a study of learning runs, else
    :func:`cells`."""
    return learn_cells(spec) if spec.learn is not None else cells(spec)
