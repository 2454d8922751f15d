"""See what was learned: recorded episodes of a robot as pictures, animations and rule tables.

``coevo show`` (:mod:`coevo.show.command`) resolves what to show (:mod:`.source`),
plays it with the runner's recorder (:mod:`.play`), turns the recording into a
task-agnostic :class:`~coevo.show.scene.Scene` (:mod:`.tracking_fuel`, the only task
so far) and renders it (:mod:`.draw`); :mod:`.rules_view` prints the rule sets.
"""

from __future__ import annotations

from pathlib import Path

from coevo.errors import ConfigError
from coevo.show.draw import animate, draw_png
from coevo.show.play import Played, play
from coevo.show.scene import Scene
from coevo.show.source import Robot, robot_from_default, robot_from_path, robot_from_rules
from coevo.show.tracking_fuel import TASK, scene_of

__all__ = ["TASKS", "Robot", "Played", "Scene", "play", "picture", "scene_for", "robot_from_path",
           "robot_from_default", "robot_from_rules", "draw_png", "animate"]

TASKS = {TASK: scene_of}  # task name -> recording-to-scene function; a second task adds its entry here


def scene_for(played: Played, task: str = TASK, *, title: str | None = None) -> Scene:
    if task not in TASKS:
        raise ConfigError(f"--task {task!r}: unknown task (known: {', '.join(TASKS)})")
    return TASKS[task](played, title=title)


def picture(robot: Robot, path: Path, *, seed: int, episodes: int | None = None, trace: bool = False,
            title: str | None = None) -> Played:
    """Play ``robot`` (``episodes`` in a row, or one epoch) and write its PNG to ``path``."""
    played = play(robot, seed=seed, episodes=episodes)
    draw_png(scene_for(played, title=title), path, trace=trace)
    return played
