"""The survey's hidden-state world (Appendix C, Figure 13 and Table 5): two states that both look "blue".

World states and what the agent senses::

    red   --R--> blue (upper)  --L--> goal  3.0      --R--> goal  1.0
          --L--> goal  RED_L                                          (RED_L = 0.0, ours)
    green --L--> blue (lower)  --L--> goal -4.0      --R--> goal  1.0
          --R--> goal  0.75

The agent starts in red or green with equal chance, acts L or R, and all moves are deterministic;
a goal ends the episode and pays its reward. The rewards are ours, fixed by the text (the derivation
is in ``docs/earl/reconstruction.md``): L in the upper blue state pays 3.0 and R in the lower one 1.0;
Q(blue, R) = 1 makes R pay 1.0 in the upper one too; Q(blue, L) = -0.5, the mean over the two blue
states, makes L in the lower one pay -4.0; the expected rewards 1.0 (red R, green L, blue R) and
1.875 (red R, green R, blue L) make green R pay 0.75. Red L is not constrained beyond "less than 1"
(the Q-learner prefers red R); we use 0.0.
"""

from __future__ import annotations

import numpy as np

from coevo.errors import ConfigError

__all__ = [
    "L", "R", "ACTIONS", "RED", "GREEN", "BLUE", "OBSERVATIONS", "N_STATES", "RED_L", "GREEN_R",
    "UPPER_BLUE_L", "UPPER_BLUE_R", "LOWER_BLUE_L", "LOWER_BLUE_R", "OPTIMAL_POLICY", "Q_POLICY",
    "expected_reward", "sampled_reward", "all_policies", "HiddenWorld",
]

L, R = 0, 1
ACTIONS = ("L", "R")
RED, GREEN, BLUE = 0, 1, 2           # observations (what the agent senses)
OBSERVATIONS = ("red", "green", "blue")
_RED, _GREEN, _UPPER, _LOWER = 0, 1, 2, 3   # world states
N_STATES = 4
_SENSED = np.array([RED, GREEN, BLUE, BLUE])

RED_L = 0.0          # ours: the text only requires < 1
GREEN_R = 0.75
UPPER_BLUE_L, UPPER_BLUE_R = 3.0, 1.0
LOWER_BLUE_L, LOWER_BLUE_R = -4.0, 1.0

OPTIMAL_POLICY = (R, R, L)   # red R, green R, blue L: 1.875, the best for what the agent senses
Q_POLICY = (R, L, R)         # red R, green L, blue R: 1.0, what a table Q-learner settles on


def _tables(red_l: float) -> tuple[np.ndarray, np.ndarray]:
    """(N_STATES, 2) successor (-1 = a goal, the episode ends) and reward of each move."""
    nxt = np.array([[-1, _UPPER], [_LOWER, -1], [-1, -1], [-1, -1]])
    rew = np.array([[red_l, 0.0], [0.0, GREEN_R], [UPPER_BLUE_L, UPPER_BLUE_R], [LOWER_BLUE_L, LOWER_BLUE_R]])
    return nxt, rew


def expected_reward(policies: np.ndarray, *, red_l: float = RED_L) -> np.ndarray:
    """Exact expected reward (both starts, equal chance) of policies given as (..., 3) actions for red, green, blue."""
    pol = np.asarray(policies)
    if pol.shape[-1:] != (3,):
        raise ConfigError(f"hidden-state policies need 3 genes (red, green, blue), not shape {pol.shape}")
    return 0.5 * (_episode(pol, _RED, red_l) + _episode(pol, _GREEN, red_l))


def _episode(pol: np.ndarray, start: int | np.ndarray, red_l: float) -> np.ndarray:
    """Reward of each policy started in ``start`` (a world state, or one per policy)."""
    nxt, rew = _tables(red_l)
    s = np.broadcast_to(np.asarray(start), pol.shape[:-1])
    a = np.take_along_axis(pol, _SENSED[s][..., None], axis=-1)[..., 0]
    total = rew[s, a]
    s2 = nxt[s, a]
    on = s2 >= 0
    s2 = np.where(on, s2, 0)
    a2 = np.take_along_axis(pol, _SENSED[s2][..., None], axis=-1)[..., 0]
    return total + np.where(on, rew[s2, a2], 0.0)


def sampled_reward(policies: np.ndarray, rng: np.random.Generator, *, trials: int = 1,
                   red_l: float = RED_L) -> np.ndarray:
    """Mean reward of each policy over ``trials`` episodes from random starts (what an EA sees), shape (...)."""
    pol = np.asarray(policies)
    if int(trials) != trials or trials < 1:
        raise ConfigError(f"trials={trials!r}: give a whole number >= 1")
    starts = rng.integers(0, 2, size=(int(trials),) + pol.shape[:-1])
    return np.mean([_episode(pol, st, red_l) for st in starts], axis=0)


def all_policies() -> np.ndarray:
    """The 8 deterministic policies (red, green, blue), shape (8, 3)."""
    return np.array([[a, b, c] for a in (L, R) for b in (L, R) for c in (L, R)])


class HiddenWorld:
    """``n_lanes`` copies of the world stepped together; observations are red/green/blue (the DiscreteEnv protocol)."""

    n_observations = 3
    n_actions = 2

    def __init__(self, n_lanes: int, *, red_l: float = RED_L) -> None:
        if int(n_lanes) != n_lanes or n_lanes < 1:
            raise ConfigError(f"n_lanes={n_lanes!r}: give a whole number >= 1")
        if not np.isfinite(red_l) or red_l >= UPPER_BLUE_R:
            raise ConfigError(f"red_l={red_l!r}: the survey's Q-learner prefers red R, so red L must pay less than 1.0")
        self.n_lanes = int(n_lanes)
        self._next, self._reward = _tables(float(red_l))
        self._s = np.zeros(self.n_lanes, dtype=np.int64)

    def reset(self, rng: np.random.Generator) -> np.ndarray:
        """Each lane starts in red or green with equal chance."""
        self._s = rng.integers(0, 2, size=self.n_lanes)
        return _SENSED[self._s]

    def step(self, actions: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Apply one action per lane; returns (observations, rewards, done); finished lanes stay done with reward 0."""
        on = self._s >= 0
        here = np.where(on, self._s, 0)
        a = np.asarray(actions)
        reward = np.where(on, self._reward[here, a], 0.0)
        self._s = np.where(on, self._next[here, a], -1)
        done = self._s < 0
        return _SENSED[np.where(done, 0, self._s)], reward, done
