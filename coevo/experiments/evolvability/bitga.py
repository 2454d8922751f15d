"""A bit-string GA run as many independent runs at once (report Appendix D §2.1, §2.4.2).

Every array has the shape ``(runs, population, ...)``; one numpy operation advances
all runs, each with its own mutation model and rates.  All runs of one call share a
:class:`~coevo.experiments.evolvability.landscape.DynamicLandscape` (the report runs every model
on the same landscapes).

The GA is the report's: generational, every individual evaluated in every generation,
fitness-proportional selection without fitness scaling (stochastic universal sampling
*(ours)*, then random pairing), 2-point crossover with probability ``crossover_rate``
*(ours: 0.6)*, no elitism, then mutation by the run's model (see
:mod:`coevo.ga.mutation`): a mutated bit is *reset* to a random value.

A genome is 43 bits in one ``uint64``: string positions 0-19 are x1, 20-39 x2 (each
read as an unsigned integer and scaled to [0, 100)), 40-42 the control gene k.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coevo.errors import ConfigError
from coevo.experiments.evolvability.landscape import DynamicLandscape
from coevo.ga.mutation import CONTROL_BITS, CONTROL_LEVELS, MODEL_NAMES

__all__ = ["COORD_BITS", "GENOME_BITS", "RunParams", "Trace", "decode", "gene_of", "run_batch", "breed"]

COORD_BITS = 20
GENOME_BITS = 2 * COORD_BITS + CONTROL_BITS  # 43
_COORD_MASK = np.uint64((1 << COORD_BITS) - 1)


@dataclass(frozen=True)
class RunParams:
    """Per-run mutation settings, arrays of shape (runs,).

    ``model`` holds indices into ``MODEL_NAMES`` (fm, gm, fh, gh); ``rate`` is the
    base mutation rate mr; ``alpha_m`` GM's minimum rate; ``hyper`` FH's fraction hr;
    ``alpha_h`` GH's minimum hypermutation rate.
    """

    model: np.ndarray
    rate: np.ndarray
    alpha_m: np.ndarray
    hyper: np.ndarray
    alpha_h: np.ndarray

    @staticmethod
    def make(models: list[str], rates: list[float], *, alpha_m: float = 0.03, hyper: float = 0.2,
             alpha_h: float = 0.05) -> RunParams:
        """One run per (model, rate) pair given as two equal-length lists."""
        if len(models) != len(rates):
            raise ConfigError(f"{len(models)} models but {len(rates)} rates")
        bad = [m for m in models if m not in MODEL_NAMES]
        if bad:
            raise ConfigError(f"unknown mutation model {bad[0]!r}: choose from {', '.join(MODEL_NAMES)}")
        for name, v in (("rate", min(rates, default=0)), ("rate", max(rates, default=0)), ("alpha_m", alpha_m),
                        ("hyper", hyper), ("alpha_h", alpha_h)):
            if not 0 <= v <= 1:
                raise ConfigError(f"{name} {v!r} is not in [0, 1]")
        n = len(models)
        return RunParams(
            model=np.array([MODEL_NAMES.index(m) for m in models]),
            rate=np.asarray(rates, dtype=np.float64),
            alpha_m=np.full(n, alpha_m),
            hyper=np.full(n, hyper),
            alpha_h=np.full(n, alpha_h),
        )

    def __len__(self) -> int:
        return len(self.model)


@dataclass
class Trace:
    """Per-generation statistics, each (runs, generations).

    ``mean``: mean fitness of the population (online performance is its mean over
    generations); ``best``: best fitness of the population (current best);
    ``control``: mean rate the control genes stand for (GM: mutation rate, GH:
    hypermutation rate; NaN for FM and FH).
    """

    mean: np.ndarray
    best: np.ndarray
    control: np.ndarray

    @property
    def online(self) -> np.ndarray:
        return self.mean.mean(axis=1)

    @property
    def current_best(self) -> np.ndarray:
        return self.best.mean(axis=1)


def decode(g: np.ndarray) -> np.ndarray:
    """Genomes (...) -> points (..., 2) in [0, 100)."""
    x1 = (g & _COORD_MASK).astype(np.float64)
    x2 = ((g >> np.uint64(COORD_BITS)) & _COORD_MASK).astype(np.float64)
    return np.stack([x1, x2], axis=-1) * (100.0 / (1 << COORD_BITS))


def gene_of(g: np.ndarray) -> np.ndarray:
    """The control gene k (0..7) of each genome."""
    return ((g >> np.uint64(2 * COORD_BITS)) & np.uint64(CONTROL_LEVELS - 1)).astype(np.int64)


def _random_genomes(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return rng.integers(0, 1 << GENOME_BITS, size=shape, dtype=np.uint64)


def _select(fitness: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Stochastic universal sampling per run: (R, N) parent indices, shuffled for pairing."""
    R, N = fitness.shape
    f = np.where(fitness.sum(axis=1, keepdims=True) > 0, fitness, 1.0)
    cum = np.cumsum(f, axis=1)
    cum /= cum[:, -1:]
    cum[:, -1] = 1.0
    rows = np.arange(R)[:, None]
    pointers = (rng.random((R, 1)) + np.arange(N)) / N
    idx = np.searchsorted((cum + rows).ravel(), (pointers + rows).ravel(), side="right").reshape(R, N) - rows * N
    idx = np.clip(idx, 0, N - 1)
    perm = np.argsort(rng.random((R, N)), axis=1)
    return np.take_along_axis(idx, perm, axis=1)


