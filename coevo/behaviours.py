"""What each learning agent senses and sets: the rule layout of the three behaviours.

Every sensor is discretised into bins (report Appendix A §4): bearings in 5° bins,
ranges in 5-inch bins from 0 to 150 (a last bin for "150 and beyond"), the Target's
heading in 45° bins.  The Docking agent's dock sensors and the Executive's sensors
are *(ours)*: the report does not list them.

A rule condition is an interval of bin indices; it prints as the bins' lower
edges (``range = [35, 45]`` covers bins 35..49.99 inches).  Circular sensors
(bearings, headings) may wrap through 0: ``bearing = [340, 35]``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

__all__ = ["Behaviour", "Sensor", "Action", "Schema", "schema", "TASK_TRACK", "TASK_DOCK"]

TASK_TRACK = 0
TASK_DOCK = 1


class Behaviour(str, enum.Enum):
    TRACKING = "tracking"
    DOCKING = "docking"
    EXECUTIVE = "executive"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Sensor:
    """A discretised sensor: bin ``k`` holds values in ``[k*width, (k+1)*width)``."""

    name: str
    width: float
    bins: int
    circular: bool
    unit: str

    def label(self, k: int) -> int | float:
        """The printed value of bin ``k`` (its lower edge)."""
        v = k * self.width
        return int(v) if float(v).is_integer() else v

    def bin_of_label(self, value: float) -> int | None:
        """The bin whose label is ``value``, or None if no bin has that label."""
        k = round(value / self.width)
        if 0 <= k < self.bins and abs(k * self.width - value) < 1e-9:
            return k
        return None

    def discretise(self, values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Bin indices (uint8) of raw values; circular values are taken modulo 360."""
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
    """A control variable with a finite set of values."""

    name: str
    values: tuple[float | str, ...]

    def index_of(self, value: str) -> int | None:
        for i, v in enumerate(self.values):
            if str(v) == value.strip():
                return i
        return None


@dataclass(frozen=True)
class Schema:
    behaviour: Behaviour
    sensors: tuple[Sensor, ...]
    actions: tuple[Action, ...]

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


def _range(name: str) -> Sensor:
    return Sensor(name, 5.0, 31, False, "inches")  # 0..145 plus a last "150+" bin


def _bearing(name: str) -> Sensor:
    return Sensor(name, 5.0, 72, True, "degrees")


TURN = Action("turn", tuple(range(-24, 25, 4)))  # deg/s, 13 values
SPEED = Action("speed", tuple(range(-4, 17, 4)))  # inches/s, 6 values
TASK = Action("task", ("track", "dock"))

_REPORT_FIVE = (
    _range("range"),  # to the nearest object (wall, dock or Target)
    _bearing("bearing"),
    Sensor("heading", 45.0, 8, True, "degrees"),  # Target's heading relative to its bearing
    _range("target_range"),
    _bearing("target_bearing"),
)

_SCHEMAS = {
    Behaviour.TRACKING: Schema(Behaviour.TRACKING, _REPORT_FIVE, (TURN, SPEED)),
    Behaviour.DOCKING: Schema(
        Behaviour.DOCKING,
        _REPORT_FIVE
        + (
            _range("dock_range"),  # to the middle of the dock's front face
            _bearing("dock_bearing"),
            _bearing("dock_orientation"),  # robot heading minus the head-on docking heading
        ),
        (TURN, SPEED),
    ),
    Behaviour.EXECUTIVE: Schema(
        Behaviour.EXECUTIVE,
        (
            Sensor("fuel", 10.0, 10, False, "percent"),
            _range("target_range"),
            _range("dock_range"),
        ),
        (TASK,),
    ),
}


def schema(behaviour: Behaviour | str) -> Schema:
    """The rule layout of a behaviour."""
    return _SCHEMAS[Behaviour(behaviour)]
