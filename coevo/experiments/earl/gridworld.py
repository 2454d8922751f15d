"""The survey's 5 x 5 grid world (Appendix C, Figure 1), with the box payoffs reconstructed from Tables 1 and 2.

Boxes are named by column letter and row number (``a1`` top left, ``e5`` bottom right); R moves
to the next letter, D to the next number, and a move off the grid ends the task. The agent starts
in a1 and senses the box it is in. A box's payoff is counted on every visit, the start box included,
which is the survey's own convention (its eq. 6 and 8 reward ``r(s_t)`` for the state acted in) and,
since a1 pays 0, the same score as "added on entering". The payoffs are ours, derived in
``docs/earl/reconstruction.md``: they reproduce the legible row of Table 1, the five fitnesses of
Table 2, the "15 vs. 8" of the text and the optimum 17 along R,D,R,D,D,R,R,D.

States are numbered in the survey's table order a1, a2, ..., a5, b1, ..., e5 (``state = 5*column + row``).
"""

from __future__ import annotations

import numpy as np

from coevo.errors import ConfigError

__all__ = [
    "ACTIONS", "RIGHT", "DOWN", "N_STATES", "START", "PAYOFF", "NEXT", "STATE_NAMES", "OPTIMAL_PATH",
    "state_name", "dp_q", "returns", "optimal_paths", "GridWorld",
]

ACTIONS = ("R", "D")
RIGHT, DOWN = 0, 1
SIZE = 5
N_STATES = SIZE * SIZE
START = 0
STATE_NAMES = tuple(f"{c}{r}" for c in "abcde" for r in range(1, SIZE + 1))
OPTIMAL_PATH = "RDRDDRRD"  # the survey's example of an optimal action sequence (score 17)

# Payoff by box, rows 1-5 top to bottom, columns a-e left to right (ours: the reconstruction).
_PAYOFF_BY_ROW = np.array([
    #  a   b   c   d   e
    [0, 2, 1, -1, 1],   # row 1
    [1, 1, 2, 0, 2],    # row 2
    [3, -5, 4, 3, 1],   # row 3
    [1, -2, 4, 1, 2],   # row 4
    [1, 1, 2, 1, 1],    # row 5
], dtype=float)
PAYOFF = _PAYOFF_BY_ROW.T.reshape(N_STATES).copy()  # indexed by state (column-major: a1..a5, b1..)
PAYOFF.setflags(write=False)


def _next_table() -> np.ndarray:
    """(N_STATES, 2) successor of each state under R and D; -1 is off the grid (the task ends)."""
    nxt = np.empty((N_STATES, 2), dtype=np.int64)
    for s in range(N_STATES):
        col, row = divmod(s, SIZE)
        nxt[s, RIGHT] = s + SIZE if col + 1 < SIZE else -1
        nxt[s, DOWN] = s + 1 if row + 1 < SIZE else -1
    nxt.setflags(write=False)
    return nxt


NEXT = _next_table()


def state_name(s: int) -> str:
    """``a1`` ... ``e5`` for a state number."""
    if not 0 <= s < N_STATES:
        raise ConfigError(f"grid state {s} is out of range 0..{N_STATES - 1}")
    return STATE_NAMES[s]


def dp_q(payoff: np.ndarray = PAYOFF) -> np.ndarray:
    """The exact Q-function, Q(s, a) = r(s) + V(next(s, a)) with V(off grid) = 0 (undiscounted), shape (25, 2).

    The grid is acyclic (R and D only move right or down), so one sweep from e5 back to a1 is exact.
    """
    payoff = np.asarray(payoff, dtype=float)
    if payoff.shape != (N_STATES,):
        raise ConfigError(f"grid payoff must have shape ({N_STATES},), not {payoff.shape}")
    q = np.zeros((N_STATES, 2))
    v = np.zeros(N_STATES + 1)  # v[-1] is off the grid
    for s in range(N_STATES - 1, -1, -1):
        q[s] = payoff[s] + v[NEXT[s]]
        v[s] = q[s].max()
    return q


def returns(policies: np.ndarray, payoff: np.ndarray = PAYOFF) -> np.ndarray:
    """Score from a1 of each policy (one action per state, shape (..., 25), 0 = R, 1 = D), shape (...).

    All policies are walked at once; a path is at most 9 boxes long.
    """
    pol = np.asarray(policies)
    if pol.shape[-1:] != (N_STATES,):
        raise ConfigError(f"grid policies need {N_STATES} genes in their last axis, not shape {pol.shape}")
    flat = pol.reshape(-1, N_STATES)
    lanes = np.arange(flat.shape[0])
    s = np.full(flat.shape[0], START)
    total = np.zeros(flat.shape[0])
    for _ in range(2 * SIZE - 1):
        on = s >= 0
        if not on.any():
            break
        here = np.where(on, s, 0)
        total += np.where(on, payoff[here], 0.0)
        s = np.where(on, NEXT[here, flat[lanes, here]], -1)
    return total.reshape(pol.shape[:-1])


def optimal_paths(payoff: np.ndarray = PAYOFF) -> tuple[float, list[str]]:
    """The best score from a1 and every action sequence reaching it, as the moves inside the grid (the survey's form)."""
    best = -np.inf
    paths: list[str] = []

    def walk(s: int, score: float, path: str) -> None:
        nonlocal best, paths
        score += payoff[s]
        for a in (RIGHT, DOWN):
            n = int(NEXT[s, a])
            if n >= 0:
                walk(n, score, path + ACTIONS[a])
            elif s == N_STATES - 1 and a == DOWN:
                continue  # from e5 both moves leave the grid: count the path once
            elif score > best:
                best, paths = score, [path]
            elif score == best:
                paths.append(path)

    walk(START, 0.0, "")
    return float(best), sorted(set(paths))


class GridWorld:
    """``n_lanes`` copies of the grid stepped together (the :class:`~coevo.experiments.earl.qlearning.DiscreteEnv` protocol).

    The reward of a step is the payoff of the box the agent acts in. A lane that has left the grid
    stays done and earns 0 until the next ``reset``.
    """

    n_observations = N_STATES
    n_actions = 2

    def __init__(self, n_lanes: int, payoff: np.ndarray = PAYOFF) -> None:
        if int(n_lanes) != n_lanes or n_lanes < 1:
            raise ConfigError(f"n_lanes={n_lanes!r}: give a whole number >= 1")
        self.n_lanes = int(n_lanes)
        self.payoff = np.asarray(payoff, dtype=float)
        if self.payoff.shape != (N_STATES,):
            raise ConfigError(f"grid payoff must have shape ({N_STATES},), not {self.payoff.shape}")
        self._s = np.full(self.n_lanes, START)

    def reset(self, rng: np.random.Generator) -> np.ndarray:
        """Every lane back in a1 (the start is fixed; ``rng`` is unused but part of the protocol)."""
        self._s = np.full(self.n_lanes, START)
        return self._s.copy()

    def step(self, actions: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Apply one action per lane; returns (observations, rewards, done)."""
        on = self._s >= 0
        here = np.where(on, self._s, 0)
        reward = np.where(on, self.payoff[here], 0.0)
        self._s = np.where(on, NEXT[here, np.asarray(actions)], -1)
        done = self._s < 0
        return np.where(done, 0, self._s), reward, done
