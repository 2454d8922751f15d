"""What a learning behaviour senses and sets: the rule layout, the same for every task.

A task declares, for each of its learning behaviours, a :class:`Schema`: its
discretised sensors and its actions.  Rules, the matcher, the rule text and the GA
read everything they need from it and name no task.  Schemas are registered by
behaviour name (names are unique across tasks: a rule set on the wire carries only
its behaviour's name), and :func:`schema` finds them.  The registry is filled from
above: each task registers its behaviours when it is imported, and a behaviour asked for
before its task was imported is looked for by the finder the tasks' registry sets
(:func:`set_finder`); this module, like the rest of the core, names no task.

Every sensor is discretised into bins.  A rule condition is an interval of bin
indices; it prints as the bins' lower edges (``range = [35, 45]`` covers bins
35..49.99 inches).  Circular sensors (bearings, headings) may wrap through 0:
``bearing = [340, 35]``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coevo.errors import RuleSetError

__all__ = ["Sensor", "Action", "Schema", "schema", "register", "registered", "known", "set_finder"]


@dataclass(frozen=True)
class Sensor:
    """A discretised sensor: bin ``k`` holds values in ``[origin + k*width, origin + (k+1)*width)``.

    ``origin`` (0 unless given) lets a non-circular sensor hold signed values (a lateral offset).
    ``mirrored``: the value changes sign in the world's mirror image (a bearing relative to the robot's
    heading, a signed lateral offset); then bin ``k`` mirrors to bin ``bins - 1 - k``, which needs the
    bins to lie symmetric about 0 (a full circle, or ``origin = -bins * width / 2``).
    """

    name: str
    width: float
    bins: int
    circular: bool
    unit: str
    origin: float = 0.0
    mirrored: bool = False

    def __post_init__(self) -> None:
        if self.mirrored and (self.bins * self.width != 360.0 if self.circular else
                              self.origin != -self.bins * self.width / 2):
            raise RuleSetError(f"sensor {self.name!r} is mirrored but its bins do not lie symmetric about 0")

    def label(self, k: int) -> int | float:
        """The printed value of bin ``k`` (its lower edge)."""
        v = self.origin + k * self.width
        return int(v) if float(v).is_integer() else v

    def bin_of_label(self, value: float) -> int | None:
        """The bin whose label is ``value``, or None if no bin has that label."""
        k = round((value - self.origin) / self.width)
        if 0 <= k < self.bins and abs(self.origin + k * self.width - value) < 1e-9:
            return k
        return None

    def discretise(self, values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Bin indices (uint8) of raw values; circular values are taken modulo 360."""
        if self.origin:
            values = values - self.origin
        if self.circular:
            k = (values - 360.0 * np.floor(values * (1.0 / 360.0))) * (1.0 / self.width)
            k = k.astype(np.int64)
            k[k >= self.bins] -= self.bins  # mod() may round a tiny negative up to 360.0
        else:
            k = np.clip(values * (1.0 / self.width), 0, self.bins - 1).astype(np.int64)
        if out is None:
            return k.astype(np.uint8)
        out[...] = k
        return out


@dataclass(frozen=True)
class Action:
    """A control variable with a finite set of values.

    ``mirrored``: the value changes sign in the world's mirror image (a turn rate); then value ``i``
    mirrors to value ``len(values) - 1 - i``, which needs the values to lie symmetric about 0.
    """

    name: str
    values: tuple[float | str, ...]
    mirrored: bool = False

    def __post_init__(self) -> None:
        if self.mirrored and list(self.values) != [-v for v in reversed(self.values)]:  # type: ignore[operator]
            raise RuleSetError(f"action {self.name!r} is mirrored but its values {self.values} are not symmetric about 0")

    def index_of(self, value: str) -> int | None:
        for i, v in enumerate(self.values):
            if str(v) == value.strip():
                return i
        return None


@dataclass(frozen=True)
class Schema:
    """The sensors and actions of one learning behaviour (its name: ``behaviour``)."""

    behaviour: str
    sensors: tuple[Sensor, ...]
    actions: tuple[Action, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "behaviour", str(self.behaviour))

    @property
    def n_sensors(self) -> int:
        return len(self.sensors)

    @property
    def max_bins(self) -> int:
        return max(s.bins for s in self.sensors)

    @property
    def sensor_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.sensors)

    def discretise(self, raw: dict[str, np.ndarray]) -> np.ndarray:
        """``(n, S)`` uint8 bins from raw sensor values keyed by sensor name."""
        n = len(next(iter(raw.values())))
        out = np.empty((self.n_sensors, n), dtype=np.uint8)
        for j, s in enumerate(self.sensors):
            s.discretise(raw[s.name], out[j])
        return out.T

    def sensor_index(self, name: str) -> int | None:
        for i, s in enumerate(self.sensors):
            if s.name == name:
                return i
        return None

    def action_index(self, name: str) -> int | None:
        for i, a in enumerate(self.actions):
            if a.name == name:
                return i
        return None


_REGISTRY: dict[str, Schema] = {}
#: Called with a behaviour's name when it is not registered, to load the task that declares it (set from above, by
#: the tasks' registry: this module names no task).
_FINDER: Callable[[str], None] | None = None


def set_finder(finder: Callable[[str], None] | None) -> None:
    """What loads a behaviour's declaring task when the behaviour is asked for before it is registered."""
    global _FINDER
    _FINDER = finder


def known(behaviour: str) -> bool:
    """Is ``behaviour`` registered, once its task is loaded if the finder finds one?"""
    name = str(behaviour)
    if name not in _REGISTRY and _FINDER is not None:
        _FINDER(name)
    return name in _REGISTRY


def register(*schemas: Schema) -> None:
    """Make behaviours known by name; registering the same schema twice is harmless, a clash is an error."""
    for s in schemas:
        old = _REGISTRY.get(s.behaviour)
        if old is not None and old != s:
            raise RuleSetError(f"behaviour {s.behaviour!r} is declared twice with different schemas")
        _REGISTRY[s.behaviour] = s


def registered() -> tuple[str, ...]:
    """The names of every registered behaviour."""
    return tuple(_REGISTRY)


def schema(behaviour: str) -> Schema:
    """The rule layout of a behaviour, by name."""
    name = str(behaviour)
    if not known(name):
        names = ", ".join(_REGISTRY) or "none: import the task that declares it"
        raise RuleSetError(f"unknown behaviour {name!r} (known: {names})")
    return _REGISTRY[name]
