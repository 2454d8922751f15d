"""The batched door world: many trials of the door traversal task stepped together.

Trial ``i`` is a room of its own (report Appendix B, Figure 2): a robot on the
starting line, a wall across the room with an opening at ``opening[i]``, a goal
line beyond it.  State lives in numpy arrays of shape ``(n,)``; a decision moves
every running trial at once, and the sonars of the whole batch are read at once.

Why no pymunk: every wall is an axis-aligned box, so a sonar ray against the room
is a box exit (two divisions) and against the wall four face tests, and the
robot's contact with a wall is a point-to-box distance.  These closed forms on
whole arrays are all the physics the task needs; a pymunk space would add a
body per trial and a query per ray for nothing it could do better.

A sonar *(ours)* is ``sonar_rays`` rays spread over its 22.5° cone and reads the
nearest echo, measured from the robot's rim; no echo within range reads the
range.  A failed sonar reads 0, the minimum (report §7).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coevo import exactmath
from coevo.errors import ConfigError
from coevo.tasks.door.settings import SONAR_ANGLES, SONARS, DoorConfig

__all__ = ["Trials", "draw_trials", "DoorWorld", "RUNNING", "GOAL", "COLLISION", "TIMEOUT", "SONAR_CONE"]

RUNNING, GOAL, COLLISION, TIMEOUT = 0, 1, 2, 3
SONAR_CONE = 22.5  # degrees: each sonar's beam (report: "angular resolution of 22.5 degrees")


@dataclass(frozen=True)
class Trials:
    """The random draws of ``n`` trials: start ``x``, start ``heading`` (deg) and the opening's left edge."""

    x: np.ndarray
    heading: np.ndarray
    opening: np.ndarray

    def __len__(self) -> int:
        return len(self.x)

    def tile(self, times: int) -> Trials:
        """The same trials ``times`` over (every individual of a population faces the same ones)."""
        return Trials(np.tile(self.x, times), np.tile(self.heading, times), np.tile(self.opening, times))


def draw_trials(cfg: DoorConfig, n: int, rng: np.random.Generator) -> Trials:
    """``n`` fresh trials: a random point on the starting line, a random heading, a random opening."""
    lo = cfg.robot_radius + cfg.start_margin
    x = rng.uniform(lo, cfg.room_width - lo, n)
    heading = rng.uniform(-cfg.start_heading, cfg.start_heading, n)
    opening = rng.uniform(cfg.opening_margin, cfg.room_width - cfg.opening_margin - cfg.opening, n)
    return Trials(x, heading, opening)


