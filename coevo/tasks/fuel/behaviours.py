"""The three learning agents of the tracking-under-fuel task and what each senses and sets.

Every sensor is discretised into bins (report Appendix A §4): bearings in 5° bins,
ranges in 5-inch bins from 0 to 150 (a last bin for "150 and beyond"), the Target's
heading in 45° bins.  The Docking agent's dock sensors and the Executive's sensors
are *(ours)*: the report does not list them.  Docking's come in two sets, polar and
in the dock's frame (:mod:`.dock_frame`); ``WorldConfig.docking_sensors`` picks the one
it learns over.  Docking's rules leave the Target's own sensors (:data:`TARGET_SENSORS`)
out unless ``WorldConfig.docking_target_sensors``.

The schemas are registered by behaviour name (:mod:`coevo.policy.schema`).
"""

from __future__ import annotations

import enum

from coevo.policy.schema import Action, Schema, Sensor, register
from coevo.tasks.fuel.dock_frame import FRAME_SENSORS

__all__ = ["Behaviour", "SCHEMAS", "TASK_TRACK", "TASK_DOCK", "TURN", "SPEED", "TARGET_SENSORS"]

TASK_TRACK = 0
TASK_DOCK = 1


class Behaviour(str, enum.Enum):
    TRACKING = "tracking"
    DOCKING = "docking"
    EXECUTIVE = "executive"

    def __str__(self) -> str:
        return self.value

    # Hash as the plain name (Enum hashes its member name): the service keys dicts by plain
    # behaviour names, and a member must find the same entry as its name.
    __hash__ = str.__hash__


def _range(name: str) -> Sensor:
    return Sensor(name, 5.0, 31, False, "inches")  # 0..145 plus a last "150+" bin


def _bearing(name: str) -> Sensor:
    return Sensor(name, 5.0, 72, True, "degrees", mirrored=True)  # relative to the robot: its sign flips in a mirror


TURN = Action("turn", tuple(range(-24, 25, 4)), mirrored=True)  # deg/s, 13 values
SPEED = Action("speed", tuple(range(-4, 17, 4)))  # inches/s, 6 values
TASK = Action("task", ("track", "dock"))

_REPORT_FIVE = (
    _range("range"),  # to the nearest object (wall, dock or Target)
    _bearing("bearing"),
    Sensor("heading", 45.0, 8, True, "degrees", mirrored=True),  # Target's heading relative to its bearing
    _range("target_range"),
    _bearing("target_bearing"),
)

#: The Target's own sensors among the report's five (its heading, range and bearing).  Docking's rules leave them
#: out by default (``WorldConfig.docking_target_sensors``); ``range`` and ``bearing`` still see the Target when it is
#: the nearest object.
TARGET_SENSORS = frozenset({"heading", "target_range", "target_bearing"})

SCHEMAS = {
    Behaviour.TRACKING: Schema(Behaviour.TRACKING, _REPORT_FIVE, (TURN, SPEED)),
    Behaviour.DOCKING: Schema(
        Behaviour.DOCKING,
        _REPORT_FIVE
        + (
            _range("dock_range"),  # to the middle of the dock's front face
            _bearing("dock_bearing"),
            _bearing("dock_orientation"),  # robot heading minus the head-on docking heading
        )
        + FRAME_SENSORS,  # dock_axis, dock_offset: the robot's place in the dock's frame (dock_frame.py)
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

register(*SCHEMAS.values())
