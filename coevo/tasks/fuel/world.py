"""The batched world: many tracking-under-fuel arenas in one pymunk space.

Each lane ``i`` is an arena of its own, a cell of a grid laid out with gaps wider
than a robot, so lanes cannot touch each other.  The robot is a kinematic pymunk
body with a sensor shape: pymunk integrates its motion (velocity mode, report
Appendix A §4) and detects its contacts with the walls and the dock, which are
static shapes.  Contact is a mission failure, except a head-on slow contact with
the dock's front, which is a docking.  State lives in numpy arrays of shape
``(n, ...)`` and moves in and out of pymunk with its batch API, so a step costs a
few whole-array calls whatever ``n`` is.

The Target is a point random walk kept in numpy, and Robot-Target contact is an
exact circle-circle test there *(ours, for speed)*: the Target never touches the
walls or the dock (it turns away from them), so the only contact it could need
pymunk for is a two-circle distance, and a second kinematic body per lane cost
pymunk ~45 % of its step time (measured: 0.8 M robot-steps/s with Target bodies,
see ``coevo bench``).

Geometry *(ours)*: the dock is a box on the middle of the south wall, its front
face at ``y = dock_depth`` facing north; docking head-on means heading -90°.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymunk
import pymunk.batch as pb

from coevo.tasks.fuel import dock_frame
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["BatchWorld", "StepEvents", "MAX_SPEED", "MAX_TURN", "DOCK_HEADING", "SENSOR_NAMES"]

MAX_SPEED = 16.0  # ips, the fastest the robot can be set to
MAX_TURN = 24.0  # deg/s
DOCK_HEADING = -90.0  # deg: facing south, into the dock

_ROBOT, _WALL, _DOCK = 1, 4, 8  # collision types, also filter categories


SENSOR_NAMES = (
    "range", "bearing", "heading", "target_range", "target_bearing",
    "dock_range", "dock_bearing", "dock_orientation", "fuel", "dock_axis", "dock_offset",
)


@dataclass
class StepEvents:
    """What happened to each lane in a step, ``(n,)`` bool arrays (all False for lanes not stepped)."""

    collided: np.ndarray
    docked: np.ndarray
    dry: np.ndarray
    tracking: np.ndarray


def wrap_deg(a: np.ndarray) -> np.ndarray:
    """Angles in degrees folded into [0, 360) (floor-based: np.mod is 10x slower)."""
    return a - 360.0 * np.floor(a * (1.0 / 360.0))


def signed_deg(a: np.ndarray) -> np.ndarray:
    """Angles in degrees folded into [-180, 180)."""
    return wrap_deg(a + 180.0) - 180.0


def _signed_rad(a: np.ndarray) -> np.ndarray:
    return a - (2 * np.pi) * np.floor((a + np.pi) * (0.5 / np.pi))


def _norm(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    return np.sqrt(dx * dx + dy * dy)  # np.hypot is 4x slower


class BatchWorld:
    """``n`` independent arenas stepped together."""

    def __init__(self, config: WorldConfig, n: int) -> None:
        self.cfg = c = config
        self.n = n
        A = c.arena
        self.dock_x0 = A / 2 - c.dock_width / 2
        self.dock_x1 = A / 2 + c.dock_width / 2
        self.dock_point = np.array([A / 2, c.dock_depth])
        gap = 4 * max(c.robot_radius, c.target_radius) + 2 * MAX_SPEED * c.step_seconds
        self.pitch = A + gap
        cols = int(np.ceil(np.sqrt(n)))
        self.origin = np.stack([(np.arange(n) % cols) * self.pitch, (np.arange(n) // cols) * self.pitch], axis=1)

        space = pymunk.Space()
        space.collision_persistence = 1
        space.use_spatial_hash(c.hash_cell, max(1000, 20 * n))
        self.space = space
        wall_f = pymunk.ShapeFilter(categories=_WALL, mask=_ROBOT)
        dock_f = pymunk.ShapeFilter(categories=_DOCK, mask=_ROBOT)
        robot_f = pymunk.ShapeFilter(categories=_ROBOT, mask=_WALL | _DOCK)
        corners = [(0, 0), (A, 0), (A, A), (0, A)]
        self._robots: list[pymunk.Body] = []
        statics: list[pymunk.Shape] = []
        for i in range(n):
            ox, oy = self.origin[i]
            for k in range(4):
                (ax, ay), (bx, by) = corners[k], corners[(k + 1) % 4]
                statics.append(self._static(pymunk.Segment(space.static_body, (ox + ax, oy + ay), (ox + bx, oy + by), 0.0), _WALL, wall_f))
            box = [(ox + self.dock_x0, oy), (ox + self.dock_x1, oy), (ox + self.dock_x1, oy + c.dock_depth), (ox + self.dock_x0, oy + c.dock_depth)]
            statics.append(self._static(pymunk.Poly(space.static_body, box), _DOCK, dock_f))
        space.add(*statics)
        for i in range(n):
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.position = tuple(self.origin[i] + A / 2)
            shape = pymunk.Circle(body, c.robot_radius)
            shape.sensor = True
            shape.collision_type = _ROBOT
            shape.filter = robot_f
            shape.lane = i  # read back by the contact callbacks
            space.add(body, shape)
            self._robots.append(body)
        self._contacts: dict[int, list[int]] = {_WALL: [], _DOCK: []}
        for other in (_WALL, _DOCK):
            space.on_collision(_ROBOT, other, begin=self._on_contact, data=self._contacts[other])

        # Row of each body in pymunk's batch buffers (its own iteration order).
        buf = pb.Buffer()
        pb.get_space_bodies(space, pb.BodyFields.BODY_ID, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.uintp)
        row = {int(b): r for r, b in enumerate(ids)}
        self._nbodies = len(ids)
        self._robot_row = np.array([row[b.id] for b in self._robots])
        self._in_order = self._nbodies == n and np.array_equal(self._robot_row, np.arange(n))
        self._io = np.zeros((self._nbodies, 3))  # x, y, angle  or  vx, vy, omega
        # Two buffers: one pointed at our numpy array for writes, one owned by pymunk for
        # reads (a read may grow its array, which must never be memory numpy owns).
        self._wbuf = pb.Buffer()
        self._rbuf = pb.Buffer()

        # State, in arena-local coordinates; headings in radians (pymunk's angle).
        self.rx = np.zeros(n)
        self.ry = np.zeros(n)
        self.rh = np.zeros(n)
        self.tx = np.zeros(n)
        self.ty = np.zeros(n)
        self.th = np.zeros(n)
        self.fuel = np.zeros(n)
        self.speed = np.zeros(n)  # the last commanded speed, ips
        self.turn = np.zeros(n)  # the last commanded turn rate, deg/s
        self._centre = np.array([A / 2, A / 2])
        self._rows = np.arange(n)

    @staticmethod
    def _static(shape: pymunk.Shape, ctype: int, filt: pymunk.ShapeFilter) -> pymunk.Shape:
        shape.sensor = True
        shape.collision_type = ctype
        shape.filter = filt
        return shape

    @staticmethod
    def _on_contact(arbiter: pymunk.Arbiter, space: pymunk.Space, hits: list[int]) -> None:
        a, b = arbiter.shapes
        hits.append(a.lane if a.collision_type == _ROBOT else b.lane)

    # ----------------------------------------------------------------- placement
    def random_starts(self, m: int, rng: np.random.Generator) -> np.ndarray:
        """``m`` random epoch starts, rows of (robot x, y, heading, target x, y, heading) in radians."""
        c = self.cfg
        robot = np.empty((m, 2))
        target = np.empty((m, 2))
        todo = np.arange(m)
        while todo.size:
            k = todo.size
            robot[todo] = self._free_points(k, c.robot_radius, rng)
            target[todo] = self._free_points(k, c.target_radius, rng)
            far = np.hypot(*(robot[todo] - target[todo]).T) >= c.spawn_separation + c.robot_radius + c.target_radius
            todo = todo[~far]
        heading = rng.uniform(-np.pi, np.pi, (m, 2))
        return np.column_stack([robot, heading[:, 0], target, heading[:, 1]])

    def reset(self, lanes: np.ndarray, rng: np.random.Generator | None = None, *, starts: np.ndarray | None = None) -> None:
        """Start an epoch in ``lanes``: Robot and Target placed (random, or the given ``starts``
        rows from :meth:`random_starts`), fuel at its initial level."""
        lanes = np.asarray(lanes, dtype=np.int64)
        if lanes.size == 0:
            return
        if starts is None:
            if rng is None:
                raise ValueError("reset needs an rng or explicit starts")
            starts = self.random_starts(lanes.size, rng)
        self.rx[lanes], self.ry[lanes], self.rh[lanes] = starts[:, 0], starts[:, 1], starts[:, 2]
        self.tx[lanes], self.ty[lanes], self.th[lanes] = starts[:, 3], starts[:, 4], starts[:, 5]
        self.fuel[lanes] = self.cfg.initial_fuel
        self.speed[lanes] = 0.0
        self.turn[lanes] = 0.0
        self._push_positions()

    def _free_points(self, k: int, radius: float, rng: np.random.Generator) -> np.ndarray:
        c = self.cfg
        lo = c.spawn_margin + radius
        pts = rng.uniform(lo, c.arena - lo, (k, 2))
        near_dock = (pts[:, 1] < c.dock_depth + lo + 2 * c.robot_radius) & (np.abs(pts[:, 0] - c.arena / 2) < c.dock_width / 2 + lo)
        pts[near_dock, 1] += c.dock_depth + 2 * c.robot_radius  # keep clear of the dock
        return pts

    def place_at_dock(self, lanes: np.ndarray) -> None:
        """After a docking *(ours)*: just in front of the dock, facing into the arena, tank full."""
        lanes = np.asarray(lanes, dtype=np.int64)
        if lanes.size == 0:
            return
        c = self.cfg
        self.rx[lanes] = self.dock_point[0]
        self.ry[lanes] = self.dock_point[1] + c.robot_radius + 2 * c.dock_max_speed * c.step_seconds + 1.0
        self.rh[lanes] = np.pi / 2
        self.fuel[lanes] = 1.0
        self.speed[lanes] = 0.0
        self.turn[lanes] = 0.0
        # A Target standing where the robot must be is moved aside.
        clash = np.hypot(self.tx[lanes] - self.rx[lanes], self.ty[lanes] - self.ry[lanes]) < c.robot_radius + c.target_radius + 5
        if clash.any():
            self.ty[lanes[clash]] += 3 * (c.robot_radius + c.target_radius)
        self._push_positions()

    def set_state(
        self,
        lanes: np.ndarray | list[int],
        *,
        robot: tuple[float, float] | None = None,
        heading: float | None = None,
        target: tuple[float, float] | None = None,
        target_heading: float | None = None,
        fuel: float | None = None,
    ) -> None:
        """Put lanes into a given state (arena coordinates, degrees): for tests and tools."""
        lanes = np.asarray(lanes, dtype=np.int64)
        if robot is not None:
            self.rx[lanes], self.ry[lanes] = robot
        if heading is not None:
            self.rh[lanes] = np.radians(heading)
        if target is not None:
            self.tx[lanes], self.ty[lanes] = target
        if target_heading is not None:
            self.th[lanes] = np.radians(target_heading)
        if fuel is not None:
            self.fuel[lanes] = fuel
        self._push_positions()

    def _write(self, col: int, values: np.ndarray) -> None:
        if self._in_order:
            self._io[:, col] = values
        else:
            self._io[self._robot_row, col] = values

    def _push_positions(self) -> None:
        self._io[:] = 0.0
        self._write(0, self.rx + self.origin[:, 0])
        self._write(1, self.ry + self.origin[:, 1])
        self._write(2, self.rh)
        self._wbuf.set_float_buf(self._io.reshape(-1))
        pb.set_space_bodies(self.space, pb.BodyFields.POSITION | pb.BodyFields.ANGLE, self._wbuf)

    # ----------------------------------------------------------------- sensing
    def observe(self, names: tuple[str, ...] = SENSOR_NAMES) -> dict[str, np.ndarray]:
        """Raw sensor values of every lane, ``(n,)`` each, for the sensors in ``names``.

        Ranges in inches; bearings, headings and orientations in degrees in [0, 360);
        fuel in percent.  Only what is asked for is computed.
        """
        c = self.cfg
        out: dict[str, np.ndarray] = {}
        want = set(names)
        h = np.degrees(self.rh)
        dx, dy = self.tx - self.rx, self.ty - self.ry
        t_dist = _norm(dx, dy)
        if want & {"heading", "target_bearing", "range", "bearing"}:
            t_dir = np.degrees(np.arctan2(dy, dx))
        if want & {"range", "bearing"}:
            x, y = self.rx, self.ry
            A = c.arena
            qx = np.clip(x, self.dock_x0, self.dock_x1)
            qy = np.minimum(y, c.dock_depth)
            dock_gap = _norm(x - qx, y - qy)
            gaps = np.stack([x, A - x, y, A - y, dock_gap, t_dist - c.target_radius]) - c.robot_radius
            which = np.argmin(gaps, axis=0)
            out["range"] = np.maximum(gaps[which, self._rows], 0.0)
            obj_dir = _WALL_DIR[np.minimum(which, 4)]
            obj_dir = np.where(which == 5, t_dir, obj_dir)
            at_dock = np.flatnonzero(which == 4)
            if at_dock.size:
                obj_dir[at_dock] = np.degrees(np.arctan2(qy[at_dock] - y[at_dock], qx[at_dock] - x[at_dock]))
            out["bearing"] = wrap_deg(obj_dir - h)
        if "heading" in want:
            out["heading"] = wrap_deg(np.degrees(self.th) - t_dir)
        if "target_range" in want:
            out["target_range"] = t_dist
        if "target_bearing" in want:
            out["target_bearing"] = wrap_deg(t_dir - h)
        if want & {"dock_range", "dock_bearing"}:
            ddx, ddy = self.dock_point[0] - self.rx, self.dock_point[1] - self.ry
            out["dock_range"] = _norm(ddx, ddy)
            if "dock_bearing" in want:
                out["dock_bearing"] = wrap_deg(np.degrees(np.arctan2(ddy, ddx)) - h)
        if "dock_orientation" in want:
            out["dock_orientation"] = wrap_deg(h - DOCK_HEADING)
        if "fuel" in want:
            out["fuel"] = 100.0 * np.clip(self.fuel, 0.0, 1.0)
        if want & dock_frame.FRAME_NAMES:  # Docking's sensors in the dock's frame (dock_frame.py)
            out.update(dock_frame.observe(self, want))
        return {k: out[k] for k in names}

    def min_dock_steps(self, lanes: np.ndarray) -> np.ndarray:
        """Estimated fewest steps to dock from now (the report's m): turn to face the dock at full rate, drive
        there at full speed, one step to touch.  A lower bound: it ignores the slow, head-on final approach."""
        c = self.cfg
        ddx = self.dock_point[0] - self.rx[lanes]
        ddy = self.dock_point[1] - self.ry[lanes]
        dist = np.maximum(np.hypot(ddx, ddy) - c.robot_radius, 0.0)
        face = np.abs(signed_deg(np.degrees(np.arctan2(ddy, ddx) - self.rh[lanes])))
        return 1 + np.ceil(face / (MAX_TURN * c.step_seconds)) + np.ceil(dist / (MAX_SPEED * c.step_seconds))

    # ----------------------------------------------------------------- stepping
    def step(self, active: np.ndarray, turn: np.ndarray, speed: np.ndarray, target_noise: np.ndarray) -> StepEvents:
        """Advance the ``active`` lanes one step; the others stand still.

        ``turn`` (deg/s) and ``speed`` (ips) are the robot commands; ``target_noise``
        (deg) perturbs each Target's heading for its random walk.  All ``(n,)``.
        """
        c = self.cfg
        dt = c.step_seconds
        speed = np.where(active, speed, 0.0)
        turn = np.where(active, turn, 0.0)
        self._write(0, speed * np.cos(self.rh))
        self._write(1, speed * np.sin(self.rh))
        self._write(2, np.radians(turn))
        self._wbuf.set_float_buf(self._io.reshape(-1))
        pb.set_space_bodies(self.space, pb.BodyFields.VELOCITY | pb.BodyFields.ANGULAR_VELOCITY, self._wbuf)
        for hits in self._contacts.values():
            hits.clear()
        self.space.step(dt)
        self._rbuf.clear()
        pb.get_space_bodies(self.space, pb.BodyFields.POSITION | pb.BodyFields.ANGLE, self._rbuf)
        state = np.frombuffer(self._rbuf.float_buf(), dtype=np.float64).reshape(-1, 3)
        if not self._in_order:
            state = state[self._robot_row]
        np.copyto(self.rx, state[:, 0] - self.origin[:, 0], where=active)
        np.copyto(self.ry, state[:, 1] - self.origin[:, 1], where=active)
        np.copyto(self.rh, _signed_rad(state[:, 2]), where=active)
        self._target_walk(active, target_noise)
        self.speed[:] = speed
        self.turn[:] = turn

        wall = self._contacts[_WALL]
        dock = self._contacts[_DOCK]
        if wall or dock:
            self._park(wall + dock)
        dist = _norm(self.tx - self.rx, self.ty - self.ry)
        collided = active & (dist < c.robot_radius + c.target_radius)
        collided[wall] = True
        docked = np.zeros(self.n, dtype=bool)
        if dock:
            lanes = np.unique(np.asarray(dock, dtype=np.int64))
            ok = self._docking_accepted(lanes, speed[lanes]) & ~collided[lanes]
            docked[lanes[ok]] = True
            collided[lanes[~ok]] = True
        self.fuel -= np.where(active, c.fuel_idle + c.fuel_per_ips * np.abs(speed) + c.fuel_per_dps * np.abs(turn), 0.0)
        dry = active & (self.fuel <= 0.0) & ~docked & ~collided
        tracking = active & (dist >= c.tracking_min) & (dist <= c.tracking_max) & ~collided
        return StepEvents(collided=collided, docked=docked, dry=dry, tracking=tracking)

    def _park(self, lanes: list[int]) -> None:
        """Move robots that touched a wall or the dock to their arena's centre, in pymunk only.

        Their episode is over; left in contact they would cost pymunk a narrow-phase
        test every step until the next episode repositions them.
        """
        for i in set(lanes):
            self._robots[i].position = tuple(self.origin[i] + self._centre)

    def _docking_accepted(self, lanes: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Contact with the dock docks only on its front face, head-on within the angle, slowly enough."""
        c = self.cfg
        x, y = self.rx[lanes], self.ry[lanes]
        on_front = (y >= c.dock_depth) & (x >= self.dock_x0) & (x <= self.dock_x1)
        head_on = np.abs(signed_deg(np.degrees(self.rh[lanes]) - DOCK_HEADING)) <= c.dock_max_angle
        slow = (speed > 0) & (speed <= c.dock_max_speed)
        return on_front & head_on & slow

    def _target_walk(self, active: np.ndarray, noise_deg: np.ndarray) -> None:
        """Move the active Targets: a random walk that turns away from walls and the dock."""
        c = self.cfg
        th = _signed_rad(self.th + np.radians(noise_deg))
        cos, sin = np.cos(th), np.sin(th)
        ahead_x = self.tx + c.target_avoid * cos
        ahead_y = self.ty + c.target_avoid * sin
        lo = c.target_radius + 2.0
        hi = c.arena - lo
        near_dock = (ahead_y < c.dock_depth + lo + c.target_avoid / 2) & (np.abs(ahead_x - c.arena / 2) < c.dock_width)
        blocked = active & ((ahead_x < lo) | (ahead_x > hi) | (ahead_y < lo) | (ahead_y > hi) | near_dock)
        if blocked.any():
            k = np.flatnonzero(blocked)
            th[k] = _signed_rad(np.arctan2(self._centre[1] - self.ty[k], self._centre[0] - self.tx[k]) + np.radians(noise_deg[k]))
            cos[k], sin[k] = np.cos(th[k]), np.sin(th[k])
        step = c.target_speed * c.step_seconds
        np.copyto(self.tx, self.tx + step * cos, where=active)
        np.copyto(self.ty, self.ty + step * sin, where=active)
        np.copyto(self.th, th, where=active)


_WALL_DIR = np.array([180.0, 0.0, -90.0, 90.0, 0.0])  # west, east, south, north walls; dock filled in
