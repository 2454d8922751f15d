"""A tabular Q-learner over many independent lanes at once, for any finite, discrete, episodic task.

Each lane is one learner with its own table ``q[lane, observation, action]``, playing its own copy
of the task, so 100 independent runs are one batch of 100 lanes. The task only has to follow the
small :class:`DiscreteEnv` protocol (integer observations, integer actions, N lanes stepped
together); a robot task joins by discretising its sensors into one observation index per lane.

The update is one-step Q-learning (the survey's eq. 8, Watkins 1989)::

    Q(o, a) <- Q(o, a) + alpha * (r + gamma * max_b Q(o', b) * (1 - done) - Q(o, a))

with epsilon-greedy action choice (ties between equal Q-values broken at random). ``alpha`` is
either constant or ``1 / n(o, a)`` (the number of updates of that pair so far): the latter makes
each Q-value the running mean of its targets, the Robbins-Monro condition under which tabular
Q-learning converges, and the setting under which an aliased observation's values settle on the
average over the states it stands for (the survey's Q(blue, L) = -0.5).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from coevo.errors import ConfigError

__all__ = ["DiscreteEnv", "QConfig", "QLearner", "train"]

ALPHA_SCHEDULES = ("constant", "1/n")


class DiscreteEnv(Protocol):
    """N copies of a finite episodic task stepped together.

    ``reset`` starts a new episode in every lane and returns the observations, shape (n_lanes,),
    integers in ``[0, n_observations)``. ``step`` takes one action per lane and returns
    (observations, rewards, done), each shape (n_lanes,). A lane whose episode has ended stays
    done with reward 0 (and any observation) until the next ``reset``. Randomness comes only from
    the generator passed in.
    """

    n_lanes: int
    n_observations: int
    n_actions: int

    def reset(self, rng: np.random.Generator) -> np.ndarray: ...

    def step(self, actions: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


@dataclass(frozen=True, kw_only=True)
class QConfig:
    """Q-learning settings, checked on construction."""

    alpha: float = 0.1
    """Learning rate (the constant schedule), in (0, 1]."""
    alpha_schedule: str = "constant"
    """``constant`` or ``1/n`` (per observation-action pair: the running mean of its targets)."""
    gamma: float = 1.0
    """Discount, in [0, 1]; 1 is the survey's undiscounted episodic score."""
    epsilon: float = 0.1
    """Chance of a uniformly random action, in [0, 1]."""
    initial_q: float = 0.0
    """Every Q-value's start."""
    max_steps: int = 10_000
    """An episode still running after this many steps is an error (a task that never ends)."""

    def __post_init__(self) -> None:
        if not 0.0 < self.alpha <= 1.0:
            raise ConfigError(f"alpha={self.alpha!r}: the learning rate must be in (0, 1]")
        if self.alpha_schedule not in ALPHA_SCHEDULES:
            raise ConfigError(f"alpha_schedule={self.alpha_schedule!r}: choose one of {', '.join(ALPHA_SCHEDULES)}")
        if not 0.0 <= self.gamma <= 1.0:
            raise ConfigError(f"gamma={self.gamma!r}: the discount must be in [0, 1]")
        if not 0.0 <= self.epsilon <= 1.0:
            raise ConfigError(f"epsilon={self.epsilon!r}: the exploration rate must be in [0, 1]")
        if not np.isfinite(self.initial_q):
            raise ConfigError(f"initial_q={self.initial_q!r}: give a finite number")
        if int(self.max_steps) != self.max_steps or self.max_steps < 1:
            raise ConfigError(f"max_steps={self.max_steps!r}: give a whole number >= 1")


