"""What one task's TD-against-GA comparison is: its settings (:class:`TDSpec`), its curves, its names."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from coevo.errors import ConfigError
from coevo.experiments.earl.qlearning import QConfig
from coevo.experiments.earl.td.encoders import ENCODERS

__all__ = ["TASKS", "REWARDS", "PRIORS", "VARIANTS", "Policy", "Progress", "no_progress", "TDSpec", "Curve", "default_checkpoints"]

TASKS = ("tracking", "docking", "door")
REWARDS = ("sparse", "shaped")
PRIORS = ("none", "default")
#: Extra TD runs beside the main one, by name: the settings each changes.
VARIANTS: dict[str, dict[str, Any]] = {"shaped": {"reward": "shaped"}, "default-rules": {"prior": "default"}}
#: A policy for measurement: (sensor bins (m, S), lane ids (m,), rng) -> joint action indices (m,).
Policy = Callable[[np.ndarray, np.ndarray, np.random.Generator], np.ndarray]
Progress = Callable[[str, int, int], None]


def no_progress(stage: str, done: int, total: int) -> None:
    return None




@dataclass(frozen=True, kw_only=True)
class TDSpec:
    """One task's comparison; '(ours)' everywhere the issue leaves a number open."""

    task: str = "tracking"
    seeds: int = 3
    """Independent runs of each learner (GA seeds seed .. seed+seeds-1; the TD runs share one batched world)."""
    seed: int = 0
    generations: int = 50
    """GA generations (the report's 50); the TD budget is the GA's mean robot-steps over them."""
    population: int = 50
    episodes: int = 90
    checkpoints: tuple[int, ...] | None = None
    """GA generations at which both learners are measured (TD at the GA's mean robot-steps there);
    None: :func:`default_checkpoints` (1, 2, 5, 10, 20, ... up to ``generations``)."""
    lanes: int = 256
    """(ours) robots feeding each TD run's table at once."""
    encoder: str = "reduced"
    reward: str = "sparse"
    prior: str = "none"
    """``default``: where the table has no preference yet, act as the task's shipped default rules (the GA's
    starting point) instead of at random (ours)."""
    alpha: float = 0.1
    gamma: float = 1.0
    """1: the undiscounted episode payoff the GA maximises is the return."""
    epsilon: float = 0.1
    trials: int = 100
    """Fresh trials per measurement: epochs (Tracking; ~1,000 episodes), random starts x5 (Docking), trials x5 (door)."""
    td_steps: int | None = None
    """TD robot-steps per run; None: match the GA's."""
    max_rows: int = 2_000_000

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise ConfigError(f"task={self.task!r}: choose one of {', '.join(TASKS)}")
        for name, low in (("seeds", 1), ("seed", 0), ("generations", 1), ("population", 2), ("episodes", 1),
                          ("lanes", 1), ("trials", 1), ("max_rows", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise ConfigError(f"{name}={v!r}: give a whole number >= {low}")
        if self.td_steps is not None and (isinstance(self.td_steps, bool) or not isinstance(self.td_steps, int)
                                          or self.td_steps < 1):
            raise ConfigError(f"td_steps={self.td_steps!r}: give a whole number >= 1 (or None to match the GA)")
        if (self.task, self.encoder) not in ENCODERS:
            raise ConfigError(f"encoder={self.encoder!r}: choose reduced or full")
        if self.reward not in REWARDS:
            raise ConfigError(f"reward={self.reward!r}: choose one of {', '.join(REWARDS)}")
        if self.prior not in PRIORS:
            raise ConfigError(f"prior={self.prior!r}: choose one of {', '.join(PRIORS)}")
        if self.reward == "shaped" and self.task != "tracking":
            raise ConfigError(f"reward='shaped' for task={self.task!r}: only Tracking has a natural shaped reward")
        marks = default_checkpoints(int(self.generations)) if self.checkpoints is None else tuple(self.checkpoints)
        object.__setattr__(self, "checkpoints", marks)
        if (not marks or list(marks) != sorted(set(marks))
                or any(isinstance(g, bool) or not isinstance(g, int) or not 1 <= g <= self.generations for g in marks)):
            raise ConfigError(f"checkpoints={self.checkpoints!r}: give increasing generations in 1..{self.generations}")
        QConfig(alpha=self.alpha, gamma=self.gamma, epsilon=self.epsilon)  # raises on a bad one

    @property
    def marks(self) -> tuple[int, ...]:
        """The checkpoints, filled in (``checkpoints`` is never None once the spec is made)."""
        return self.checkpoints or ()

    @property
    def q_config(self) -> QConfig:
        return QConfig(alpha=self.alpha, gamma=self.gamma, epsilon=self.epsilon)

    @property
    def measure_trials(self) -> int:
        return self.trials if self.task == "tracking" else 5 * self.trials

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["checkpoints"] = list(self.marks)
        return d


@dataclass
class Curve:
    """One run of one learner: its measure (%) against its robot-steps at each checkpoint."""

    learner: str  # "ga" or "td"
    seed: int
    robot_steps: list[int] = field(default_factory=list)
    measure: list[float] = field(default_factory=list)
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def default_checkpoints(generations: int) -> tuple[int, ...]:
    """Generations 1, 2, 5, 10, 20, 30, ... up to and including ``generations``."""
    marks = [g for g in (1, 2, 5) if g < generations] + list(range(10, generations, 10)) + [generations]
    return tuple(sorted(set(marks)))
