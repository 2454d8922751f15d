"""The pursuit world's settings: a square arena, two bodies, a capture radius and a time limit."""

from __future__ import annotations

from pydantic import Field

from coevo.config import Settings

__all__ = ["PursuitConfig"]


class PursuitConfig(Settings):
    """Lengths in arena units, speeds in units a step.  The defaults make a game neither side wins always: the
    hand-written pursuer catches the hand-written evader in some episodes and not in others (README: "the game")."""

    arena: float = Field(20.0, gt=0, le=1000, description="side of the square arena")
    steps: int = Field(60, ge=1, le=10_000, description="steps an episode lasts at most")
    capture: float = Field(1.0, gt=0, le=1000, description="the pursuer captures the evader within this distance")
    pursuer_speed: float = Field(1.0, gt=0, le=1000, description="the pursuer's speed (units a step)")
    evader_speed: float = Field(0.85, gt=0, le=1000, description="the evader's speed (units a step)")
    min_start: float = Field(6.0, ge=0, le=1000, description="the least distance between the two at the start")
