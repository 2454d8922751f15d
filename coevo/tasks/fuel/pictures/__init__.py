"""The fuel task's pictures: a robot (:mod:`.robot`) played with the runner's recorder (:mod:`.play`),
its recording as a :class:`~coevo.scene.Scene` (:mod:`.scene`) and its rule tables (:mod:`.rules_view`).

``coevo show``, ``coevo learn``'s best.png and the dashboard reach these through the task's display,
:class:`.display.FuelDisplay` (``FuelTask.display()``); ``coevo compare``'s robot pictures through
:func:`picture`.  matplotlib is imported only when a picture is drawn.
"""

from __future__ import annotations

from pathlib import Path

from coevo.scene import draw_png
from coevo.tasks.fuel.pictures.display import FuelDisplay
from coevo.tasks.fuel.pictures.play import Played, play
from coevo.tasks.fuel.pictures.robot import Robot, robot_from_rules
from coevo.tasks.fuel.pictures.scene import episode_endings, scene_for

__all__ = ["FuelDisplay", "Robot", "Played", "play", "picture", "scene_for", "robot_from_rules", "episode_endings"]


def picture(robot: Robot, path: Path, *, seed: int, episodes: int | None = None, trace: bool = False,
            title: str | None = None) -> Played:
    """Play ``robot`` (``episodes`` in a row, or one epoch) and write its PNG to ``path``."""
    played = play(robot, seed=seed, episodes=episodes)
    draw_png(scene_for(played, title=title), path, trace=trace)
    return played
