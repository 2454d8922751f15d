"""The tracking-under-fuel task as a :class:`~coevo.scene.Scene`.

The arena's walls and the dock are the static geometry; the robot and the Target are
tracks, the robot's coloured by the Executive's choice for each episode; the
tracking range (``tracking_min``–``tracking_max`` around the Target) is drawn at
each episode's start, up to :data:`MAX_RINGS` of them; every episode has a start
event and an ending: *collided*, *docked*, *ran dry*, or when its time ran out,
*tracking* (in range at the end) or *time up*.
"""

from __future__ import annotations

import numpy as np

from coevo.scene.scene import Event, Ring, Scene, Shape, Span, Track
from coevo.tasks.fuel.pictures.play import Played
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK

__all__ = ["scene_of", "scene_for", "episode_endings", "CATEGORIES"]

CATEGORIES = tuple(name for _, name in sorted({TASK_TRACK: "Track", TASK_DOCK: "Dock"}.items()))  # index = task value
MAX_RINGS = 6


def episode_endings(played: Played) -> list[str]:
    """How each played episode of lane 0 ended (an EVENT_KINDS name)."""
    out, rec, cfg = played.outcome, played.record, played.robot.world
    ends = []
    for k in range(played.episodes):
        if out.collided[0, k]:
            ends.append("collided")
        elif out.docked[0, k]:
            ends.append("docked")
        elif out.dry[0, k]:
            ends.append("ran dry")
        else:
            s = int(out.steps[0, k])
            d = float(np.hypot(rec.rx[k, s, 0] - rec.tx[k, s, 0], rec.ry[k, s, 0] - rec.ty[k, s, 0]))
            ends.append("tracking" if cfg.tracking_min <= d <= cfg.tracking_max else "time up")
    return ends


def _statics(played: Played) -> tuple[Shape, ...]:
    c = played.robot.world
    A = c.arena
    walls = Shape("polygon", np.array([[0, 0], [A, 0], [A, A], [0, A]], float), "wall")
    x0, x1 = A / 2 - c.dock_width / 2, A / 2 + c.dock_width / 2
    dock = Shape("polygon", np.array([[x0, 0], [x1, 0], [x1, c.dock_depth], [x0, c.dock_depth]], float), "dock", "dock")
    return walls, dock


def _rule_letter(task: int) -> str:
    return "T" if task == TASK_TRACK else "D"


def scene_of(played: Played, *, title: str | None = None) -> Scene:
    """The scene of lane 0 of a recorded play."""
    rec, out, cfg = played.record, played.outcome, played.robot.world
    K = played.episodes
    endings = episode_endings(played)
    rows: list[tuple[int, int]] = []  # (episode, step) per frame
    for k in range(K):
        rows += [(k, t) for t in range(int(out.steps[0, k]) + 1)]
    ks = np.array([r[0] for r in rows])
    ts = np.array([r[1] for r in rows])
    task = rec.task[ks, 0].astype(np.int64)
    robot_xy = np.column_stack([rec.rx[ks, ts, 0], rec.ry[ks, ts, 0]])
    target_xy = np.column_stack([rec.tx[ks, ts, 0], rec.ty[ks, ts, 0]])
    steps_per_ep = out.steps[0, :K].astype(np.int64)
    fired = np.full(len(rows), -1, np.int64)
    moving = ts < steps_per_ep[ks]  # the last frame of an episode is its end state: no rule fires there
    fired[moving] = rec.rule[ks[moving], ts[moving], 0]
    rule = np.where(fired >= 0, fired + 1, 0)

    spans, events, rings = [], [], []
    first = 0
    ring_eps = set(np.linspace(0, K - 1, min(K, MAX_RINGS)).round().astype(int).tolist()) if K else set()
    epoch_starts = {0} | {k for k in range(1, K) if out.epoch_of[0, k] != out.epoch_of[0, k - 1]}
    for k in range(K):
        last = first + int(steps_per_ep[k])
        name = CATEGORIES[int(rec.task[k, 0])]
        in_range = int(out.tracked[0, k])
        ex_rule = int(rec.executive_rule[k, 0])
        picked = f" (E{ex_rule + 1})" if ex_rule >= 0 else ""
        spans.append(Span(first, last, int(rec.task[k, 0]),
                          f"{k + 1:>2}. {name}{picked}: {int(steps_per_ep[k])} steps, {in_range} in range, "
                          f"{endings[k]}"))
        x, y = robot_xy[first]
        events.append(Event(first, float(x), float(y), "start", str(k + 1) + ("*" if k in epoch_starts else "")))
        x, y = robot_xy[last]
        events.append(Event(last, float(x), float(y), endings[k], str(k + 1)))
        if k in ring_eps:
            tx, ty = target_xy[first]
            rings.append(Ring(first, float(tx), float(ty), cfg.tracking_min, cfg.tracking_max, around="Target"))
        first = last + 1

    fuel = rec.fuel[ks, ts, 0]
    captions = tuple(
        f"episode {k + 1} ({CATEGORIES[task[i]]}) step {t}"
        + (f" rule {_rule_letter(task[i])}{rule[i]}" if rule[i] else "")
        + f"  fuel {100 * max(fuel[i], 0.0):.0f}%"
        for i, (k, t) in enumerate(rows)
    )
    what = "one epoch" if played.epoch else f"{K} episodes"
    payoff = out.epoch_payoff[out.epoch_complete]
    pay = f", executive payoff {payoff.mean():.2f}" if payoff.size and played.robot.combined else ""
    return Scene(
        title=title or f"{played.robot.name}: {what}, seed {played.seed}{pay}",
        extent=(0.0, cfg.arena, 0.0, cfg.arena),
        statics=_statics(played),
        categories=CATEGORIES,
        tracks=(Track("robot", robot_xy, rec.rh[ks, ts, 0], task, cfg.robot_radius),
                Track("Target", target_xy, None, None, cfg.target_radius)),
        rings=tuple(rings), events=tuple(events), spans=tuple(spans), captions=captions,
        rule=rule, rule_label="rule fired (T: Tracking, D: Docking)",
    )



scene_for = scene_of
