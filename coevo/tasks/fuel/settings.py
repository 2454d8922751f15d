"""The tracking-under-fuel world's settings (report Appendix A §4, §6; docs/spec.md §1).

Every number the report gives is a default here; every choice the report leaves
open is marked *(ours)* in its description and can be overridden.

The world a behaviour learns in is more than its physics: what Docking may sense and where its
training episodes start are settings of this world too (the last three fields), as an environment's
observation and reset choices are its own keyword arguments in Gymnasium's registration.  They were
GA settings (:class:`~coevo.config.GAConfig`) in runs saved before November 2026; such a run reads them from there
(:func:`coevo.tasks.saved_settings`) and ``--ga docking_sensors=...`` still sets them
(:func:`coevo.tasks.split_settings`).
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field, model_validator

from coevo.config import Settings

__all__ = ["WorldConfig"]


class WorldConfig(Settings):
    """The tracking-under-fuel task (report Appendix A §4, §6)."""

    physical: ClassVar[bool] = True

    arena: float = Field(300.0, gt=50, description="side of the square arena, inches")
    step_seconds: float = Field(0.5, gt=0, description="simulated time per step, s")
    episode_steps: int = Field(60, ge=1, le=10_000, description="max steps per episode")
    epoch_episodes: int = Field(10, ge=1, le=1_000, description="max episodes per epoch")
    tracking_min: float = Field(40.0, ge=0, description="tracking range lower bound, inches")
    tracking_max: float = Field(60.0, gt=0, description="tracking range upper bound, inches")
    towing_penalty: int = Field(50, ge=0, description="steps added to the epoch denominator on running dry")
    initial_fuel: float = Field(0.5, gt=0, le=1, description="tank fraction at each epoch start")
    robot_radius: float = Field(9.0, gt=0, description="(ours) robot radius, inches (a Nomad 200 is ~18 in wide)")
    target_radius: float = Field(9.0, gt=0, description="(ours) target radius, inches")
    target_speed: float = Field(2.0, ge=0, le=16, description="(ours) target random-walk speed, ips")
    target_turn_sd: float = Field(20.0, ge=0, description="(ours) s.d. of the target's heading change per step, deg")
    target_avoid: float = Field(30.0, ge=0, description="(ours) distance at which the target turns away from walls/dock, inches")
    fuel_idle: float = Field(
        1 / 960, gt=0,
        description="tank fraction used per step standing still; the report: 'if it were to remain motionless it "
        "could survive approximately eight episodes', read of the 50 % an epoch starts with (docs/spec.md §1, Fuel): "
        "0.5 / (1/960) = 480 steps = 8 episodes",
    )
    fuel_per_ips: float = Field(
        1 / 3840, ge=0,
        description="extra tank fraction per step per inch/s; the report: 'while it is moving slowly it can last up "
        "to four episodes', read of the starting 50 % at 4 ips: 0.5 / (1/960 + 4/3840) = 240 steps = 4 episodes",
    )
    fuel_per_dps: float = Field(
        1 / 23040, ge=0,
        description="(ours) extra tank fraction per step per deg/s of turn: the report says consumption grows "
        "linearly with the turning rate but gives no figure; a full-rate turn (24 deg/s) costs what driving at 4 ips does",
    )
    dock_width: float = Field(30.0, gt=0, description="(ours) width of the dock's front face, inches")
    dock_depth: float = Field(10.0, gt=0, description="(ours) depth of the dock from the south wall, inches")
    dock_max_speed: float = Field(4.0, ge=0, description="fastest accepted docking speed, ips")
    dock_max_angle: float = Field(15.0, ge=0, le=90, description="largest accepted angle off head-on, deg")
    spawn_margin: float = Field(20.0, ge=0, description="(ours) min clearance from walls/dock for random placements, inches")
    spawn_separation: float = Field(40.0, ge=0, description="(ours) min robot-target distance at epoch start, inches")
    hash_cell: float = Field(100.0, gt=0, description="(ours, speed only) pymunk spatial-hash cell size")
    # What Docking learns in (docs/docking-learning.md): the world its rules see and its training episodes start in.
    docking_fresh_starts: bool = Field(
        True,
        description="(ours) with the trivial always-Dock Executive (Independent, coevo learn), every Docking training "
        "episode starts from a fresh random placement, where an Executive would call Docking, instead of in front "
        "of the dock where the last docking left the robot (docs/design.md, 'Where Docking learns'; measured: 85 % of "
        "a Docking learner's fitness came from such re-docking episodes, and docking from random starts stayed at "
        "4-7 %)",
    )
    docking_sensors: Literal["polar", "dock-frame", "both"] = Field(
        "both", description="(ours) the dock sensors Docking's rules may condition on (coevo/tasks/fuel/dock_frame.py): "
        "'polar' dock_range, dock_bearing, dock_orientation; 'dock-frame' dock_axis, dock_offset (the robot's place "
        "in the dock's frame) and dock_orientation; 'both' all five.  Each starts from the direction-only default "
        "written in its own terms ('both' from the polar one).  Docking from random starts (docs/docking-learning.md, "
        "Round 3), median of seeds 0-9 with Docking's keep_evaluated and best_candidates: both 50.1 %, polar 43.5 %, "
        "dock-frame (0-4) 40.4 %; polar without them 45.0 % (the defaults before)"
    )
    docking_target_sensors: bool = Field(
        False, description="(ours) may Docking's rules condition on the Target's own sensors (heading, target_range, "
        "target_bearing)?  range and bearing to the nearest object, which may be the Target, stay either way.  "
        "Docking from random starts (docs/docking-learning.md, Round 7): development seeds 0-19, median 79.1 % without "
        "them against 71.1 % with them (paired +8.9 +- 2.2, 15 wins of 20); held-out seeds 1300-1319, run once after "
        "the choice, 79.7 % against 74.2 % (+8.8 +- 3.2, 14 wins of 20, one-sided Wilcoxon p = 0.008)"
    )

    #: A run saved before Round 7 (docs/docking-learning.md) has no docking_target_sensors: it learned with them.
    saved_before: ClassVar[dict[str, Any]] = {"docking_target_sensors": True}

    @model_validator(mode="after")
    def _check(self) -> WorldConfig:
        if self.tracking_min >= self.tracking_max:
            raise ValueError(f"tracking_min ({self.tracking_min}) must be below tracking_max ({self.tracking_max})")
        if self.dock_width >= self.arena / 2:
            raise ValueError(f"dock_width ({self.dock_width}) must be under half the arena ({self.arena})")
        if 2 * (self.spawn_margin + self.robot_radius) + self.spawn_separation >= self.arena:
            raise ValueError("spawn_margin/spawn_separation leave no room in the arena")
        return self
