"""The world: the tracking-under-fuel task, batched on numpy arrays and pymunk."""

from __future__ import annotations

from coevo.sim.measures import Measures, measure
from coevo.sim.recorder import Recorder
from coevo.sim.runner import ALWAYS_DOCK, ALWAYS_TRACK, Outcome, Rules, Trivial, run_lanes
from coevo.sim.world import BatchWorld

__all__ = ["BatchWorld", "run_lanes", "Rules", "Trivial", "ALWAYS_TRACK", "ALWAYS_DOCK", "Outcome", "Measures", "measure",
           "Recorder"]
