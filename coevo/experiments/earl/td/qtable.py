"""The hashed Q-table: a row only for an observation some robot has met, updated by many lanes at once."""

from __future__ import annotations

import numpy as np

from coevo.errors import ConfigError
from coevo.experiments.earl.qlearning import QConfig

__all__ = ["HashedQ"]


class HashedQ:
    """One Q-table per run, rows allocated for observations as they are first met; see the module docstring."""

    def __init__(self, runs: int, n_actions: int, config: QConfig, *, max_rows: int = 2_000_000) -> None:
        for name, v in (("runs", runs), ("n_actions", n_actions), ("max_rows", max_rows)):
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ConfigError(f"{name}={v!r}: give a whole number >= 1")
        self.runs, self.n_actions, self.config, self.max_rows = int(runs), int(n_actions), config, int(max_rows)
        self._index: dict[int, int] = {}
        self._run_of_row = np.zeros(1024, dtype=np.int64)
        self.q = np.full((1024, self.n_actions), float(config.initial_q))
        self.visits = np.zeros((1024, self.n_actions), dtype=np.int64)
        self.n_rows = 0
        self.overflow = 0  # observations met after the table was full (played, not learned)

    def _grow(self, need: int) -> None:
        cap = len(self.q)
        while cap < need:
            cap *= 2
        if cap != len(self.q):
            extra = cap - len(self.q)
            self.q = np.concatenate([self.q, np.full((extra, self.n_actions), float(self.config.initial_q))])
            self.visits = np.concatenate([self.visits, np.zeros((extra, self.n_actions), dtype=np.int64)])
            self._run_of_row = np.concatenate([self._run_of_row, np.zeros(extra, dtype=np.int64)])

    def rows(self, run: np.ndarray, codes: np.ndarray, *, allocate: bool = True) -> np.ndarray:
        """The row of each (run, observation code); new ones get a row (``allocate``) or -1."""
        keys = (codes * self.runs + run).tolist()
        get = self._index.get
        out = np.fromiter((get(k, -1) for k in keys), dtype=np.int64, count=len(keys))
        if allocate and (out < 0).any():
            for i in np.flatnonzero(out < 0).tolist():
                k = keys[i]
                r = self._index.get(k, -1)
                if r < 0 and self.n_rows < self.max_rows:
                    r = self.n_rows
                    self._grow(r + 1)
                    self._index[k] = r
                    self._run_of_row[r] = int(run[i])
                    self.n_rows += 1
                elif r < 0:
                    self.overflow += 1
                out[i] = r
        return out

    def act(self, rows: np.ndarray, rng: np.random.Generator, *, explore: bool = True,
            fallback: np.ndarray | None = None) -> np.ndarray:
        """Epsilon-greedy (or greedy) joint actions, ties broken at random; an unknown row (-1) acts at random,
        or, given ``fallback`` actions, rows with no preference yet (every action's value equal) take those.

        The same random numbers are drawn whatever the Q-values, so the stream does not depend on them.
        """
        qo = np.where((rows >= 0)[:, None], self.q[np.maximum(rows, 0)], self.config.initial_q)
        top = qo.max(axis=1, keepdims=True)
        ties = qo == top
        greedy = np.argmax(np.where(ties, rng.random(qo.shape), -1.0), axis=1)
        if fallback is not None:
            greedy = np.where(ties.all(axis=1), fallback, greedy)
        if not explore:
            return greedy
        random = rng.integers(0, self.n_actions, size=len(rows))
        return np.where(rng.random(len(rows)) < self.config.epsilon, random, greedy)

    def update(self, rows: np.ndarray, actions: np.ndarray, rewards: np.ndarray, next_rows: np.ndarray,
               done: np.ndarray) -> None:
        """One-step Q-learning on a batch of transitions (duplicates merged, see the module docstring)."""
        ok = rows >= 0
        rows, actions, rewards, next_rows, done = rows[ok], actions[ok], rewards[ok], next_rows[ok], done[ok]
        if rows.size == 0:
            return
        future = np.where((next_rows >= 0) & ~done, self.q[np.maximum(next_rows, 0)].max(axis=1), 0.0)
        target = rewards + self.config.gamma * future
        pair, inverse, count = np.unique(rows * self.n_actions + actions, return_inverse=True, return_counts=True)
        mean = np.bincount(inverse, weights=target, minlength=pair.size) / count
        r, a = pair // self.n_actions, pair % self.n_actions
        n_before = self.visits[r, a]
        if self.config.alpha_schedule == "1/n":
            step = count / (n_before + count)
        else:
            step = 1.0 - (1.0 - self.config.alpha) ** count
        self.q[r, a] += step * (mean - self.q[r, a])
        self.visits[r, a] = n_before + count

    def table_sizes(self) -> list[dict[str, int]]:
        """Per run: observations with a row, and (observation, action) pairs ever updated."""
        run = self._run_of_row[: self.n_rows]
        pairs = (self.visits[: self.n_rows] > 0).sum(axis=1)
        return [{"observations": int((run == r).sum()), "pairs": int(pairs[run == r].sum())} for r in range(self.runs)]
