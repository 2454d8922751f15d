"""The observations the TD learner sees: the tasks' discretised sensors, reduced (see the package's docstring)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.schema import Schema, Sensor, schema

__all__ = ["Encoder", "ENCODERS"]


@dataclass(frozen=True)
class Encoder:
    """The learner's observation: some of a schema's sensors, each with ``k`` of its bins merged into one.

    ``code`` packs the merged bins into one integer (mixed radix), the key of the hashed table.
    """

    behaviour: str
    keep: tuple[tuple[str, int], ...]
    name: str = "custom"

    def __post_init__(self) -> None:
        sch = schema(self.behaviour)
        if not self.keep:
            raise ConfigError(f"encoder {self.name!r}: keep at least one sensor")
        for sensor, k in self.keep:
            if sch.sensor_index(sensor) is None:
                raise ConfigError(f"encoder {self.name!r}: {self.behaviour} has no sensor {sensor!r} "
                                  f"(it has {', '.join(sch.sensor_names)})")
            if isinstance(k, bool) or not isinstance(k, int) or k < 1:
                raise ConfigError(f"encoder {self.name!r}: merge factor {sensor}={k!r}: give a whole number >= 1")

    @property
    def schema(self) -> Schema:
        return schema(self.behaviour)

    def _sensor(self, name: str) -> Sensor:
        """A kept sensor of the schema (checked to exist when the encoder was made)."""
        return next(s for s in self.schema.sensors if s.name == name)

    @property
    def columns(self) -> np.ndarray:
        return np.array([self.schema.sensor_names.index(s) for s, _ in self.keep], dtype=np.int64)

    @property
    def radix(self) -> np.ndarray:
        return np.array([-(-self._sensor(s).bins // k) for s, k in self.keep], dtype=np.int64)

    @property
    def n_states(self) -> int:
        """Observations a dense table would need (a Python int: it can exceed int64)."""
        n = 1
        for r in self.radix.tolist():
            n *= r
        return n

    def code(self, bins: np.ndarray) -> np.ndarray:
        """``(n,)`` int64 codes of ``(n, S)`` schema bins."""
        merged = bins[:, self.columns].astype(np.int64) // np.array([k for _, k in self.keep], dtype=np.int64)
        out = np.zeros(len(bins), dtype=np.int64)
        for j, r in enumerate(self.radix.tolist()):
            out = out * r + merged[:, j]
        return out

    def describe(self) -> str:
        parts = []
        for s, k in self.keep:
            sen = self._sensor(s)
            parts.append(f"{s} ({-(-sen.bins // k)} bins of {sen.width * k:g} {sen.unit})")
        return ", ".join(parts)


def _full(behaviour: str) -> Encoder:
    """Every sensor at the schema's bins; for Docking its polar set (the figures in docs/td/ were measured
    before the dock-frame sensors, coevo/tasks/fuel/dock_frame.py, joined the schema)."""
    from coevo.tasks.fuel.dock_frame import FRAME_NAMES

    names = [n for n in schema(behaviour).sensor_names if behaviour != "docking" or n not in FRAME_NAMES]
    return Encoder(behaviour, tuple((s, 1) for s in names), "full")


def _encoders() -> dict[tuple[str, str], Encoder]:
    from coevo.tasks.door.sensors import DOOR

    return {
        # Tracking: where the Target is (10 in x 30 deg) and where the nearest thing is (20 in x 45 deg).
        ("tracking", "reduced"): Encoder("tracking", (("target_range", 2), ("target_bearing", 6), ("range", 4),
                                                      ("bearing", 9)), "reduced"),
        ("tracking", "full"): _full("tracking"),
        # Docking: where the dock's front is (10 in x 15 deg) and how the robot is turned to it (15 deg).
        ("docking", "reduced"): Encoder("docking", (("dock_range", 2), ("dock_bearing", 3), ("dock_orientation", 3)),
                                        "reduced"),
        ("docking", "full"): _full("docking"),
        # Door: the five forward sonars at 72 in, the goal 35 in at a time, the heading in 45 deg sectors.
        ("door", "reduced"): Encoder(DOOR, (("left", 3), ("front_left", 3), ("front", 3), ("front_right", 3),
                                            ("right", 3), ("goal_range", 7), ("heading", 2)), "reduced"),
        ("door", "full"): _full(DOOR),
    }


ENCODERS = _encoders()
