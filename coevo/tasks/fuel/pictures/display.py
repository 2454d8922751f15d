"""The fuel task's pictures as its :class:`~coevo.tasks.showing.TaskDisplay`: ``FuelTask.display()``.

A robot is Tracking, Docking or the three together (:mod:`.robot`), played with the runner's
recorder (:mod:`.play`), drawn as a :class:`~coevo.scene.Scene` (:mod:`.scene`) and listed by
:mod:`.rules_view`.  A Tracking or Docking policy alone plays a few episodes with the trivial
Executive that always picks it; a combined robot plays one epoch.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from coevo.ga.evaluator import Partners
from coevo.policy.rules import RuleSet
from coevo.scene import Scene, draw_png
from coevo.tasks.fuel.pictures.play import Played, play
from coevo.tasks.fuel.pictures.robot import Robot, robot_from_rules
from coevo.tasks.fuel.pictures.rules_view import rule_tables, trace_lines
from coevo.tasks.fuel.pictures.scene import scene_for
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.showing import RuleTable, TaskDisplay

__all__ = ["FuelDisplay", "PICTURE_EPISODES"]

PICTURE_EPISODES = 3  # Tracking or Docking alone in a learned policy's picture; an Executive's is one epoch


class FuelDisplay(TaskDisplay[WorldConfig]):
    """The fuel task's robots, plays and pictures (:mod:`coevo.tasks.fuel.pictures`)."""

    def picture(self, path: Path, behaviour: str, best: RuleSet, *, world: WorldConfig, partners: Partners,
                seed: int, name: str) -> None:
        """best.png: the best policy playing a few episodes (or, for the Executive, one epoch); ~0.5 s."""
        robot = robot_from_rules(name, world, {**partners, behaviour: best})
        played = play(robot, seed=seed, episodes=self.show_episodes(robot))
        draw_png(scene_for(played, title=f"{name}: the best {behaviour} policy, seed {seed}"), path)

    def show_robot(self, name: str, world: WorldConfig, rules: Mapping[str, RuleSet]) -> Robot:
        return robot_from_rules(name, world, rules)

    def show_episodes(self, robot: Robot) -> int | None:
        """One epoch for a combined robot; a few episodes for Tracking or Docking alone."""
        return None if robot.combined else PICTURE_EPISODES

    def show_play(self, robot: Robot, *, seed: int, episodes: int | None) -> Played:
        return play(robot, seed=seed, episodes=episodes)

    def show_scene(self, played: Played, *, title: str | None = None) -> Scene:
        return scene_for(played, title=title)

    def show_rules(self, played: Played) -> list[RuleTable]:
        return rule_tables(played)

    def show_trace(self, played: Played) -> list[str]:
        return trace_lines(played)

    def show_score(self, played: Played) -> tuple[str, float] | None:
        """A combined robot's epoch: its Executive payoff; Tracking or Docking alone: none."""
        payoff = played.outcome.epoch_payoff
        return ("Executive payoff", float(payoff[0])) if played.epoch and played.robot.combined and payoff.size else None