def _crossover(g: np.ndarray, rate: float, rng: np.random.Generator) -> np.ndarray:
    """2-point crossover of pairs (0, 1), (2, 3), ...: the bits between the two cuts are swapped."""
    R, N = g.shape
    half = N // 2
    a, b = g[:, 0 : 2 * half : 2].copy(), g[:, 1 : 2 * half : 2].copy()
    cut1 = rng.integers(1, GENOME_BITS, size=(R, half))
    cut2 = rng.integers(1, GENOME_BITS - 1, size=(R, half))
    cut2 = cut2 + (cut2 >= cut1)  # two distinct cuts in 1..42
    lo, hi = np.minimum(cut1, cut2).astype(np.uint64), np.maximum(cut1, cut2).astype(np.uint64)
    one = np.uint64(1)
    mask = ((one << hi) - one) ^ ((one << lo) - one)
    mask = np.where(rng.random((R, half)) < rate, mask, np.uint64(0))
    diff = (a ^ b) & mask
    out = g.copy()
    out[:, 0 : 2 * half : 2] = a ^ diff
    out[:, 1 : 2 * half : 2] = b ^ diff
    return out


def _reset_bits(g: np.ndarray, rate: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Reset each bit of each genome to a random value with probability ``rate`` (per genome)."""
    hit = rng.random(g.shape + (GENOME_BITS,), dtype=np.float32) < rate[..., None].astype(np.float32)
    packed = np.zeros(g.shape + (8,), dtype=np.uint8)  # the hit bits, little-endian, as one uint64 per genome
    packed[..., : (GENOME_BITS + 7) // 8] = np.packbits(hit, axis=-1, bitorder="little")
    mask = packed.view("<u8")[..., 0].astype(np.uint64)
    fresh = _random_genomes(rng, g.shape)
    return (g & ~mask) | (fresh & mask)


def breed(g: np.ndarray, fitness: np.ndarray, params: RunParams, rng: np.random.Generator, *,
          crossover_rate: float = 0.6) -> np.ndarray:
    """The next generation of every run: select, cross over, then mutate by each run's model."""
    R, N = g.shape
    kids = np.take_along_axis(g, _select(fitness, rng), axis=1)
    kids = _crossover(kids, crossover_rate, rng)
    model = params.model[:, None]
    k = gene_of(kids)
    rate = np.where(model == MODEL_NAMES.index("gm"), params.alpha_m[:, None] + k / CONTROL_LEVELS, params.rate[:, None])
    rate = np.minimum(rate, 1.0)
    # hypermutation: FH a fixed number of random offspring per run, GH each with chance alpha_h + k/8
    n_fh = np.round(params.hyper * N).astype(np.int64)[:, None]
    rank = np.argsort(np.argsort(rng.random((R, N)), axis=1), axis=1)
    p_gh = np.minimum(params.alpha_h[:, None] + k / CONTROL_LEVELS, 1.0)
    hyper = np.where(model == MODEL_NAMES.index("fh"), rank < n_fh,
                     (model == MODEL_NAMES.index("gh")) & (rng.random((R, N)) < p_gh))
    kids = _reset_bits(kids, rate, rng)
    return np.where(hyper, _random_genomes(rng, (R, N)), kids)


def run_batch(
    landscape: DynamicLandscape,
    params: RunParams,
    *,
    population: int = 100,
    generations: int = 200,
    crossover_rate: float = 0.6,
    seed: int | np.random.SeedSequence = 0,
    on_generation: Callable[[int], None] | None = None,
) -> Trace:
    """Run ``len(params)`` independent GAs on ``landscape`` for ``generations`` generations."""
    if generations > landscape.generations:
        raise ConfigError(f"the landscape covers {landscape.generations} generations, not {generations}")
    if population < 2 or population % 2:
        raise ConfigError(f"population must be an even number >= 2, got {population}")
    rng = np.random.default_rng(seed)
    R = len(params)
    g = _random_genomes(rng, (R, population))
    mean = np.empty((R, generations))
    best = np.empty((R, generations))
    control = np.full((R, generations), np.nan)
    gm, gh = params.model == MODEL_NAMES.index("gm"), params.model == MODEL_NAMES.index("gh")
    for t in range(generations):
        f = landscape.fitness(decode(g), t)
        mean[:, t] = f.mean(axis=1)
        best[:, t] = f.max(axis=1)
        k = gene_of(g)
        control[gm, t] = np.minimum(params.alpha_m[gm, None] + k[gm] / CONTROL_LEVELS, 1.0).mean(axis=1)
        control[gh, t] = np.minimum(params.alpha_h[gh, None] + k[gh] / CONTROL_LEVELS, 1.0).mean(axis=1)
        if t + 1 < generations:
            g = breed(g, f, params, rng, crossover_rate=crossover_rate)
        if on_generation is not None:
            on_generation(t + 1)
    return Trace(mean=mean, best=best, control=control)
