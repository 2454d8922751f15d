"""What the door robot senses and sets (report Appendix B §5), as a rule schema.

Seven sonars, far-left to far-right, each 0 to 168 in in 24-inch bins (the last bin,
``168``, is "no echo within range"); the range to the goal line, 0 to 168 in in 5-inch
bins (the last, ``165``, holds 165 and beyond); the robot's heading in the room in
22.5° bins (0 = toward the goal, counter-clockwise).  Actions: speed −4 to 10 ips in
steps of 2, turn −30 to 30 deg/s in steps of 10 (positive: to the left).

Rules print as ``IF front = [0, 24] AND goal_range = [0, 50] THEN SET turn = 10 AND
speed = 2 (strength 0.5)``; sonar names use underscores (``front_right``) because
rule text names are words.
"""

from __future__ import annotations

import numpy as np

from coevo.policy.schema import Action, Schema, Sensor, register
from coevo.tasks.door.settings import SONARS
from coevo.tasks.door.world import DoorWorld

__all__ = ["DOOR", "SCHEMA", "TURN", "SPEED", "sense", "action_values"]

DOOR = "door"
SONAR_BIN = 24.0
TURN = Action("turn", tuple(range(-30, 31, 10)))  # deg/s, 7 values
SPEED = Action("speed", tuple(range(-4, 11, 2)))  # ips, 8 values

SCHEMA = Schema(
    DOOR,
    tuple(Sensor(s, SONAR_BIN, 8, False, "inches") for s in SONARS)
    + (Sensor("goal_range", 5.0, 34, False, "inches"), Sensor("heading", 22.5, 16, True, "degrees")),
    (TURN, SPEED),
)
register(SCHEMA)

_SPEEDS = np.array(SPEED.values, dtype=np.float64)
_TURNS = np.array(TURN.values, dtype=np.float64)


def sense(world: DoorWorld, lanes: np.ndarray, sonar: np.ndarray | None = None) -> np.ndarray:
    """``(m, 9)`` uint8 sensor bins of ``lanes``, in the schema's order; ``sonar`` gives readings already
    taken (``world.sonars(lanes)``: the execution module's monitor reads them too, and they are the dearest part)."""
    out = np.empty((SCHEMA.n_sensors, len(lanes)), dtype=np.uint8)
    if sonar is None:
        sonar = world.sonars(lanes)
    sensors = SCHEMA.sensors
    for j in range(len(SONARS)):
        sensors[j].discretise(sonar[:, j], out[j])
    sensors[-2].discretise(world.goal_range(lanes), out[-2])
    sensors[-1].discretise(world.heading_deg(lanes), out[-1])
    return out.T


def action_values(actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(speed ips, turn deg/s) of ``(m, 2)`` action indices (turn, speed)."""
    return _SPEEDS[actions[:, 1]], _TURNS[actions[:, 0]]
