"""What happened at every step of a few lanes, for pictures and animations (``coevo show``).

:func:`~coevo.tasks.fuel.runner.run_lanes` fills a :class:`Recorder` when one is given:
per episode ``k``, step ``t`` and lane, the robot's position and heading and the
Target's position *before* step ``t`` (so ``t = 0`` is where the episode began and
``t = steps`` where it ended), the rule that fired for the controller in charge, and
per episode the Executive's task and rule.  Positions are NaN where a lane was not
playing.  The arrays are ``(K, T + 1, L)``: meant for a handful of lanes, not the
GA's thousands.  Recording only reads the world; it draws no random numbers, so a
recorded run has exactly the outcome of an unrecorded one with the same seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from coevo.tasks.fuel.world import BatchWorld

__all__ = ["Recorder", "NO_RULE"]

NO_RULE = -1  # no rule fired (the lane was not playing, or a Trivial Executive decided)


@dataclass
class Recorder:
    """Per-step state of every lane; filled by ``run_lanes(..., record=recorder)``."""

    rx: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    ry: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    rh: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # radians
    tx: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    ty: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    fuel: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # tank fraction
    rule: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0), np.int16))  # (K, T, L) rule of the task's policy
    task: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.int8))  # (K, L), -1 not played
    executive_rule: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.int16))  # (K, L)

    def open(self, lanes: int, episodes: int, steps: int) -> None:
        """Size the arrays for a run of ``lanes`` x ``episodes`` episodes of at most ``steps`` steps."""
        shape = (episodes, steps + 1, lanes)
        self.rx, self.ry, self.rh, self.tx, self.ty, self.fuel = (np.full(shape, np.nan) for _ in range(6))
        self.rule = np.full((episodes, steps, lanes), NO_RULE, np.int16)
        self.task = np.full((episodes, lanes), -1, np.int8)
        self.executive_rule = np.full((episodes, lanes), NO_RULE, np.int16)

    def state(self, world: BatchWorld, k: int, t: int, lanes: np.ndarray) -> None:
        """The world's state of ``lanes`` (indices or a bool mask) before step ``t`` of episode ``k``."""
        for dst, src in ((self.rx, world.rx), (self.ry, world.ry), (self.rh, world.rh),
                         (self.tx, world.tx), (self.ty, world.ty), (self.fuel, world.fuel)):
            dst[k, t, lanes] = src[lanes]

    def decision(self, k: int, lanes: np.ndarray, task: np.ndarray, rule: np.ndarray | None) -> None:
        """The Executive's choice for episode ``k`` (``rule`` None for a Trivial Executive)."""
        self.task[k, lanes] = task
        if rule is not None:
            self.executive_rule[k, lanes] = rule

    def fired(self, k: int, t: int, lanes: np.ndarray, rule: np.ndarray) -> None:
        """The rules the controllers in charge fired at step ``t`` of episode ``k``."""
        self.rule[k, t, lanes] = rule

    @property
    def episodes(self) -> int:
        return int(self.task.shape[0])

    @property
    def lanes(self) -> int:
        return int(self.task.shape[1]) if self.task.ndim == 2 else 0
