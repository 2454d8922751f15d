"""The two experiments of Appendix C, each over many independent runs at once.

``run_grid``: tabular Q-learning and EARL1 on the grid world (Figure 1, Tables 1, 2 and 4).
``run_hidden``: the same two learners on the hidden-state world (Figure 13, Table 5, Figure 14).
Each returns a plain dict of numbers and numpy arrays that :mod:`~coevo.experiments.earl.report`
turns into files. Every run has its own generator stream, spawned from one seed, so the same
spec gives identical results.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from coevo.errors import ConfigError
from coevo.experiments.earl import gridworld, hidden
from coevo.experiments.earl.earl1 import EARL1Config, evolve, implicit_values
from coevo.experiments.earl.qlearning import QConfig, QLearner, train

__all__ = ["EarlSpec", "run_grid", "run_hidden", "TABLE2", "TABLE2_FITNESS"]

Progress = Callable[[str, int, int], None]

# The survey's Table 2: five EARL1 policies (genes a1..e5, 0 = R, 1 = D) and their listed fitness.
_TABLE2_TEXT = """\
D R D D R R R R R R D R D D R R D R R R D R R D R 8
D D D D R R R R R R D D R R D R D R R R D R D D R 9
R D D R R D R D R R D D D R D R D R R R D R D D D 17
D D D D R D R R R R R D R R R D R R D R D R D D R 11
R D D D R D R R D R R D R R D R D R R D D R D D D 16"""
TABLE2 = np.array([[gridworld.ACTIONS.index(t) for t in line.split()[:25]] for line in _TABLE2_TEXT.splitlines()])
TABLE2_FITNESS = np.array([float(line.split()[25]) for line in _TABLE2_TEXT.splitlines()])


def _whole(name: str, v: Any, low: int) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
        raise ConfigError(f"{name}={v!r}: give a whole number >= {low}")


def _prob(name: str, v: Any) -> None:
    if not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
        raise ConfigError(f"{name}={v!r}: give a number in [0, 1]")


@dataclass(frozen=True, kw_only=True)
class EarlSpec:
    """Both experiments' settings; '(ours)' where the survey does not say."""

    runs: int = 100
    seed: int = 0
    generations: int = 100
    """EARL1 generations after the first (ours)."""
    population: int = 50
    crossover: float = 0.8
    mutation: float = 0.01
    grid_episodes: int = 2000
    """Q-learning episodes per grid run (ours)."""
    grid_alpha: float = 0.5
    grid_epsilon: float = 1.0
    """(ours) a uniform behaviour policy: Q-learning is off-policy, and every box must be visited often for
    the whole table (Table 1) to converge; with 0.5 the far boxes (e1, a5) stay up to 5 off after 3000 episodes."""
    hidden_episodes: int = 20000
    """Q-learning episodes per hidden-state run (ours)."""
    hidden_epsilon: float = 0.2
    hidden_trials: tuple[int, ...] = field(default=(0, 1, 2, 4))
    """EARL1 fitness on the hidden-state world: 0 = the exact expectation over both starts (the headline,
    ours), k > 0 = the mean of k episodes from random starts; each is run and reported."""

    def __post_init__(self) -> None:
        _whole("runs", self.runs, 1)
        _whole("seed", self.seed, 0)
        _whole("generations", self.generations, 0)
        _whole("grid_episodes", self.grid_episodes, 1)
        _whole("hidden_episodes", self.hidden_episodes, 1)
        for name in ("crossover", "mutation", "grid_alpha", "grid_epsilon", "hidden_epsilon"):
            _prob(name, getattr(self, name))
        if self.grid_alpha == 0:
            raise ConfigError("grid_alpha=0: the learning rate must be in (0, 1]")
        if not self.hidden_trials:
            raise ConfigError("hidden_trials is empty: give at least one (0 = exact expectation)")
        for t in self.hidden_trials:
            _whole("hidden_trials", t, 0)
        EARL1Config(population=self.population, crossover=self.crossover, mutation=self.mutation,
                    generations=self.generations)

    @property
    def earl1(self) -> EARL1Config:
        return EARL1Config(population=self.population, crossover=self.crossover, mutation=self.mutation,
                           generations=self.generations)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["hidden_trials"] = list(self.hidden_trials)
        return d


def _streams(spec: EarlSpec, experiment: int, n: int) -> list[np.random.Generator]:
    """``n`` independent generators for one experiment (0 grid, 1 hidden) of this seed."""
    root = np.random.SeedSequence([spec.seed, experiment])
    return [np.random.default_rng(s) for s in root.spawn(n)]


def _quiet(stage: str, done: int, total: int) -> None:
    return None


