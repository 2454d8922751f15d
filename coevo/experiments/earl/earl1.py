"""EARL1, the survey's simplest EA for reinforcement learning (Appendix C, section 4.2), over many runs at once.

A policy is one gene per observed state holding that state's action (Figure 5). A generation:
evaluate every policy, pick parents by binary tournament (the fitter of two drawn with
replacement; a tie goes to the first drawn), pair them in order, cross each pair with one-point
crossover at chance ``crossover`` (cut uniform between genes), and reset every gene with chance
``mutation`` to a different action. There is no elitism. The survey's footnote 4 gives the
settings of its hidden-state run: binary tournament, 50 policies, crossover 0.8, mutation 0.01;
we use them on the grid as well (ours: the survey gives no settings for the grid).

Runs are the leading axis of every array, so 100 runs are one batch: the population is
``(runs, population, genes)`` and the fitness function maps it to ``(runs, population)``.

:func:`implicit_values` is the population's implicit value estimate (Table 4): for each state and
action, the mean fitness of the policies whose gene for that state holds that action; NaN (the
survey's "?") where no policy does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coevo.errors import ConfigError

__all__ = ["EARL1Config", "EARL1Result", "FitnessFn", "evolve", "next_generation", "implicit_values"]

FitnessFn = Callable[[np.ndarray, np.random.Generator], np.ndarray]


@dataclass(frozen=True, kw_only=True)
class EARL1Config:
    """EARL1 settings (the survey's footnote 4 by default), checked on construction."""

    population: int = 50
    crossover: float = 0.8
    mutation: float = 0.01
    """Chance per gene per generation of a reset to a different action (ours: the survey says only 'mutation rate')."""
    generations: int = 100
    """Generations after the initial one (ours: the survey does not say)."""

    def __post_init__(self) -> None:
        if int(self.population) != self.population or self.population < 2 or self.population % 2:
            raise ConfigError(f"population={self.population!r}: give an even whole number >= 2 (parents are paired)")
        if not 0.0 <= self.crossover <= 1.0:
            raise ConfigError(f"crossover={self.crossover!r}: a probability in [0, 1]")
        if not 0.0 <= self.mutation <= 1.0:
            raise ConfigError(f"mutation={self.mutation!r}: a probability in [0, 1]")
        if int(self.generations) != self.generations or self.generations < 0:
            raise ConfigError(f"generations={self.generations!r}: give a whole number >= 0")


@dataclass(frozen=True)
class EARL1Result:
    """What :func:`evolve` records: per generation 0..G, for each run."""

    population: np.ndarray
    """(runs, population, genes) the final population."""
    fitness: np.ndarray
    """(runs, population) its fitness."""
    mean: np.ndarray
    """(G + 1, runs) mean fitness of the population."""
    best: np.ndarray
    """(G + 1, runs) best fitness in the population."""
    share: np.ndarray
    """(G + 1, runs) share of the population equal to ``target`` (NaN without a target)."""
    evaluations: int
    """Policies evaluated per run (each one episode, or ``trials`` episodes, of experience)."""


def next_generation(pop: np.ndarray, fitness: np.ndarray, n_actions: int, cfg: EARL1Config,
                    rng: np.random.Generator) -> np.ndarray:
    """Selection, crossover and mutation for every run at once; returns the offspring, same shape as ``pop``."""
    runs, size, genes = pop.shape
    r = np.arange(runs)[:, None]
    i = rng.integers(0, size, size=(runs, size))
    j = rng.integers(0, size, size=(runs, size))
    winner = np.where(fitness[r, j] > fitness[r, i], j, i)
    parents = pop[r, winner]                                     # (runs, size, genes)
    a, b = parents[:, 0::2], parents[:, 1::2]
    cross = rng.random((runs, size // 2)) < cfg.crossover
    cut = rng.integers(1, genes, size=(runs, size // 2)) if genes > 1 else np.ones((runs, size // 2), dtype=int)
    swap = cross[..., None] & (np.arange(genes) >= cut[..., None])  # genes from the cut on come from the mate
    kids = np.empty_like(parents)
    kids[:, 0::2] = np.where(swap, b, a)
    kids[:, 1::2] = np.where(swap, a, b)
    mutate = rng.random(kids.shape) < cfg.mutation
    shift = rng.integers(1, n_actions, size=kids.shape) if n_actions > 1 else np.zeros(kids.shape, dtype=int)
    return np.where(mutate, (kids + shift) % n_actions, kids)


def evolve(fitness_fn: FitnessFn, *, runs: int, genes: int, n_actions: int = 2, cfg: EARL1Config | None = None,
           rng: np.random.Generator, target: np.ndarray | None = None,
           on_generation: Callable[[int, int], None] | None = None) -> EARL1Result:
    """Run EARL1 ``runs`` times at once from uniformly random populations.

    ``fitness_fn(pop, rng)`` scores a (runs, population, genes) array; ``target`` (genes,) is a
    policy whose share of the population is recorded (the survey's Figure 14 plots it);
    ``on_generation(g, G)`` reports progress.
    """
    cfg = cfg or EARL1Config()
    for name, v in (("runs", runs), ("genes", genes), ("n_actions", n_actions)):
        if int(v) != v or v < 1:
            raise ConfigError(f"{name}={v!r}: give a whole number >= 1")
    if target is not None:
        target = np.asarray(target)
        if target.shape != (genes,):
            raise ConfigError(f"target must have shape ({genes},), not {target.shape}")
    pop = rng.integers(0, n_actions, size=(runs, cfg.population, genes))
    mean, best, share = [], [], []
    fit = np.empty((runs, cfg.population))
    for g in range(cfg.generations + 1):
        if g:
            pop = next_generation(pop, fit, n_actions, cfg, rng)
        fit = np.asarray(fitness_fn(pop, rng), dtype=float)
        if fit.shape != (runs, cfg.population):
            raise ConfigError(f"the fitness function returned shape {fit.shape}, expected {(runs, cfg.population)}")
        mean.append(fit.mean(axis=1))
        best.append(fit.max(axis=1))
        share.append((pop == target).all(axis=2).mean(axis=1) if target is not None else np.full(runs, np.nan))
        if on_generation is not None:
            on_generation(g, cfg.generations)
    return EARL1Result(population=pop, fitness=fit, mean=np.array(mean), best=np.array(best), share=np.array(share),
                       evaluations=(cfg.generations + 1) * cfg.population)


def implicit_values(pop: np.ndarray, fitness: np.ndarray, n_actions: int = 2) -> np.ndarray:
    """Mean fitness of the policies choosing each action in each state, (..., genes, n_actions); NaN where none do."""
    pop = np.asarray(pop)
    fitness = np.asarray(fitness, dtype=float)
    if pop.shape[:-1] != fitness.shape:
        raise ConfigError(f"population {pop.shape} and fitness {fitness.shape} do not match")
    chose = pop[..., None] == np.arange(n_actions)                 # (..., P, genes, actions)
    count = chose.sum(axis=-3)
    total = (chose * fitness[..., None, None]).sum(axis=-3)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.where(count > 0, count, 1), np.nan)