class QLearner:
    """One Q-table per lane, acted on and updated for all lanes at once."""

    def __init__(self, n_lanes: int, n_observations: int, n_actions: int, config: QConfig | None = None) -> None:
        for name, v in (("n_lanes", n_lanes), ("n_observations", n_observations), ("n_actions", n_actions)):
            if int(v) != v or v < 1:
                raise ConfigError(f"{name}={v!r}: give a whole number >= 1")
        self.config = config or QConfig()
        self.q = np.full((int(n_lanes), int(n_observations), int(n_actions)), float(self.config.initial_q))
        self.visits = np.zeros(self.q.shape, dtype=np.int64)
        self.steps = np.zeros(int(n_lanes), dtype=np.int64)   # experience: updates made per lane
        self._lanes = np.arange(int(n_lanes))

    @property
    def n_lanes(self) -> int:
        return self.q.shape[0]

    def act(self, obs: np.ndarray, rng: np.random.Generator, *, explore: bool = True) -> np.ndarray:
        """An action per lane: greedy on its table (ties at random), or with chance epsilon uniformly random.

        The same random numbers are drawn whether or not a lane explores, so the stream does not
        depend on the Q-values.
        """
        qo = self.q[self._lanes, obs]                       # (lanes, actions)
        ties = qo == qo.max(axis=1, keepdims=True)
        greedy = np.argmax(np.where(ties, rng.random(qo.shape), -1.0), axis=1)
        if not explore:
            return greedy
        random = rng.integers(0, qo.shape[1], size=qo.shape[0])
        return np.where(rng.random(qo.shape[0]) < self.config.epsilon, random, greedy)

    def update(self, obs: np.ndarray, actions: np.ndarray, rewards: np.ndarray, next_obs: np.ndarray,
               done: np.ndarray, active: np.ndarray) -> None:
        """One Q-learning step on the lanes in ``active`` (those whose episode had not ended before this step)."""
        lanes = self._lanes[active]
        o, a = obs[active], actions[active]
        future = self.q[lanes, next_obs[active]].max(axis=1) * (~done[active])
        target = rewards[active] + self.config.gamma * future
        self.visits[lanes, o, a] += 1
        if self.config.alpha_schedule == "1/n":
            alpha = 1.0 / self.visits[lanes, o, a]
        else:
            alpha = self.config.alpha
        self.q[lanes, o, a] += alpha * (target - self.q[lanes, o, a])
        self.steps[lanes] += 1

    def greedy_policy(self) -> np.ndarray:
        """(lanes, observations) the best action per observation (the lowest index on a tie)."""
        return self.q.argmax(axis=2)

    def run_episode(self, env: DiscreteEnv, rng: np.random.Generator, *, learn: bool = True,
                    explore: bool = True) -> np.ndarray:
        """Play one episode in every lane (learning from it unless ``learn`` is off); returns each lane's total reward."""
        if env.n_lanes != self.n_lanes or env.n_observations != self.q.shape[1] or env.n_actions != self.q.shape[2]:
            raise ConfigError(f"env has {env.n_lanes} lanes x {env.n_observations} observations x {env.n_actions} "
                              f"actions but the learner {self.q.shape[0]} x {self.q.shape[1]} x {self.q.shape[2]}")
        obs = env.reset(rng)
        active = np.ones(self.n_lanes, dtype=bool)
        total = np.zeros(self.n_lanes)
        for _ in range(self.config.max_steps):
            actions = self.act(obs, rng, explore=explore)
            nxt, reward, done = env.step(actions, rng)
            total += np.where(active, reward, 0.0)
            if learn:
                self.update(obs, actions, reward, nxt, done, active)
            active &= ~done
            if not active.any():
                return total
            obs = nxt
        raise ConfigError(f"an episode ran past max_steps={self.config.max_steps}; raise it or check that the task ends")


def train(learner: QLearner, env: DiscreteEnv, rng: np.random.Generator, episodes: int, *,
          on_episode: Callable[[int, QLearner], None] | None = None) -> np.ndarray:
    """Learn for ``episodes`` episodes in every lane; returns the per-episode rewards, shape (episodes, lanes).

    ``on_episode(i, learner)`` is called after episode i (0-based), e.g. to record a curve or progress.
    """
    if int(episodes) != episodes or episodes < 0:
        raise ConfigError(f"episodes={episodes!r}: give a whole number >= 0")
    out = np.empty((int(episodes), learner.n_lanes))
    for i in range(int(episodes)):
        out[i] = learner.run_episode(env, rng)
        if on_episode is not None:
            on_episode(i, learner)
    return out
