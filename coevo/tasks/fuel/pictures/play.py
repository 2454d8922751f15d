"""Play a robot for a few recorded episodes or one epoch, in a single arena.

``episodes=N`` plays N episodes in a row; when an epoch ends early (a collision,
an empty tank, or the epoch's last episode) a new one starts, so all N are played.
``episodes=None`` plays exactly one epoch, as the report's measures do.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coevo.errors import ConfigError
from coevo.tasks.fuel.pictures.robot import Robot
from coevo.tasks.fuel.recorder import Recorder
from coevo.tasks.fuel.robot import controllers
from coevo.tasks.fuel.runner import Outcome, run_lanes
from coevo.tasks.fuel.world import BatchWorld

__all__ = ["Played", "play"]


@dataclass(frozen=True)
class Played:
    """A robot's recorded episodes (lane 0 of ``outcome`` and ``record``)."""

    robot: Robot
    seed: int
    epoch: bool
    outcome: Outcome
    record: Recorder

    @property
    def episodes(self) -> int:
        return int(self.outcome.played[0].sum())


def play(robot: Robot, *, seed: int, episodes: int | None = None) -> Played:
    """Play ``robot`` from ``seed``: ``episodes`` in a row, or one epoch when None."""
    if episodes is not None and episodes < 1:
        raise ConfigError(f"--episodes must be positive, got {episodes}")
    executive, tracking, docking = controllers(robot.executive, robot.tracking, robot.docking, 1)
    rec = Recorder()
    out = run_lanes(
        BatchWorld(robot.world, 1), lane_episodes=episodes or robot.world.epoch_episodes, executive=executive,
        tracking=tracking, docking=docking, restart_epochs=episodes is not None,
        rng=np.random.default_rng(seed), record=rec,
    )
    return Played(robot=robot, seed=seed, epoch=episodes is None, outcome=out, record=rec)