class DoorWorld:
    """``n`` door trials stepped together; see the module docstring.

    Per trial: position ``x, y`` (inches), heading ``h`` (radians, 0 = toward the goal,
    counter-clockwise positive), ``outcome`` (RUNNING, GOAL, COLLISION, TIMEOUT) and
    ``time`` (seconds when it ended).  ``record=True`` keeps every substep's pose in
    ``path`` (for pictures).
    """

    def __init__(self, cfg: DoorConfig, trials: Trials, *, rng: np.random.Generator | None = None,
                 record: bool = False) -> None:
        if cfg.sonar_noise > 0 and rng is None:
            raise ConfigError("sonar_noise > 0 needs a random generator for the world")
        self.cfg = c = cfg
        self.rng = rng
        n = len(trials)
        self.n = n
        self.x = np.asarray(trials.x, dtype=np.float64).copy()
        self.y = np.full(n, c.start_line)
        self.h = np.deg2rad(np.asarray(trials.heading, dtype=np.float64))
        self.a = np.asarray(trials.opening, dtype=np.float64).copy()  # the opening spans [a, b]
        self.b = self.a + c.opening
        self.outcome = np.zeros(n, dtype=np.int8)
        self.time = np.zeros(n)
        self.decisions = 0
        self.working = np.array([s not in c.failed for s in SONARS])
        k = np.arange(c.sonar_rays)
        rays = (k + 0.5) / c.sonar_rays * SONAR_CONE - SONAR_CONE / 2
        offsets = np.deg2rad((np.array(SONAR_ANGLES)[:, None] + rays[None, :]).reshape(-1))  # (7*R,)
        ray_sin, ray_cos = exactmath.sincos(offsets)  # sines and cosines the same on every machine
        self._ray_sin, self._ray_cos = ray_sin[None, :], ray_cos[None, :]
        self.path: list[np.ndarray] | None = [self.pose()] if record else None
        if self._collides(self.x, self.y, self.a, self.b).any():
            i = int(np.flatnonzero(self._collides(self.x, self.y, self.a, self.b))[0])
            raise ConfigError(f"trial {i} starts in contact with a wall (x={self.x[i]:.1f}, y={self.y[i]:.1f})")

    @property
    def running(self) -> np.ndarray:
        return self.outcome == RUNNING

    def pose(self) -> np.ndarray:
        """``(n, 3)``: x, y and heading in degrees of every trial."""
        return np.stack([self.x, self.y, np.rad2deg(self.h)], axis=1)

    # ------------------------------------------------------------ sensing
    def sonars(self, lanes: np.ndarray) -> np.ndarray:
        """``(m, 7)`` sonar readings (inches) of ``lanes``, far-left to far-right."""
        c = self.cfg
        # Each ray is the heading turned by a fixed offset: two sines and cosines per trial, not per ray
        # (sonars are ~45 % of a generation; this made them ~30 % faster, measured in docs/door.md).
        h = self.h[lanes, None]
        sh, ch = exactmath.sincos(h)
        dx = -(sh * self._ray_cos + ch * self._ray_sin)
        dy = ch * self._ray_cos - sh * self._ray_sin
        x, y = self.x[lanes, None], self.y[lanes, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            ix, iy = 1.0 / dx, 1.0 / dy
            # The room: where the ray leaves its box.
            t = np.minimum(np.where(dx > 0, c.room_width - x, -x) * ix, np.where(dy > 0, c.room_depth - y, -y) * iy)
            # The wall's two long faces, outside the opening.
            a, b = self.a[lanes, None], self.b[lanes, None]
            for face in (c.wall_near, c.wall_far):
                tf = (face - y) * iy
                hx = x + tf * dx
                np.copyto(t, tf, where=(tf > 0) & (tf < t) & ((hx <= a) | (hx >= b)))
            # The opening's two edges (the wall's end faces).
            for edge in (a, b):
                tf = (edge - x) * ix
                hy = y + tf * dy
                np.copyto(t, tf, where=(tf > 0) & (tf < t) & (hy >= c.wall_near) & (hy <= c.wall_far))
        reading = t.reshape(len(lanes), len(SONARS), c.sonar_rays).min(axis=2) - c.robot_radius
        if c.sonar_noise > 0:
            reading = reading + self.rng.normal(0.0, c.sonar_noise, reading.shape)  # type: ignore[union-attr]
        reading = np.clip(reading, 0.0, c.sonar_range)
        reading[:, ~self.working] = 0.0
        return reading

    def goal_range(self, lanes: np.ndarray) -> np.ndarray:
        """Distance (inches) from the robot's centre to the goal line, 0 once across."""
        return np.maximum(self.cfg.goal_line - self.y[lanes], 0.0)

    def heading_deg(self, lanes: np.ndarray) -> np.ndarray:
        """The robot's heading in the room, [0, 360) degrees, 0 toward the goal, counter-clockwise."""
        d = np.rad2deg(self.h[lanes])
        return d - 360.0 * np.floor(d * (1.0 / 360.0))

    # ------------------------------------------------------------ acting
    def act(self, lanes: np.ndarray, speed: np.ndarray, turn: np.ndarray) -> None:
        """One decision: ``lanes`` drive at ``speed`` (ips) turning at ``turn`` (deg/s) for a decision period.

        The motion is integrated in ``substeps`` (midpoint heading); a trial ends at the
        first substep where it touches a wall (COLLISION) or crosses the goal line (GOAL);
        after ``time_limit`` decisions the rest end as TIMEOUT.
        """
        c = self.cfg
        dt = c.decision_seconds / c.substeps
        x, y, h = self.x[lanes], self.y[lanes], self.h[lanes]
        a, b = self.a[lanes], self.b[lanes]
        step = np.asarray(speed, dtype=np.float64) * dt
        w = np.deg2rad(np.asarray(turn, dtype=np.float64)) * dt
        run = np.ones(len(lanes), dtype=bool)
        outcome = np.zeros(len(lanes), dtype=np.int8)
        ended = np.zeros(len(lanes))
        t0 = self.decisions * c.decision_seconds
        for k in range(c.substeps):
            sin_mid, cos_mid = exactmath.sincos(h + 0.5 * w)
            x = np.where(run, x - step * sin_mid, x)
            y = np.where(run, y + step * cos_mid, y)
            h = np.where(run, h + w, h)
            hit = run & self._collides(x, y, a, b)
            goal = run & ~hit & (y >= c.goal_line)
            outcome[hit] = COLLISION
            outcome[goal] = GOAL
            ended[hit | goal] = t0 + (k + 1) * dt
            run &= ~(hit | goal)
            if self.path is not None:
                self.x[lanes], self.y[lanes], self.h[lanes] = x, y, h
                self.path.append(self.pose())
        self.x[lanes], self.y[lanes], self.h[lanes] = x, y, h
        self.outcome[lanes] = outcome
        self.time[lanes] = ended
        self.decisions += 1
        if self.decisions >= c.time_limit:
            late = self.running
            self.outcome[late] = TIMEOUT
            self.time[late] = self.decisions * c.decision_seconds

    def _collides(self, x: np.ndarray, y: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Does a robot at ``x, y`` touch the room's walls or the wall's two pieces ([0, a] and [b, width])?"""
        c = self.cfg
        r = c.robot_radius
        room = (x < r) | (x > c.room_width - r) | (y < r) | (y > c.room_depth - r)
        gy = np.maximum(np.maximum(c.wall_near - y, y - c.wall_far), 0.0)
        gx = np.minimum(np.maximum(x - a, 0.0), np.maximum(b - x, 0.0))
        return room | (gx * gx + gy * gy < r * r)
