"""The batched world: many tracking-under-fuel arenas in one pymunk space.

Each lane ``i`` is an arena of its own, a cell of a grid laid out with gaps wider
than a robot, so lanes cannot touch each other.  The robot moves as a kinematic
pymunk body in velocity mode (report Appendix A §4): its pose is integrated here with
pymunk's own operations (``cpBodyUpdatePosition``), and pymunk detects its contacts
with the walls and the dock, static shapes, through probe bodies lent to the lanes
within reach of them (:meth:`BatchWorld._sense_contacts`).  Contact is a mission
failure, except a head-on slow contact with the dock's front, which is a docking.
State lives in numpy arrays of shape ``(n, ...)``; sensing and stepping are
whole-array numpy passes, or for big batches compiled loops (numba, :mod:`.kernels`)
doing the same operations in the same order.

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
from types import ModuleType

import numpy as np
import pymunk
import pymunk.batch as pb

from coevo import exactmath
from coevo.policy.schema import Schema
from coevo.tasks.fuel import dock_frame
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["BatchWorld", "StepEvents", "MAX_SPEED", "MAX_TURN", "DOCK_HEADING", "SENSOR_NAMES"]

MAX_SPEED = 16.0  # ips, the fastest the robot can be set to
MAX_TURN = 24.0  # deg/s
DOCK_HEADING = -90.0  # deg: facing south, into the dock

_ROBOT, _WALL, _DOCK = 1, 4, 8  # collision types, also filter categories
_DOCK_SIDE = 4  # arena sides 0-3: south, east, north, west walls; 4: the dock


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


def _directions(pairs: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, np.ndarray]:
    """The angle in degrees of each named (dy, dx) pair, from one :func:`coevo.exactmath.atan2` call: it is
    elementwise, so the same bits as one call each, and numpy's cost is per call at a step's sizes."""
    if not pairs:
        return {}
    ys, xs = zip(*pairs.values())
    angles = np.degrees(exactmath.atan2(np.concatenate(ys), np.concatenate(xs)))
    return dict(zip(pairs, np.split(angles, np.cumsum([len(y) for y in ys])[:-1]), strict=True))


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
        # The hash's cell count serves the static shapes (5 per lane) and the few probes alike; pymunk clears all
        # cells of the probes' hash every step, which at 20 cells a lane was most of a 450-lane step's pymunk time
        # (13 us; 5 us at 1000 cells).  Which shapes touch does not depend on it (the hash only proposes pairs).
        space.use_spatial_hash(c.hash_cell, max(1000, 2 * n))
        self.space = space
        wall_f = pymunk.ShapeFilter(categories=_WALL, mask=_ROBOT)
        dock_f = pymunk.ShapeFilter(categories=_DOCK, mask=_ROBOT)
        robot_f = pymunk.ShapeFilter(categories=_ROBOT, mask=_WALL | _DOCK)
        corners = [(0, 0), (A, 0), (A, A), (0, A)]
        # One static body (at the origin, unrotated: shapes keep the coordinates they are given) per side
        # of the arenas (south, east, north, west walls) and one for the docks: the body a robot's
        # contact is with says which of its arena's five shapes it touches (see _sense_contacts).
        self._sides = [pymunk.Body(body_type=pymunk.Body.STATIC) for _ in range(5)]
        statics: list[pymunk.Shape] = []
        for i in range(n):
            ox, oy = self.origin[i]
            for k in range(4):
                (ax, ay), (bx, by) = corners[k], corners[(k + 1) % 4]
                statics.append(self._static(pymunk.Segment(self._sides[k], (ox + ax, oy + ay), (ox + bx, oy + by), 0.0), _WALL, wall_f))
            box = [(ox + self.dock_x0, oy), (ox + self.dock_x1, oy), (ox + self.dock_x1, oy + c.dock_depth), (ox + self.dock_x0, oy + c.dock_depth)]
            statics.append(self._static(pymunk.Poly(self._sides[_DOCK_SIDE], box), _DOCK, dock_f))
        space.add(*self._sides, *statics)
        self._side_ids = np.array([b.id for b in self._sides], dtype=np.uintp)
        self._side_of_sorted = np.argsort(self._side_ids)
        self._side_order_ids = self._side_ids[self._side_of_sorted]
        # Robots (see _sense_contacts): each lane's pose as pymunk would hold it for a kinematic body,
        # global coordinates, integrated here with pymunk's own arithmetic; pymunk tests contacts with
        # a pool of probe bodies lent to the lanes that are within reach of a wall or the dock.
        self._robot_f = robot_f
        self._gx = self.origin[:, 0] + A / 2
        self._gy = self.origin[:, 1] + A / 2
        self._ga = np.zeros(n)
        self._lane_probe = np.full(n, -1, dtype=np.int64)
        self._probe_lane = np.zeros(0, dtype=np.int64)
        self._probes: list[pymunk.Body] = []
        self._probe_row = np.zeros(0, dtype=np.int64)
        self._void = np.zeros((0, 2))
        self._io = np.zeros((0, 2))
        self._wbuf = pb.Buffer()
        self._probe_ids = np.zeros(0, dtype=np.uintp)  # pymunk body ids of the probes, sorted
        self._probe_of_id = np.zeros(0, dtype=np.int64)  # ... and their probe index
        self._abuf = pb.Buffer()
        self._touching: set[int] = set()  # lane * 5 + side of every contact at the last step
        self._contacts: dict[int, list[int]] = {_WALL: [], _DOCK: []}  # lanes that began touching a wall, the dock
        r, m = c.robot_radius, _REACH_MARGIN
        self._mid = self.origin + A / 2
        self._near_half = A / 2 - r - m  # a centre farther than this from the middle (in x or y) may touch a wall
        self._near_dock_y = c.dock_depth + r + m - A / 2  # ... one below this and within this of the middle, the dock
        self._near_dock_x = c.dock_width / 2 + r + m

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
        self._compiled_constants()

    def _compiled_constants(self) -> None:
        """What the compiled loops (:mod:`.kernels`) take as arrays, and their buffers."""
        c, n = self.cfg, self.n
        self._ox, self._oy = self.origin[:, 0].copy(), self.origin[:, 1].copy()
        self._midx, self._midy = self._mid[:, 0].copy(), self._mid[:, 1].copy()
        self._geom = np.array([c.arena, self.dock_x0, self.dock_x1, c.dock_depth, c.robot_radius, c.target_radius,
                               self.dock_point[0], self.dock_point[1]], dtype=np.float64)
        lo = c.target_radius + 2.0
        t_step = c.target_speed * c.step_seconds
        self._walk = np.array([c.target_avoid, lo, c.arena - lo, c.dock_depth + lo + c.target_avoid / 2, c.arena / 2,
                               c.dock_width, t_step, self._centre[0], self._centre[1]], dtype=np.float64)
        self._event_consts = np.array([
            c.robot_radius + c.target_radius, c.dock_depth, self.dock_x0, self.dock_x1, c.dock_max_angle,
            c.dock_max_speed, self._centre[0], t_step, c.fuel_idle, c.fuel_per_ips, c.fuel_per_dps, c.tracking_min,
            c.tracking_max], dtype=np.float64)
        self._idx = np.empty(n, dtype=np.int64)  # the active lanes of a step
        self._blocked = np.empty(n, dtype=np.int64)  # ... the lanes whose Target turns away, and its arctan2's
        self._bdy, self._bdx, self._bang = np.empty(n), np.empty(n), np.empty(n)  # arguments and result
        self._near = np.empty(n, dtype=np.bool_)  # lanes within reach of a wall or the dock
        # The kernels' views of the state (its arrays are only ever written in place).
        self._sensing = (self.rx, self.ry, self.rh, self.tx, self.ty, self.th, self.fuel, self._geom)
        self._moving = (self.rh, self._gx, self._gy, self._ga, self._ox, self._oy, self.rx, self.ry, self.th, self.tx,
                        self.ty)
        self._settling = (self.rh, self._gx, self._gy, self._ox, self._oy, self.rx, self.ry, self.th, self.tx, self.ty)
        self._reach = (self._midx, self._midy, np.array([self._near_half, self._near_dock_y, self._near_dock_x]))
        self._probing = self._probe_state()

    def _probe_state(self) -> tuple[np.ndarray, ...]:
        """The probes' arrays as the kernels take them (new ones whenever the pool grows)."""
        return self._lane_probe, self._probe_lane, self._probe_row, self._io, self._void, self._near

    @staticmethod
    def _static(shape: pymunk.Shape, ctype: int, filt: pymunk.ShapeFilter) -> pymunk.Shape:
        shape.sensor = True
        shape.collision_type = ctype
        shape.filter = filt
        return shape

    def _grow(self, k: int) -> None:
        """``k`` more probe bodies, parked in the void (below the grid, a hash cell apart)."""
        c, space = self.cfg, self.space
        j0 = len(self._probes)
        for j in range(j0, j0 + k):
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.position = self._void_point(j)
            shape = pymunk.Circle(body, c.robot_radius)
            shape.sensor = True
            shape.collision_type = _ROBOT
            shape.filter = self._robot_f
            space.add(body, shape)
            self._probes.append(body)
        self._probe_lane = np.concatenate([self._probe_lane, np.full(k, -1, dtype=np.int64)])
        self._void = np.array([self._void_point(j) for j in range(len(self._probes))])
        # Row of each probe in pymunk's batch buffers (its own iteration order).
        buf = pb.Buffer()
        pb.get_space_bodies(space, pb.BodyFields.BODY_ID, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.uintp)
        row = {int(b): r for r, b in enumerate(ids)}
        self._probe_row = np.array([row[b.id] for b in self._probes], dtype=np.int64)
        pid = np.array([b.id for b in self._probes], dtype=np.uintp)
        order = np.argsort(pid)
        self._probe_ids, self._probe_of_id = pid[order], order
        self._io = np.zeros((len(ids), 2))
        self._io[self._probe_row] = self._void
        self._probing = self._probe_state()

    def _void_point(self, j: int) -> tuple[float, float]:
        step = max(self.cfg.hash_cell, 4 * self.cfg.robot_radius) * 2
        return (float(j * step), float(-4 * self.pitch - 10 * step))

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
            far = _norm(*(robot[todo] - target[todo]).T) >= c.spawn_separation + c.robot_radius + c.target_radius
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
        clash = _norm(self.tx[lanes] - self.rx[lanes], self.ty[lanes] - self.ry[lanes]) < c.robot_radius + c.target_radius + 5
        if clash.any():
            self.ty[lanes[clash]] += 3 * (c.robot_radius + c.target_radius)
        self._push_positions()

    def set_state(
        self,
        lanes: np.ndarray | list[int],
        *,
        robot: tuple[float | np.ndarray, float | np.ndarray] | None = None,
        heading: float | np.ndarray | None = None,
        target: tuple[float | np.ndarray, float | np.ndarray] | None = None,
        target_heading: float | np.ndarray | None = None,
        fuel: float | np.ndarray | None = None,
    ) -> None:
        """Put lanes into a given state (arena coordinates, degrees): for tests and tools.  Each value is one for
        all of ``lanes`` or an array of one per lane."""
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

    def _push_positions(self) -> None:
        """Every robot's pymunk pose set from the state (as a kinematic body's position and angle would be)."""
        np.add(self.rx, self.origin[:, 0], out=self._gx)
        np.add(self.ry, self.origin[:, 1], out=self._gy)
        self._ga[:] = self.rh

    # ----------------------------------------------------------------- sensing
    def observe(self, names: tuple[str, ...] = SENSOR_NAMES) -> dict[str, np.ndarray]:
        """Raw sensor values of every lane, ``(n,)`` each, for the sensors in ``names``.

        Ranges in inches; bearings, headings and orientations in degrees in [0, 360);
        fuel in percent.  Only what is asked for is computed.
        """
        return self._observe(names, None)

    def _observe(self, names: tuple[str, ...], lanes: np.ndarray | None) -> dict[str, np.ndarray]:
        """:meth:`observe` of ``lanes`` only (None: all), the same numbers for them."""
        c = self.cfg
        out: dict[str, np.ndarray] = {}
        want = set(names)
        if lanes is None:
            rx, ry, rh, tx, ty = self.rx, self.ry, self.rh, self.tx, self.ty
        else:
            rx, ry, rh, tx, ty = self.rx[lanes], self.ry[lanes], self.rh[lanes], self.tx[lanes], self.ty[lanes]
        h = np.degrees(rh)
        dx, dy = tx - rx, ty - ry
        t_dist = _norm(dx, dy)
        ranged = bool(want & {"range", "bearing"})
        if ranged:
            x, y = rx, ry
            A = c.arena
            qx = np.clip(x, self.dock_x0, self.dock_x1)
            qy = np.minimum(y, c.dock_depth)
            dock_gap = _norm(x - qx, y - qy)
            r = c.robot_radius
            gaps = (x - r, (A - x) - r, y - r, (A - y) - r, dock_gap - r, (t_dist - c.target_radius) - r)
            nearest = gaps[0]
            for g in gaps[1:]:
                nearest = np.minimum(nearest, g)
            out["range"] = np.maximum(nearest, 0.0)
            at_dock = np.flatnonzero(gaps[4] == nearest)
        if want & {"dock_range", "dock_bearing"}:
            ddx, ddy = self.dock_point[0] - rx, self.dock_point[1] - ry
            out["dock_range"] = _norm(ddx, ddy)
        # Every direction the sensors need (to the Target, to the dock's nearest point where it is the nearest object,
        # to the middle of the dock's front), in degrees, from one arctangent call.
        pairs = {}
        if want & {"heading", "target_bearing", "range", "bearing"}:
            pairs["target"] = (dy, dx)
        if ranged and at_dock.size:
            pairs["dock_gap"] = (qy[at_dock] - y[at_dock], qx[at_dock] - x[at_dock])
        if "dock_bearing" in want:
            pairs["dock"] = (ddy, ddx)
        dirs = _directions(pairs)
        if ranged:
            # The direction of the nearest object, the first of equals winning (argmin's rule): Target,
            # then dock, then the walls, later ones overwriting.
            obj_dir = dirs["target"].copy()
            if at_dock.size:
                obj_dir[at_dock] = dirs["dock_gap"]
            for k in (3, 2, 1, 0):
                obj_dir[gaps[k] == nearest] = _WALL_DIR[k]
            out["bearing"] = wrap_deg(obj_dir - h)
        if "heading" in want:
            th = self.th if lanes is None else self.th[lanes]
            out["heading"] = wrap_deg(np.degrees(th) - dirs["target"])
        if "target_range" in want:
            out["target_range"] = t_dist
        if "target_bearing" in want:
            out["target_bearing"] = wrap_deg(dirs["target"] - h)
        if "dock_bearing" in want:
            out["dock_bearing"] = wrap_deg(dirs["dock"] - h)
        if "dock_orientation" in want:
            out["dock_orientation"] = wrap_deg(h - DOCK_HEADING)
        if "fuel" in want:
            fuel = self.fuel if lanes is None else self.fuel[lanes]
            out["fuel"] = 100.0 * np.clip(fuel, 0.0, 1.0)
        if want & dock_frame.FRAME_NAMES:  # Docking's sensors in the dock's frame (dock_frame.py)
            out.update(dock_frame.observe(self, want, rx, ry))
        return {k: out[k] for k in names}

    def _sense_bins(self, sch: Schema, lanes: np.ndarray | None) -> np.ndarray:
        """``sch.discretise(self._observe(sch.sensor_names, lanes))``: the (n, S) uint8 bins of ``lanes`` (None: all).
        (run_lanes' compiled steps sense in :func:`.kernels.decide_lanes`.)"""
        return sch.discretise(self._observe(sch.sensor_names, lanes))

    def sensing_state(self) -> tuple[np.ndarray, ...]:
        """What :func:`.kernels.decide_lanes` reads of the world: rx, ry, rh, tx, ty, th, fuel, geometry."""
        return self._sensing

    def min_dock_steps(self, lanes: np.ndarray) -> np.ndarray:
        """Estimated fewest steps to dock from now (the report's m): turn to face the dock at full rate, drive
        there at full speed, one step to touch.  A lower bound: it ignores the slow, head-on final approach."""
        c = self.cfg
        ddx = self.dock_point[0] - self.rx[lanes]
        ddy = self.dock_point[1] - self.ry[lanes]
        dist = np.maximum(_norm(ddx, ddy) - c.robot_radius, 0.0)
        face = np.abs(signed_deg(np.degrees(exactmath.atan2(ddy, ddx) - self.rh[lanes])))
        return 1 + np.ceil(face / (MAX_TURN * c.step_seconds)) + np.ceil(dist / (MAX_SPEED * c.step_seconds))

    # ----------------------------------------------------------------- stepping
    def step(self, active: np.ndarray, turn: np.ndarray, speed: np.ndarray, target_noise: np.ndarray) -> StepEvents:
        """Advance the ``active`` lanes one step; the others stand still.

        ``turn`` (deg/s) and ``speed`` (ips) are the robot commands; ``target_noise``
        (deg) perturbs each Target's heading for its random walk.  All ``(n,)``.
        """
        kernels = compiled_loops(int(np.count_nonzero(active)))
        if kernels is not None:
            events = np.zeros((4, self.n), dtype=np.bool_)
            self.step_compiled(kernels, events, active, turn, speed, target_noise)
            return StepEvents(collided=events[0], docked=events[1], dry=events[2], tracking=events[3])
        c = self.cfg
        dt = c.step_seconds
        speed = np.where(active, speed, 0.0)
        turn = np.where(active, turn, 0.0)
        idx = np.flatnonzero(active)
        # Robots and Targets of standing lanes do not move, so everything below is computed on the
        # active lanes only (all of them: ``a`` a slice, no copies).
        a = slice(None) if idx.size == self.n else idx
        # pymunk's integration of a kinematic body (cpBodyUpdatePosition), operation for operation:
        # p += (v + v_bias) * dt, a += (w + w_bias) * dt, the biases zero.  A standing robot's velocity
        # is zero, which leaves its pose as it is.
        rh, sp, tu = self.rh[a], speed[a], turn[a]
        noise = target_noise[a]
        th = _signed_rad(self.th[a] + np.radians(noise))  # the Targets' headings before they walk
        # One call for the robots' and the Targets' headings (elementwise: the same bits as two; numpy's cost is
        # per call at these sizes).
        sines, cosines = exactmath.sincos(np.concatenate([rh, th]))
        m = rh.size
        gx = self._gx[a] + sp * cosines[:m] * dt
        gy = self._gy[a] + sp * sines[:m] * dt
        ga = self._ga[a] + np.radians(tu) * dt
        self._gx[a], self._gy[a], self._ga[a] = gx, gy, ga
        self._sense_contacts(dt)
        rx = self.rx[a] = gx - self.origin[a, 0]
        ry = self.ry[a] = gy - self.origin[a, 1]
        self.rh[a] = _signed_rad(ga)
        self._target_walk(a, noise, th, sines[m:], cosines[m:])
        self.speed[:] = speed
        self.turn[:] = turn

        wall = self._contacts[_WALL]
        dock = self._contacts[_DOCK]
        if wall or dock:
            self._park(wall + dock)
        dist = _norm(self.tx[a] - rx, self.ty[a] - ry)
        collided = np.zeros(self.n, dtype=bool)
        collided[a] = dist < c.robot_radius + c.target_radius
        docked = self._touched(wall, dock, speed, collided)
        fuel = self.fuel[a] = self.fuel[a] - (c.fuel_idle + c.fuel_per_ips * np.abs(sp) + c.fuel_per_dps * np.abs(tu))
        going = ~collided[a]
        dry = np.zeros(self.n, dtype=bool)
        dry[a] = (fuel <= 0.0) & going & ~docked[a]
        tracking = np.zeros(self.n, dtype=bool)
        tracking[a] = (dist >= c.tracking_min) & (dist <= c.tracking_max) & going
        return StepEvents(collided=collided, docked=docked, dry=dry, tracking=tracking)

    def _touched(self, wall: list[int], dock: list[int], speed: np.ndarray, collided: np.ndarray) -> np.ndarray:
        """Lanes that touched a wall collided (``collided`` is updated); those that touched the dock docked if
        the approach was accepted and they did not hit the Target, else collided.  Returns ``docked``."""
        collided[wall] = True
        docked = np.zeros(self.n, dtype=bool)
        if dock:
            lanes = np.unique(np.asarray(dock, dtype=np.int64))
            ok = self._docking_accepted(lanes, speed[lanes]) & ~collided[lanes]
            docked[lanes[ok]] = True
            collided[lanes[~ok]] = True
        return docked

    def step_compiled(self, kernels: ModuleType, events: np.ndarray, active: np.ndarray, turn: np.ndarray,
                      speed: np.ndarray, target_noise: np.ndarray) -> None:
        """:meth:`step` with the compiled loops (``kernels``, from :func:`compiled_loops`), its events written
        into ``events``: (4, n) bool, rows collided, docked, dry, tracking (as :class:`StepEvents`).

        :func:`.kernels.move`, pymunk's contacts, :func:`.kernels.events`: the same operations in the same
        order as numpy's step (:mod:`coevo.exactmath`'s sine, cosine and arctangent in both).
        """
        dt = self.cfg.step_seconds
        m, nb, stepping, need, free = kernels.move(active, speed, turn, self.speed, self.turn, dt, self._moving,
                                                   self._walk, target_noise, self._idx, self._blocked, self._bdy,
                                                   self._bdx, self._reach, self._probing)
        if nb:  # Targets turning away from a wall or the dock, towards the centre
            self._touching = set()  # as the compiled step always did (the numpy step does not: docs/performance.md)
            kernels.atan2_into(self._bdy[:nb], self._bdx[:nb], self._bang[:nb])
        self._contacts = {_WALL: [], _DOCK: []}
        if stepping:  # a robot is within reach of a wall or the dock, or a probe went back: pymunk tests
            if free < need:
                self._grow(max(need - free, 16))
            kernels.assign_probes(self._gx, self._gy, self._probing)
            self._pymunk_contacts(dt, kernels)
        kernels.events(self._idx[:m], self._blocked[:nb], self._bang[:nb], target_noise,
                       _as_lanes(self._contacts[_WALL]), _as_lanes(self._contacts[_DOCK]), self._settling, self.speed,
                       self.turn, self.fuel, self._event_consts, events)

    def last_contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """The lanes whose robot began touching a wall, and the dock, at the last step: sorted, unique, copies.
        Read-only, for tools that ask what a robot hit (``benchmarks/loss_anatomy.py``): a dock contact there
        is a docking or a collision as :meth:`step`'s events say, and a Target contact is its distance test."""
        return (np.unique(np.asarray(self._contacts[_WALL], dtype=np.int64)),
                np.unique(np.asarray(self._contacts[_DOCK], dtype=np.int64)))

    def _park(self, lanes: list[int]) -> None:
        """Move robots that touched a wall or the dock to their arena's centre, in pymunk only.

        Their episode is over; left in contact they would cost pymunk a narrow-phase
        test every step until the next episode repositions them.
        """
        i = np.unique(np.asarray(lanes, dtype=np.int64))
        self._gx[i] = self.origin[i, 0] + self._centre[0]
        self._gy[i] = self.origin[i, 1] + self._centre[1]

    def _sense_contacts(self, dt: float) -> None:
        """pymunk's contact tests of the robots at their new poses (``self._g*``); fills ``self._contacts``
        with the lanes whose robot began touching a wall or the dock.

        A robot far from its arena's walls and dock cannot touch them (pymunk reports a contact only
        where bounding boxes meet), so only the lanes within reach get a probe: a kinematic body of
        the robot's shape, put at the robot's pose.  A lane keeps its probe as long as it stays within
        reach, so the probe's contact pairs are the lane's, and pymunk's "begin" (touching now, not at
        the previous step) means what it meant with one body per lane.  Free probes wait in the void.
        (The compiled step lends them in :func:`.kernels.move` and :func:`.kernels.assign_probes`.)
        """
        self._contacts = {_WALL: [], _DOCK: []}
        if self._lend_probes():
            self._pymunk_contacts(dt)

    def _lend_probes(self) -> bool:
        """Probes lent to the lanes within reach and put at their robots' poses (``self._io``), those of the
        others back in the void.  False if no lane is within reach and none gave a probe back: nothing to test."""
        # Centres relative to the arena's middle; |.| beyond half: within reach of a wall.
        mx, my = self._gx - self._mid[:, 0], self._gy - self._mid[:, 1]
        np.abs(mx, out=mx)
        near = mx > self._near_half
        near |= np.abs(my) > self._near_half
        dock = my < self._near_dock_y
        if dock.any():
            near |= dock & (mx < self._near_dock_x)
        lp, pl = self._lane_probe, self._probe_lane
        gone = np.flatnonzero((lp >= 0) & ~near)
        if gone.size:
            pl[lp[gone]] = -1
            self._io[self._probe_row[lp[gone]]] = self._void[lp[gone]]
            lp[gone] = -1
        need = np.flatnonzero(near & (lp < 0))
        if need.size:
            free = np.flatnonzero(pl < 0)
            if free.size < need.size:
                self._grow(max(need.size - free.size, 16))
                pl = self._probe_lane
                free = np.flatnonzero(pl < 0)
            got = free[: need.size]
            pl[got] = need
            lp[need] = got
        if not (near.any() or gone.size):
            return False
        mine = np.flatnonzero(pl >= 0)
        rows = self._probe_row[mine]
        self._io[rows, 0] = self._gx[pl[mine]]
        self._io[rows, 1] = self._gy[pl[mine]]
        return True

    def _pymunk_contacts(self, dt: float, kernels: ModuleType | None = None) -> None:
        """pymunk's contact test of the probes where :meth:`_lend_probes` put them: ``self._contacts``
        (its arbiters read by numpy, or by ``kernels``: :func:`.kernels.contact_codes`)."""
        self._wbuf.set_float_buf(self._io.reshape(-1))
        pb.set_space_bodies(self.space, pb.BodyFields.POSITION, self._wbuf)
        self.space.step(dt)  # the probes stand still (velocity zero): pymunk only tests contacts
        # pymunk's arbiters after a step (collision_persistence 1) are the pairs touching in it: read
        # them in one call (no Python callback per contact) as (probe body, side body) ids.  A contact
        # *begins* where the lane did not touch that shape at the previous step: pymunk's "begin",
        # per (robot, shape) pair, as with one body per lane.
        self._abuf.clear()
        pb.get_space_arbiters(self.space, pb.ArbiterFields.BODY_A_ID | pb.ArbiterFields.BODY_B_ID, self._abuf)
        pairs = np.frombuffer(self._abuf.int_buf(), dtype=np.uintp).reshape(-1, 2)
        if pairs.size == 0:
            self._touching = set()
            return
        if kernels is None:
            codes = self._contact_codes(pairs)
        else:
            codes = np.empty(len(pairs), dtype=np.int64)
            kernels.contact_codes(pairs, self._probe_ids, self._probe_of_id, self._side_order_ids,
                                  self._side_of_sorted, self._probe_lane, codes)
        touching = set(codes.tolist())  # lane * 5 + side, a few
        began = touching - self._touching
        self._touching = touching
        self._contacts = {_WALL: [c // 5 for c in began if c % 5 != _DOCK_SIDE],
                          _DOCK: [c // 5 for c in began if c % 5 == _DOCK_SIDE]}

    def _contact_codes(self, pairs: np.ndarray) -> np.ndarray:
        """lane * 5 + side of each (probe body, side body) pair of ids, in either order."""
        a, b = pairs[:, 0], pairs[:, 1]  # pymunk puts the circle (probe) first; checked, not assumed
        last = len(self._probe_ids) - 1
        i = np.minimum(np.searchsorted(self._probe_ids, a), last)
        swap = self._probe_ids[i] != a
        if swap.any():
            a, b = np.where(swap, b, a), np.where(swap, a, b)
            i = np.minimum(np.searchsorted(self._probe_ids, a), last)
        side = self._side_of_sorted[np.searchsorted(self._side_order_ids, b)]
        return self._probe_lane[self._probe_of_id[i]] * 5 + side

    def _docking_accepted(self, lanes: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Contact with the dock docks only on its front face, head-on within the angle, slowly enough."""
        c = self.cfg
        x, y = self.rx[lanes], self.ry[lanes]
        on_front = (y >= c.dock_depth) & (x >= self.dock_x0) & (x <= self.dock_x1)
        head_on = np.abs(signed_deg(np.degrees(self.rh[lanes]) - DOCK_HEADING)) <= c.dock_max_angle
        slow = (speed > 0) & (speed <= c.dock_max_speed)
        return on_front & head_on & slow

    def _target_walk(self, a: slice | np.ndarray, noise: np.ndarray, th: np.ndarray, sin: np.ndarray,
                     cos: np.ndarray) -> None:
        """Move the Targets of the active lanes ``a`` (a slice when all are): a random walk that turns away from walls
        and the dock.  ``noise``: their heading noise (deg); ``th``: their noisy headings, ``sin``, ``cos`` its sine
        and cosine (changed here where a Target turns away).  The other lanes keep their Target."""
        c = self.cfg
        tx, ty = self.tx[a], self.ty[a]
        ahead_x = tx + c.target_avoid * cos
        ahead_y = ty + c.target_avoid * sin
        lo = c.target_radius + 2.0
        hi = c.arena - lo
        near_dock = (ahead_y < c.dock_depth + lo + c.target_avoid / 2) & (np.abs(ahead_x - c.arena / 2) < c.dock_width)
        blocked = (ahead_x < lo) | (ahead_x > hi) | (ahead_y < lo) | (ahead_y > hi) | near_dock
        if blocked.any():
            k = np.flatnonzero(blocked)
            th[k] = _signed_rad(exactmath.atan2(self._centre[1] - ty[k], self._centre[0] - tx[k]) + np.radians(noise[k]))
            sin[k], cos[k] = exactmath.sincos(th[k])
        step = c.target_speed * c.step_seconds
        self.tx[a] = tx + step * cos
        self.ty[a] = ty + step * sin
        self.th[a] = th


_REACH_MARGIN = 1.0  # inches: the bounding-box reach test is this much generous (rounding is ~1e-12)
_WALL_DIR = np.array([180.0, 0.0, -90.0, 90.0, 0.0])  # west, east, south, north walls; dock filled in


# ----------------------------------------------------------------- compiled loops
# BatchWorld's sensing and stepping, and the agent loop's steps (runner.py), have compiled versions in
# kernels.py (numba): the same floating-point operations in the same order (see that module).  tests/test_exact_curves.py checks both paths against numbers recorded before the
# compiled ones existed.

_SENSOR_CODE = {name: i for i, name in enumerate(SENSOR_NAMES)}
COMPILED_MIN_LANES = 256  # numba is loaded (~0.35 s, ~90 MB) for a batch of at least this many lanes (a GA's
# population at the report's size: 50 x 9 = 450 lanes for Tracking and the Executive; 8 Tracking generations
# 2.87 -> 1.95 CPU s once it is, docs/performance.md; the small batches of tests and coevo show stay numpy) ...
COMPILED_WARM_MIN_LANES = 1  # ... and once loaded, for any batch (a compiled step's fixed cost is ~1/4 of numpy's)
_loaded: dict[str, ModuleType | None] = {}  # "kernels": the compiled loops once a batch wanted them (None: no numba)
_NO_LANES = np.zeros(0, dtype=np.int64)
_TABLES: dict[str, tuple[np.ndarray, ...]] = {}


def sensor_tables(sch: Schema) -> tuple[np.ndarray, ...]:
    """A schema's sensors as the kernels' arrays: code, 1 / width (as Sensor.discretise computes it), bins,
    circular, origin."""
    t = _TABLES.get(sch.behaviour)
    if t is None or len(t[0]) != sch.n_sensors:
        t = _TABLES[sch.behaviour] = (
            np.array([_SENSOR_CODE[s.name] for s in sch.sensors], dtype=np.int64),
            np.array([1.0 / s.width for s in sch.sensors], dtype=np.float64),
            np.array([s.bins for s in sch.sensors], dtype=np.int64),
            np.array([s.circular for s in sch.sensors], dtype=np.bool_),
            np.array([s.origin for s in sch.sensors], dtype=np.float64),
        )
    return t


def _worth_compiling(lanes: int) -> bool:
    """Compiled loops for a batch of ``lanes``: a big one, or any once numba is loaded."""
    return lanes >= COMPILED_MIN_LANES or (bool(_loaded) and lanes >= COMPILED_WARM_MIN_LANES)


def _kernels() -> ModuleType | None:
    """The compiled loops (:mod:`.kernels`, importing numba on first use), or None without numba (then numpy)."""
    if "kernels" not in _loaded:
        kernels: ModuleType | None
        try:
            from coevo.tasks.fuel import kernels
        except ImportError:  # pragma: no cover - numba is a dependency; a stripped install still works
            kernels = None
        _loaded["kernels"] = kernels
    return _loaded["kernels"]


def compiled_loops(lanes: int) -> ModuleType | None:
    """The compiled loops if a batch of ``lanes`` should use them (see ``COMPILED_MIN_LANES``), else None."""
    return _kernels() if _worth_compiling(lanes) else None


def _sense_kernel():
    """The compiled sensing (and deciding) of run_lanes' steps, or None without numba (then numpy's observe +
    discretise)."""
    kernels = _kernels()
    return None if kernels is None else kernels.decide_lanes


def _as_lanes(lanes: list[int]) -> np.ndarray:
    return np.array(lanes, dtype=np.int64) if lanes else _NO_LANES
