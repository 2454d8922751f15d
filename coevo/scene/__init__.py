"""Task-agnostic pictures: a :class:`Scene` (static geometry, tracks on one frame axis, events) and its
rendering to PNG, GIF or MP4 (:mod:`coevo.scene.draw`).

A task turns its recorded episodes into a Scene (the task's own ``pictures``); ``coevo show``
and the run tools render it without knowing the task.  This package imports only numpy,
coevo.errors and, inside the drawing functions, matplotlib, so that it sits below the tasks.
"""

from __future__ import annotations

from coevo.scene.draw import ANIMATION_FORMATS, FORMATS, animate, check_out_path, draw_png
from coevo.scene.scene import EVENT_KINDS, SHAPE_ROLES, Event, Ring, Scene, Shape, Span, Track

__all__ = ["Scene", "Shape", "Track", "Ring", "Event", "Span", "EVENT_KINDS", "SHAPE_ROLES", "draw_png", "animate",
           "check_out_path", "FORMATS", "ANIMATION_FORMATS"]
