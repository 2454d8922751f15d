"""Typed, validated settings: the GA's (docs/spec.md §1, "GA parameters"), shared by every task.

Each task's world settings live with the task (the fuel task's: :mod:`coevo.tasks.fuel.settings`).

Every number the report gives is a default here; every choice the report leaves
open is marked *(ours)* in its description and can be overridden.  Settings are
frozen pydantic models: invalid values fail at construction with a
:class:`~coevo.errors.ConfigError` that names the field and the value.
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, TypeVar, cast

from annotated_types import Ge, Gt, Le
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from coevo.errors import ConfigError

__all__ = ["pairs", "Bounded", "MAX_MAGNITUDE", "Settings", "GAConfig", "build", "did_you_mean", "MODELS", "HALL_SAMPLE", "HALL_SHARE", "DEFAULT_MAX_LEAD",
           "parse_max_lead", "SAVED_GA_BEFORE",
           "saved_ga"]

_M = TypeVar("_M", bound=BaseModel)

#: How a worker models a partner (:mod:`coevo.agents.models`): its best so far (the report's choice),
#: its current policy, one drawn from its recent best, or its best so far beside a sample of its past bests
#: (a hall of fame, Rosin & Belew).
MODELS = ("best", "current", "recent", "hall")
#: The hall of fame's defaults (:mod:`coevo.agents.models`, docs/competition.md): past bests sampled for each
#: generation, and the share of the population's episodes played against them.
HALL_SAMPLE = 3
HALL_SHARE = 0.5
#: Pacing (:mod:`coevo.agents.pacing`): generations a worker may lead its slowest partner.
DEFAULT_MAX_LEAD = 1


def parse_max_lead(value: str | int | None) -> int | None:
    """``"off"``/``None`` → no pacing; otherwise a lead of at least 0 generations."""
    if value is None or (isinstance(value, str) and value.strip().lower() in ("off", "none")):
        return None
    try:
        lead = int(value)
    except (TypeError, ValueError):
        raise ConfigError(f"max lead must be a whole number of generations or 'off', got {value!r}") from None
    if lead < 0:
        raise ConfigError(f"max lead must be 0 or more generations (or 'off'), got {lead}")
    return lead


@dataclass(frozen=True)
class Bounded:
    """An argument type: a number from ``lo`` to ``hi`` (above ``lo`` with ``above``; whole with ``whole``), or one
    of ``words`` (text -> value, e.g. ``off``).  Every count, size, time and rate flag of every command is one of
    these, so each flag's bound is stated in one place, checked before anything is allocated or written, and named
    in the one-line error (argparse adds the flag's name).  The tests and docs/commands.md read ``lo`` and ``hi``."""

    lo: float
    hi: float
    whole: bool = True
    above: bool = False
    words: tuple[tuple[str, Any], ...] = ()
    what: str = "number"

    def __call__(self, text: str) -> Any:
        for word, value in self.words:
            if text.strip().lower() == word:
                return value
        shown = text if len(text) <= 40 else text[:40] + "..."
        try:
            v = int(text) if self.whole else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid {self.what} {shown!r}: give {self.describe()}") from None
        if not (math.isfinite(v) and (self.lo < v if self.above else self.lo <= v) and v <= self.hi):
            raise argparse.ArgumentTypeError(f"invalid {self.what} {shown}: give {self.describe()}")
        return v

    def describe(self) -> str:
        """The bound in words: ``a whole number from 1 to 1000``."""
        def num(x: float) -> str:
            return str(int(x)) if self.whole or float(x).is_integer() else f"{x:g}"

        span = f"above {num(self.lo)}, at most {num(self.hi)}" if self.above else f"from {num(self.lo)} to {num(self.hi)}"
        return ("a whole number " if self.whole else "a number ") + span + "".join(f", or {w}" for w, _ in self.words)

    @staticmethod
    def setting(model: type, name: str) -> Bounded:
        """The bound a settings model (pydantic, e.g. ``GAConfig``) gives its field ``name``: a flag that sets that
        field is refused at parse time by the model's own bound, kept only there."""
        field = model.model_fields[name]  # type: ignore[attr-defined]
        lo = next((m.ge for m in field.metadata if isinstance(m, Ge)), None)
        gt = next((m.gt for m in field.metadata if isinstance(m, Gt)), None)
        hi = next(m.le for m in field.metadata if isinstance(m, Le))
        whole = field.annotation in (int, "int")
        low, high = cast(float, gt if lo is None else lo), cast(float, hi)  # numbers: the fields are int or float
        return Bounded(low, high, whole=whole, above=lo is None)


#: The largest magnitude a number of any settings model may have: no world is a billion inches wide, no GA
#: runs a billion of anything; beyond it numbers only overflow somewhere far from the flag that gave them.
MAX_MAGNITUDE = 1e9


class Settings(BaseModel):
    """Frozen, no unknown fields, finite numbers (``nan`` and ``inf`` are refused by name): the base of every
    settings model (the GA's and each task's world).  A model with ``physical = True`` (the GA's, the worlds')
    also refuses magnitudes beyond :data:`MAX_MAGNITUDE` (not a run's settings: seeds and times are bigger)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)
    physical: ClassVar[bool] = False
    #: Settings added after runs had been saved, each with what a saved run's settings (run.json, worker.json) mean
    #: by leaving it out: how that run learned (read by :func:`saved_ga` and :func:`coevo.tasks.saved_settings`).
    saved_before: ClassVar[Mapping[str, Any]] = {}

    @model_validator(mode="after")
    def _physical(self) -> Settings:
        if not self.physical:
            return self
        for name in type(self).model_fields:
            v = getattr(self, name)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and abs(v) > MAX_MAGNITUDE:
                raise ValueError(f"{name}={v!r} is beyond any physical value (at most {MAX_MAGNITUDE:g} in size)")
        return self


class GAConfig(Settings):
    """The generational GA (report Appendix A §6.2; operators after SAMUEL, Appendix C §7)."""

    physical: ClassVar[bool] = True
    #: Docking's rules became symmetric in Round 6 (docs/docking-learning.md); runs saved before learned without.
    saved_before: ClassVar[Mapping[str, Any]] = {"symmetric_rules": False}

    generations: int = Field(50, ge=1, le=100_000)
    population: int = Field(50, ge=2, le=10_000)
    episodes: int = Field(90, ge=1, le=100_000, description="evaluation episodes per individual")
    best_episodes: int = Field(120, ge=1, le=100_000, description="episodes re-evaluating each generation's best")
    lane_episodes: int = Field(10, ge=1, le=1_000, description="(ours) episodes played in sequence per lane (one epoch's worth)")
    parents_fraction: float = Field(0.5, gt=0, le=1, description="(ours) the top fraction that reproduces, two offspring each pair")
    elite: int = Field(1, ge=0, description="(ours) best individuals copied unchanged")
    initial_rules: int = Field(16, ge=1, le=64, description="(ours) rules per random initial policy")
    max_rules: int | None = Field(
        None, ge=1, le=64, description="(ours) most rules a policy may hold (matching packs rules in 64 bits; a "
        "symmetric policy's mirror images take half).  None: the task's choice (fuel: 32 for Docking, whose rules "
        "are symmetric; 48 for the others)"
    )
    crossover_rate: float = Field(0.8, ge=0, le=1, description="(ours) chance a pair is recombined")
    high_payoff_quantile: float = Field(0.5, ge=0, le=1, description="(ours) episodes above this payoff quantile count as 'high payoff'")
    mutation_rate: float = Field(0.1, ge=0, le=1, description="(ours) base per-rule mutation probability mr (FM, FH, GH)")
    mutation_model: Literal["fm", "gm", "fh", "gh"] = Field(
        "fm", description="mutation model (report Appendix D): fm = FM(mr), gm = GM(min_mutation_rate), "
        "fh = FH(hypermutation_rate, mr), gh = GH(min_hypermutation_rate, mr); see coevo.ga.mutation"
    )
    min_mutation_rate: float = Field(0.03, ge=0, le=1, description="GM's αM: rate = αM + k/8, k its 3-bit control gene")
    hypermutation_rate: float = Field(0.2, ge=0, le=1, description="FH's hr: fraction of offspring replaced by random immigrants")
    min_hypermutation_rate: float = Field(0.05, ge=0, le=1, description="GH's αH: hypermutation chance = αH + k/8")
    specialise_rate: float = Field(0.3, ge=0, le=1, description="(ours) chance per offspring of a specialisation")
    generalise_rate: float = Field(0.1, ge=0, le=1, description="(ours) chance per offspring of a generalisation")
    cover_rate: float = Field(0.3, ge=0, le=1, description="(ours) chance per offspring of covering an unmatched state")
    delete_rate: float = Field(0.3, ge=0, le=1, description="(ours) chance per offspring of deleting a rule that never fired")
    split_rate: float | None = Field(
        None, ge=0, le=1, description="(ours) chance per offspring of splitting an over-general rule of its parent: "
        "narrowed, on the sensor that best tells apart where it fired in paying and in failed episodes, to the paying "
        "side (coevo.ga.operators.split).  None: the task's choice (fuel: 0.5 for Docking, docking from random starts, "
        "median of seeds 0-9: 58.3 % against 50.1 % without; 0 for the others, not measured there)"
    )
    symmetric_rules: bool | None = Field(
        None, description="(ours) in a world that is its own mirror image, each rule also stands for its mirror "
        "image (coevo.ga.symmetry): what is learned on one side holds on the other; needs max_rules <= 32.  None: "
        "the task's choice (fuel: on for Docking, docking from random starts, median of development seeds 0-19 71.1 % "
        "against 60.1 %, of held-out seeds 1000-1019 70.9 % against 52.1 %; off for the others, not measured there)"
    )
    strength_rate: float = Field(0.3, gt=0, le=1, description="(ours) step size of strength updates towards episode payoffs")
    low_strength: float = Field(0.3, ge=0, le=1, description="(ours) below this a rule counts as weak (specialisation trigger)")
    common_scenarios: bool = Field(
        True, description="(ours) every individual of a generation faces the same starts and Target noise (common random numbers)"
    )
    initial: Literal["default", "random"] = Field(
        "default",
        description="how Tracking and Docking start: 'default' from their shipped direction-only rule sets "
        "(coevo/tasks/fuel/defaults/; the report lists 'initial behaviors of the agents' among its settings and SAMUEL "
        "starts from default rules, Appendix B), 'random' from random rule sets; the Executive always starts random",
    )
    conflict: Literal["strongest", "proportional"] = Field(
        "strongest", description="(ours) conflict resolution: highest strength, or strength-proportional draw"
    )
    specialise_fraction: float = Field(
        0.3, gt=0, le=1, description="(ours) chance per condition that a specialisation narrows it (at least one is); "
        "Docking from random starts, median of seeds 0-4: 46.1 % at 0.3 with recency 0.8 against 37.7 % at 1.0 "
        "(29.4 % at 0.3 without recency, baseline 29.0 %)"
    )
    specialise_recency: float = Field(
        0.8, ge=0, lt=1, description="(ours) 0: a specialisation centres on any decision of the rule in a high-payoff "
        "episode; > 0: on a late one, weight recency ** (decisions to the episode's end); Docking from random starts, "
        "median of seeds 0-4: 29.0 % at 0, 37.7 % at 0.8; with specialise_fraction 0.3: 46.1 % at 0.8, 39.6 % at 0.9"
    )
    cover_partial: bool = Field(
        False, description="(ours) covering widens the best partial match to the unmatched state instead of building a narrow rule"
    )
    seed_random_rules: int = Field(
        8, ge=0, le=63, description="(ours) random rules added in front of each mutated copy of a seed policy; Docking "
        "from random starts, median of seeds 0-4: 45.8 % with 8 against 29.0 % with none; 47.7 % with 8 together with "
        "specialise_recency 0.8 and specialise_fraction 0.3 (44.6 % on held-out seeds 100-104)"
    )
    keep_evaluated: bool | None = Field(
        None, description="(ours) the elite and the best so far are the policies as evaluated, with the strengths their "
        "fitness was earned with; strength updates reach only the offspring.  False: they carry the strengths updated "
        "from that evaluation (a policy nobody measured).  None: the task's choice (fuel: True for Docking; Docking "
        "from random starts, median of seeds 0-9: 52.5 % with best_candidates 3 against 35.4 %)"
    )
    best_candidates: int | None = Field(
        None, ge=0, le=10, description="(ours) 0: the best so far is the generation's best with the highest single "
        "re-evaluation (on best_episodes); k > 0: the k best policies so far are re-evaluated every generation and the "
        "best so far is the one with the highest mean over all its re-evaluations.  None: the task's choice (fuel: 3 "
        "for Docking, whose re-evaluations are one 60-step round of fresh starts; 0 for the others, where each costs "
        "an epoch's ten episodes: Tracking's runs took 38-59 s instead of 21-41 s)"
    )
    seed_random_share: float = Field(
        0.0, ge=0, le=1, description="(ours) share of the initial population that is random rule sets even with a seed policy"
    )

    @model_validator(mode="after")
    def _check(self) -> GAConfig:
        if self.max_rules is not None and self.initial_rules > self.max_rules:
            raise ValueError(f"initial_rules ({self.initial_rules}) exceeds max_rules ({self.max_rules})")
        if self.elite >= self.population:
            raise ValueError(f"elite ({self.elite}) must be smaller than population ({self.population})")
        if int(self.population * self.parents_fraction) < 1:
            raise ValueError(f"parents_fraction ({self.parents_fraction}) leaves no parent in a population of {self.population}")
        return self


#: GA settings added after runs had been saved, with what a saved run meant by leaving each out
#: (:attr:`GAConfig.saved_before`).  A task's own settings added since are its world model's ``saved_before``.
SAVED_GA_BEFORE: Mapping[str, Any] = GAConfig.saved_before


def saved_ga(data: Mapping[str, Any]) -> dict[str, Any]:
    """A saved run's GA settings (a dict read from its files) as the run learned with them: every setting added
    since is filled in with its value from before (:data:`SAVED_GA_BEFORE`), so that such a run resumes and replays
    as it was, rather than under today's defaults.  (GA values that are now its task's world settings are moved
    there by :func:`coevo.tasks.saved_settings`, which calls this.)"""
    return {**SAVED_GA_BEFORE, **data}


def build(model: type[_M], values: dict[str, Any] | None = None, *, what: str = "", **overrides: Any) -> _M:
    """Construct a settings model, turning validation failures into :class:`ConfigError`.

    The message names the settings (``what``, else the model's class), every bad field and the value it got, e.g.
    ``GAConfig: population=0: Input should be greater than or equal to 2``.
    """
    data = dict(values or {})
    data.update(overrides)
    try:
        return model(**data)
    except ValidationError as exc:
        parts = []
        for err in exc.errors():
            field = ".".join(str(p) for p in err["loc"]) or "(settings)"
            # a nested setting (world.arena) shows its own value, not the whole of its parent's
            value = err.get("input") if len(err["loc"]) > 1 else data.get(str(err["loc"][0])) if err["loc"] else None
            shown = f"{field}={value!r}" if err["loc"] else field
            if err["type"] == "extra_forbidden":  # a misspelt name: the nearest known one, and every known one
                names = list(_model_at(model, err["loc"][:-1]).model_fields)
                hint = did_you_mean(str(err["loc"][-1]), names)
                parts.append(f"{shown}: unknown setting{hint}{' ' if hint else '. '}Known settings: " + ", ".join(names))
                continue
            parts.append(f"{shown}: {err['msg']}")
        raise ConfigError(f"{what or model.__name__}: " + "; ".join(parts)) from exc


def did_you_mean(name: str, names: Sequence[str], *, prefix: str = "") -> str:
    """'; did you mean mutation_rate?' for a name one typo away from one of ``names`` (shown with ``prefix``), else
    ''.  Every "unknown name" message of the settings says it this way (``--ga``, ``--world``, a study's factors)."""
    near = difflib.get_close_matches(name, list(names), n=1)
    return f"; did you mean {prefix}{near[0]}?" if near else ""


def _model_at(model: type[BaseModel], loc: Sequence[int | str]) -> type[BaseModel]:
    """The settings model a validation error's location (less its last part) points into: ``model`` itself, or a
    nested model's (``world.arena`` of a model whose ``world`` is one)."""
    for part in loc:
        field = model.model_fields.get(str(part))
        inner = field.annotation if field is not None else None
        if not (isinstance(inner, type) and issubclass(inner, BaseModel)):
            break
        model = inner
    return model


def settings_listing(model: type[BaseModel], flag: str) -> str:
    """Every setting of ``model`` a ``--FLAG NAME=VALUE`` takes, one a line: its name, its default and what it is
    (``--ga help``, ``--world help``)."""
    lines = [f"--{flag} NAME=VALUE takes ({model.__name__}):"]
    for name, f in model.model_fields.items():
        default = f.default if f.default_factory is None else f.default_factory()  # type: ignore[call-arg]
        shown = default.model_dump(mode="json") if isinstance(default, BaseModel) else default
        lines.append(f"  {name} = {json.dumps(shown)}" + (f"  {f.description}" if f.description else ""))
    return "\n".join(lines)


def pairs(values: list[str] | None, flag: str) -> dict[str, Any]:
    """``--world/--ga name=value`` pairs (values parsed as JSON when they can be)."""
    out: dict[str, Any] = {}
    for item in values or []:
        if "=" not in item:
            raise ConfigError(f"--{flag} {item!r}: expected name=value")
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out
