"""A picture of recorded episodes that any task can make: static geometry, tracks on one frame axis, events.

A task turns its recording into a :class:`Scene` (e.g. :mod:`coevo.tasks.fuel.pictures.scene`);
:mod:`coevo.scene.draw` renders any scene as a PNG or an animation without knowing the
task.  Frames are the scene's clock: every track has one row per frame (NaN where
its body is absent, e.g. between episodes), and events, rings, spans and the rule
trace refer to frames.  ``category`` is what a path is coloured by (for the tracking
task: the Executive's choice, Track or Dock).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Shape", "Track", "Ring", "Event", "Span", "Scene", "EVENT_KINDS", "SHAPE_ROLES"]

# Event kinds the renderer has a marker for: the endings the tasks so far name (the fuel task's: tracking,
# docked, collided, ran dry, time up; the door task's: reached goal, ran out of time).  The renderer knows no task,
# but this vocabulary is theirs: a new task with new endings adds its kinds here (another kind gets a plain marker).
EVENT_KINDS = ("start", "tracking", "docked", "collided", "ran dry", "time up", "reached goal", "ran out of time")
# Roles of static shapes the renderer has a style for ("wall": an outline; "goal": a dashed green line;
# "mark": a dotted grey line; "beam"/"failed beam": a sensor's beam, working or failed; anything else: a filled block).
SHAPE_ROLES = ("wall", "goal", "mark", "beam", "failed beam")


@dataclass(frozen=True)
class Shape:
    """Static geometry: a closed ``polygon`` or open ``polyline`` of ``points`` (n, 2); ``role`` picks its style."""

    kind: str
    points: np.ndarray
    role: str
    label: str | None = None
    alpha: float = 1.0  # paler for what belongs to an older span; with ``category``, its fill's opacity
    category: int | None = None  # a block that belongs to a category (e.g. one trial's wall): drawn in its colour


@dataclass(frozen=True)
class Track:
    """A moving body: its position (and heading, radians) per frame, and the category of each frame."""

    name: str
    xy: np.ndarray  # (F, 2)
    heading: np.ndarray | None  # (F,) or None
    category: np.ndarray | None  # (F,) index into Scene.categories, -1 none; None: not coloured by category
    radius: float


@dataclass(frozen=True)
class Ring:
    """An annulus around a body at one frame (e.g. the tracking range around the Target).

    ``around`` names the track it belongs to: animations move it with that track.
    """

    frame: int
    x: float
    y: float
    inner: float
    outer: float
    around: str = ""


@dataclass(frozen=True)
class Event:
    """Something that happened at a frame and place: a start or an ending (kind in EVENT_KINDS)."""

    frame: int
    x: float
    y: float
    kind: str
    label: str = ""


@dataclass(frozen=True)
class Span:
    """A stretch of frames (an episode): its category and a one-line summary."""

    first: int
    last: int
    category: int
    summary: str


@dataclass(frozen=True)
class Scene:
    title: str
    extent: tuple[float, float, float, float]  # x0, x1, y0, y1
    statics: tuple[Shape, ...]
    categories: tuple[str, ...]
    tracks: tuple[Track, ...]  # the first is the protagonist (the robot)
    rings: tuple[Ring, ...]
    events: tuple[Event, ...]
    spans: tuple[Span, ...]
    captions: tuple[str, ...]  # one per frame, shown by animations
    rule: np.ndarray | None = None  # (F,) rule number that fired at each frame (1-based, 0 none), for a trace panel
    rule_label: str = "rule"
    colours: tuple[str, ...] = ()  # the categories' colours (matplotlib names), if the task chooses them

    @property
    def frames(self) -> int:
        return len(self.captions)
