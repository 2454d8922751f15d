"""The report's measures of a run (Appendix A §6.3), computed from an :class:`Outcome`."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK
from coevo.tasks.fuel.runner import Outcome

__all__ = ["Measures", "measure", "QUALITY_FRACTION"]

QUALITY_FRACTION = 0.8  # an episode is "quality tracking" with >= 80 % of its steps in range


@dataclass(frozen=True)
class Measures:
    episodes: int
    epochs: int
    quality_tracking: float  # % of episodes in tracking range for >= 80 % of the steps
    successful_docking: float  # % of episodes where the Executive picked Docking and the robot docked
    dock_choice: float  # % of episodes where the Executive picked Docking
    docking_success_rate: float  # % of Docking episodes that docked
    average_epoch_length: float  # episodes per complete epoch
    tracking_payoff: float  # mean Tracking payoff over its episodes
    docking_payoff: float  # mean Docking payoff over its episodes
    executive_payoff: float  # mean Executive payoff over complete epochs
    collision_rate: float  # % of episodes ending in a collision
    dry_rate: float  # % of episodes ending out of fuel

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def _pct(num: np.ndarray | int, den: int) -> float:
    return float(100.0 * np.sum(num) / den) if den else 0.0


def _mean(x: np.ndarray) -> float:
    return float(np.mean(x)) if x.size else 0.0


def measure(out: Outcome, episode_steps: int) -> Measures:
    p = out.played
    n = int(p.sum())
    track_ep = p & (out.task == TASK_TRACK)
    dock_ep = p & (out.task == TASK_DOCK)
    quality = p & (out.tracked >= QUALITY_FRACTION * episode_steps)
    complete = out.epoch_complete
    return Measures(
        episodes=n,
        epochs=int(complete.sum()),
        quality_tracking=_pct(quality, n),
        successful_docking=_pct(dock_ep & out.docked, n),
        dock_choice=_pct(dock_ep, n),
        docking_success_rate=_pct(dock_ep & out.docked, int(dock_ep.sum())),
        average_epoch_length=_mean(out.epoch_episodes[complete]),
        tracking_payoff=_mean(out.payoff[track_ep]),
        docking_payoff=_mean(out.payoff[dock_ep]),
        executive_payoff=_mean(out.epoch_payoff[complete]),
        collision_rate=_pct(p & out.collided, n),
        dry_rate=_pct(p & out.dry, n),
    )
