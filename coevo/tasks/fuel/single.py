"""A plain one-episode-at-a-time world: the baseline ``coevo bench`` compares against.

The same task as :class:`~coevo.tasks.fuel.world.BatchWorld` written the straightforward
way: one pymunk space per episode, Python floats, one pymunk step and one rule
lookup per robot step.  It is kept deliberately plain; it is not used for learning.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from coevo.policy.rules import RuleSet
from coevo.policy.schema import schema
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["run_episode"]

_TURN = schema(Behaviour.TRACKING).actions[0].values
_SPEED = schema(Behaviour.TRACKING).actions[1].values


def _choose(rs: RuleSet, bins: np.ndarray) -> int:
    """Strongest fully matching rule, else the best partial match."""
    b = bins[None, :]
    ok = np.where(rs.lo <= rs.hi, (b >= rs.lo) & (b <= rs.hi), (b >= rs.lo) | (b <= rs.hi))
    count = ok.sum(axis=1)
    best = count == count.max()
    cand = np.flatnonzero(best)
    return int(cand[np.argmax(rs.strength[cand])])


def run_episode(cfg: WorldConfig, policy: RuleSet, rng: np.random.Generator) -> int:
    """One Tracking or Docking episode from a random start; returns the robot-steps simulated."""
    A = cfg.arena
    space = pymunk.Space()
    hits: list[int] = []
    for a, b in (((0, 0), (A, 0)), ((A, 0), (A, A)), ((A, A), (0, A)), ((0, A), (0, 0))):
        seg = pymunk.Segment(space.static_body, a, b, 0.0)
        seg.sensor, seg.collision_type = True, 2
        space.add(seg)
    x0, x1 = A / 2 - cfg.dock_width / 2, A / 2 + cfg.dock_width / 2
    dock = pymunk.Poly(space.static_body, [(x0, 0), (x1, 0), (x1, cfg.dock_depth), (x0, cfg.dock_depth)])
    dock.sensor, dock.collision_type = True, 3
    space.add(dock)
    body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    lo = cfg.spawn_margin + cfg.robot_radius
    body.position = (float(rng.uniform(lo, A - lo)), float(rng.uniform(lo + 40, A - lo)))
    body.angle = float(rng.uniform(-math.pi, math.pi))
    shape = pymunk.Circle(body, cfg.robot_radius)
    shape.sensor, shape.collision_type = True, 1
    space.add(body, shape)
    space.on_collision(1, 2, begin=lambda arb, s, d: hits.append(2))
    space.on_collision(1, 3, begin=lambda arb, s, d: hits.append(3))
    tx, ty = float(rng.uniform(lo, A - lo)), float(rng.uniform(lo, A - lo))
    th = float(rng.uniform(-math.pi, math.pi))
    fuel = cfg.initial_fuel
    sch = policy.schema
    docking = policy.behaviour == Behaviour.DOCKING
    steps = 0
    for _ in range(cfg.episode_steps):
        x, y = body.position
        h = math.degrees(body.angle)
        dx, dy = tx - x, ty - y
        t_dist = math.hypot(dx, dy)
        t_dir = math.degrees(math.atan2(dy, dx))
        gaps = [x, A - x, y, A - y, t_dist - cfg.target_radius]
        which = min(range(5), key=gaps.__getitem__)
        near = max(gaps[which] - cfg.robot_radius, 0.0)
        obj_dir = (180.0, 0.0, -90.0, 90.0, t_dir)[which]
        raw = {
            "range": near, "bearing": (obj_dir - h) % 360, "heading": (math.degrees(th) - t_dir) % 360,
            "target_range": t_dist, "target_bearing": (t_dir - h) % 360,
        }
        if docking:
            ddx, ddy = A / 2 - x, cfg.dock_depth - y
            raw["dock_range"] = math.hypot(ddx, ddy)
            raw["dock_bearing"] = (math.degrees(math.atan2(ddy, ddx)) - h) % 360
            raw["dock_orientation"] = (h + 90.0) % 360
            raw["dock_axis"] = y - cfg.dock_depth - cfg.robot_radius
            raw["dock_offset"] = x - A / 2
        bins = np.array([s.discretise(np.array([raw[s.name]]))[0] for s in sch.sensors])
        r = _choose(policy, bins)
        turn, speed = _TURN[policy.action[r, 0]], _SPEED[policy.action[r, 1]]
        body.velocity = (speed * math.cos(body.angle), speed * math.sin(body.angle))
        body.angular_velocity = math.radians(turn)
        th += math.radians(float(rng.normal(0.0, cfg.target_turn_sd)))
        ax, ay = tx + cfg.target_avoid * math.cos(th), ty + cfg.target_avoid * math.sin(th)
        if not (lo < ax < A - lo and lo < ay < A - lo):
            th = math.atan2(A / 2 - ty, A / 2 - tx)
        tx += cfg.target_speed * cfg.step_seconds * math.cos(th)
        ty += cfg.target_speed * cfg.step_seconds * math.sin(th)
        space.step(cfg.step_seconds)
        steps += 1
        fuel -= cfg.fuel_idle + cfg.fuel_per_ips * abs(speed) + cfg.fuel_per_dps * abs(turn)
        if hits or fuel <= 0 or math.hypot(tx - body.position.x, ty - body.position.y) < cfg.robot_radius + cfg.target_radius:
            break
    return steps
