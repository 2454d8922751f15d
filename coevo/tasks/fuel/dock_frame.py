"""Docking's sensors in the dock's frame *(ours)*, and the sensor sets Docking may learn over.

The report does not list Docking's sensors.  Besides the report's five, the Docking
schema holds two sets of dock sensors:

``polar`` (the first set): ``dock_range`` and ``dock_bearing``, the distance and
    the bearing from the robot to the middle of the dock's front face, and
    ``dock_orientation``, the robot's heading minus the head-on docking heading.
``dock-frame``: the robot's position and heading in the dock's own frame, whose
    axis runs north from the middle of the dock's front face:

    - ``dock_axis``: distance along the axis, from the front face's line to the
      robot's nearest edge (robot y - dock depth - robot radius; 0 = touching the
      line), inches, 5-inch bins 0..150 as the other ranges;
    - ``dock_offset``: signed lateral offset of the robot's centre from the axis
      (robot x - dock x: positive east, to the robot's left when it faces the dock
      head-on), inches, 5-inch bins from -75 to +75, the end bins holding
      everything beyond;
    - ``dock_orientation``: the heading relative to the axis (0 = pointing straight
      into the dock), shared with the polar set.

    In the polar set an aligned approach (on the axis, pointing along it) is a
    joint condition on ``dock_bearing`` and ``dock_orientation`` that changes with
    distance; here it is one interval on each of ``dock_offset`` and
    ``dock_orientation``.

``WorldConfig.docking_sensors`` chooses the set a Docking GA learns over: every rule it
makes leaves the other set's sensors unconditioned (``ANY``), and the population
starts from the direction-only default written in that set's terms
(``defaults/docking.rules`` for ``polar`` and ``both``,
``defaults/docking-dock-frame.rules`` for ``dock-frame``).  ``both`` may use all
five.  The schema always holds all of them, so a rule set reads and runs the same
whatever set it was learned over.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from coevo.policy.schema import Sensor

if TYPE_CHECKING:
    from coevo.tasks.fuel.world import BatchWorld

__all__ = ["FRAME_SENSORS", "FRAME_NAMES", "SENSOR_SETS", "DEFAULT_FILES", "observe"]

FRAME_SENSORS = (
    Sensor("dock_axis", 5.0, 31, False, "inches"),  # 0..145 plus a last "150+" bin
    Sensor("dock_offset", 5.0, 30, False, "inches", origin=-75.0, mirrored=True),  # "< -70" .. "70+"
)
FRAME_NAMES = frozenset(s.name for s in FRAME_SENSORS)

#: The dock sensors each choice of ``WorldConfig.docking_sensors`` lets Docking's rules condition on
#: (the report's five are always there).
SENSOR_SETS = {
    "polar": ("dock_range", "dock_bearing", "dock_orientation"),
    "dock-frame": ("dock_axis", "dock_offset", "dock_orientation"),
    "both": ("dock_range", "dock_bearing", "dock_orientation", "dock_axis", "dock_offset"),
}
#: The direction-only default of each set (coevo/tasks/fuel/defaults/).
DEFAULT_FILES = {"polar": "docking.rules", "dock-frame": "docking-dock-frame.rules", "both": "docking.rules"}
DOCK_SENSORS = frozenset(SENSOR_SETS["both"])


def observe(world: BatchWorld, want: set[str], rx: np.ndarray, ry: np.ndarray) -> dict[str, np.ndarray]:
    """Raw values of the frame sensors in ``want`` for robots at ``(rx, ry)`` (some or all of ``world``'s
    lanes), in inches; ``world.py``'s compiled sensing computes the same numbers."""
    out: dict[str, np.ndarray] = {}
    if "dock_axis" in want:
        out["dock_axis"] = ry - (world.dock_point[1] + world.cfg.robot_radius)
    if "dock_offset" in want:
        out["dock_offset"] = rx - world.dock_point[0]
    return out