def run_grid(spec: EarlSpec, progress: Progress = _quiet) -> dict[str, Any]:
    """Q-learning and EARL1 on the grid, ``spec.runs`` runs each."""
    q_rng, ea_rng = _streams(spec, 0, 2)
    qstar = gridworld.dp_q()
    best, paths = gridworld.optimal_paths()

    learner = QLearner(spec.runs, gridworld.N_STATES, 2, QConfig(alpha=spec.grid_alpha, epsilon=spec.grid_epsilon))
    env = gridworld.GridWorld(spec.runs)
    greedy_return = np.empty((spec.grid_episodes, spec.runs))
    q_error = np.empty((spec.grid_episodes, spec.runs))

    def record(i: int, lr: QLearner) -> None:
        greedy_return[i] = gridworld.returns(lr.greedy_policy())
        q_error[i] = np.abs(lr.q - qstar).max(axis=(1, 2))
        if i % 100 == 99 or i + 1 == spec.grid_episodes:
            progress("grid: Q-learning", i + 1, spec.grid_episodes)

    train(learner, env, q_rng, spec.grid_episodes, on_episode=record)

    ea = evolve(lambda pop, rng: gridworld.returns(pop), runs=spec.runs, genes=gridworld.N_STATES, cfg=spec.earl1,
                rng=ea_rng, on_generation=lambda g, n: progress("grid: EARL1", g + 1, n + 1))
    optimal_action = qstar == qstar.max(axis=1, keepdims=True)          # (25, 2) ties count as optimal
    chose_optimal = optimal_action[np.arange(gridworld.N_STATES), ea.population]  # (runs, P, 25)
    on_path = _visited(ea.population)                                    # (runs, P, 25)
    return {
        "qstar": qstar, "optimum": best, "optimal_paths": paths,
        "q_final": learner.q, "q_greedy_return": greedy_return, "q_error": q_error,
        "q_steps": learner.steps,
        "ea": ea,
        "ea_chose_optimal": chose_optimal, "ea_on_path": on_path,
        "ea_implicit": implicit_values(ea.population, ea.fitness),        # (runs, 25, 2)
        "table2_returns": gridworld.returns(TABLE2),
        "table4_from_table2": implicit_values(TABLE2, TABLE2_FITNESS),
    }


def _visited(pop: np.ndarray) -> np.ndarray:
    """(..., 25) whether each policy's path from a1 passes through each box."""
    flat = pop.reshape(-1, gridworld.N_STATES)
    lanes = np.arange(flat.shape[0])
    seen = np.zeros(flat.shape, dtype=bool)
    s = np.full(flat.shape[0], gridworld.START)
    for _ in range(9):
        on = s >= 0
        seen[lanes[on], s[on]] = True
        here = np.where(on, s, 0)
        s = np.where(on, gridworld.NEXT[here, flat[lanes, here]], -1)
    return seen.reshape(pop.shape)


def run_hidden(spec: EarlSpec, progress: Progress = _quiet) -> dict[str, Any]:
    """Q-learning and EARL1 (under each fitness evaluation in ``spec.hidden_trials``) on the hidden-state world."""
    rngs = _streams(spec, 1, 1 + len(spec.hidden_trials))
    learner = QLearner(spec.runs, 3, 2, QConfig(alpha_schedule="1/n", epsilon=spec.hidden_epsilon))
    env = hidden.HiddenWorld(spec.runs)
    every = max(1, spec.hidden_episodes // 200)
    marks, q_blue, q_policy_share = [], [], []

    def record(i: int, lr: QLearner) -> None:
        if (i + 1) % every == 0 or i + 1 == spec.hidden_episodes:
            marks.append(i + 1)
            q_blue.append(lr.q[:, hidden.BLUE].copy())
            q_policy_share.append((lr.greedy_policy() == np.array(hidden.Q_POLICY)).all(axis=1).mean())
            progress("hidden: Q-learning", i + 1, spec.hidden_episodes)

    train(learner, env, rngs[0], spec.hidden_episodes, on_episode=record)

    target = np.array(hidden.OPTIMAL_POLICY)
    ea: dict[int, Any] = {}
    for k, (trials, rng) in enumerate(zip(spec.hidden_trials, rngs[1:])):
        def fitness(pop: np.ndarray, r: np.random.Generator, t: int = trials) -> np.ndarray:
            return hidden.expected_reward(pop) if t == 0 else hidden.sampled_reward(pop, r, trials=t)

        label = "exact" if trials == 0 else f"{trials} trial{'s' if trials > 1 else ''}"

        def generation_done(g: int, n: int, lb: str = label) -> None:
            progress(f"hidden: EARL1 ({lb})", g + 1, n + 1)

        ea[trials] = evolve(fitness, runs=spec.runs, genes=3, cfg=spec.earl1, rng=rng, target=target,
                            on_generation=generation_done)
    return {
        "q_final": learner.q, "q_policy": learner.greedy_policy(),
        "q_expected": hidden.expected_reward(learner.greedy_policy()),
        "q_marks": np.array(marks), "q_blue": np.array(q_blue), "q_policy_share": np.array(q_policy_share),
        "q_steps": learner.steps,
        "ea": ea,
        "policies": hidden.all_policies(), "policy_values": hidden.expected_reward(hidden.all_policies()),
    }
