"""The dynamic landscape generator of the report's Appendix D (§2.3, §2.4.1).

A landscape is ``n_peaks`` Gaussian peaks in the box ``[low, high]^dim``::

    f(x, t) = max_i A_i exp(-d(x, c_i(t))^2 / (2 σ_i^2))

The width is σ = 4, the report's parameter (its gloss "about 50 % at distance 4" would
need σ ≈ 3.4; at σ = 4 a peak keeps 61 % there).
Amplitudes are drawn from ``amplitude`` (U[10, 50]) except the ``optima`` peaks of
height ``optimum`` (100), so the landscape's maximum is exactly ``optimum`` at all
times, attained at an optimal peak's centre.  Amplitudes and widths do not change.

Peaks move every ``punctuation`` generations: each peak moves a distance drawn from
U[0, ``max_drift``] along its heading.  *(ours)* A peak's heading is a random
direction drawn once; a peak that would leave the box is reflected off the wall
(its heading mirrors), so a move never carries a centre further than ``max_drift``.
The report's classes: gradual (max_drift 1, punctuation 1) and abrupt (max_drift 50,
punctuation 20: still for 20 generations, then 50 gradual generations' worth of
change at once).

The whole trajectory is drawn at construction from one seed, so a landscape is the
same for every model and run that uses it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coevo import exactmath
from coevo.errors import ConfigError

__all__ = ["LandscapeSpec", "DynamicLandscape", "CLASSES"]


@dataclass(frozen=True)
class LandscapeSpec:
    """Parameters of the generator (defaults: the report's gradual class)."""

    n_peaks: int = 256
    dim: int = 2
    low: float = 0.0
    high: float = 100.0
    width: float = 4.0  # σ of every peak
    amplitude: tuple[float, float] = (10.0, 50.0)
    optimum: float = 100.0
    optima: int = 1
    max_drift: float = 1.0
    punctuation: int = 1

    def __post_init__(self) -> None:
        if self.n_peaks < 1 or self.dim < 1:
            raise ConfigError(f"a landscape needs at least one peak and one dimension, got n_peaks={self.n_peaks}, dim={self.dim}")
        if not 1 <= self.optima <= self.n_peaks:
            raise ConfigError(f"optima={self.optima} must be between 1 and n_peaks={self.n_peaks}")
        if self.high <= self.low or self.width <= 0:
            raise ConfigError(f"bad box [{self.low}, {self.high}] or width {self.width}")
        lo, hi = self.amplitude
        if not 0 < lo <= hi < self.optimum:
            raise ConfigError(f"amplitudes {self.amplitude} must be positive and below the optimum {self.optimum}")
        if self.max_drift < 0 or self.punctuation < 1:
            raise ConfigError(f"max_drift={self.max_drift} must be >= 0 and punctuation={self.punctuation} >= 1")


CLASSES: dict[str, LandscapeSpec] = {
    "gradual": LandscapeSpec(max_drift=1.0, punctuation=1),
    "abrupt": LandscapeSpec(max_drift=50.0, punctuation=20),
}


def _scores(aug: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``aug @ w``, its sums in the order of ``aug``'s columns: a BLAS product adds in the order of the kernel the
    processor picked, and the landscape's values would differ in their last bits between machines."""
    acc = aug[:, :1] * w[0]
    for j in range(1, aug.shape[1]):
        acc += aug[:, j : j + 1] * w[j]
    return acc


def _exp(a: np.ndarray) -> np.ndarray:
    """e**a in ``a``'s dtype from :func:`coevo.exactmath.exp` (numpy's own exp runs SIMD code on some processors)."""
    return exactmath.exp(a).astype(a.dtype, copy=False)


def _reflect(pos: np.ndarray, heading: np.ndarray, low: float, high: float) -> tuple[np.ndarray, np.ndarray]:
    """Fold positions back into [low, high] as if bouncing off the walls; mirror the heading per bounce."""
    span = high - low
    u = (pos - low) / span
    bounces = np.floor(u)
    odd = (bounces % 2) != 0
    frac = u - bounces
    folded = np.where(odd, 1.0 - frac, frac)
    return low + folded * span, np.where(odd, -heading, heading)


class DynamicLandscape:
    """One seeded dynamic landscape, its peak trajectory drawn for ``generations`` generations."""

    def __init__(self, spec: LandscapeSpec, *, seed: int | np.random.SeedSequence, generations: int) -> None:
        if generations < 1:
            raise ConfigError(f"generations must be at least 1, got {generations}")
        self.spec = spec
        self.generations = generations
        rng = np.random.default_rng(seed)
        P, d = spec.n_peaks, spec.dim
        self.amplitude = rng.uniform(*spec.amplitude, size=P)
        self.amplitude[: spec.optima] = spec.optimum
        self.width = np.full(P, spec.width)
        pos = rng.uniform(spec.low, spec.high, size=(P, d))
        heading = rng.normal(size=(P, d))
        heading /= np.linalg.norm(heading, axis=1, keepdims=True)
        centres = np.empty((generations, P, d))
        centres[0] = pos
        for t in range(1, generations):
            if t % spec.punctuation == 0:
                step = rng.uniform(0.0, spec.max_drift, size=(P, 1))
                pos, heading = _reflect(pos + step * heading, heading, spec.low, spec.high)
            centres[t] = pos
        self.centres = centres  # (generations, n_peaks, dim): positions seen during generation t
        inv = 1.0 / (2.0 * self.width**2)
        self._inv = inv
        # f = exp(max_i [y, |y|^2, 1] . W_i) with y = x - mid: the exponent expanded so that one product
        # scores all peaks (_scores); centring on the box keeps the terms small (float32 is then accurate to ~1e-5)
        self._mid = (spec.low + spec.high) / 2.0
        cy = centres - self._mid
        self._weights = np.concatenate(
            [
                2.0 * inv[None, :, None] * cy,
                np.broadcast_to(-inv, (generations, P))[..., None],
                (exactmath.log(self.amplitude) - inv * (cy**2).sum(axis=2))[..., None],
            ],
            axis=2,
        ).transpose(0, 2, 1).copy()  # (generations, dim + 2, n_peaks)
        self._weights32 = self._weights.astype(np.float32)
        self._n_cells = max(1, int(round((spec.high - spec.low) / (2.5 * spec.width)))) if spec.dim <= 3 else 1
        self._cand_t = -1
        self._cand: list[np.ndarray] = []

    def changes(self) -> np.ndarray:
        """Generations whose landscape differs from the one before."""
        t = np.arange(1, self.generations)
        return t[t % self.spec.punctuation == 0]

    def optimum_at(self, t: int) -> np.ndarray:
        """Centre of the (first) optimal peak during generation ``t``."""
        return self.centres[t, 0]

    def fitness(self, x: np.ndarray, t: int, *, dtype: type = np.float64) -> np.ndarray:
        """f(x) during generation ``t`` for points ``x`` of shape (..., dim), computed in ``dtype``.

        Exact up to rounding, and fast: the box is cut into cells and the points of a
        cell are scored only against the peaks that can be the highest somewhere in it
        (a peak whose best value over the cell is below the worst value of some other
        peak over the cell never wins there).
        """
        if not 0 <= t < self.generations:
            raise ConfigError(f"generation {t} is outside this landscape's 0..{self.generations - 1}")
        x = np.asarray(x)
        flat = x.reshape(-1, self.spec.dim)
        sp = self.spec
        if flat.size == 0:
            return np.zeros(x.shape[:-1], dtype)
        if not (np.all(flat >= sp.low) and np.all(flat <= sp.high)):
            return self.fitness_dense(x, t, dtype=dtype)
        y = flat.astype(dtype) - dtype(self._mid)
        aug = np.concatenate([y, (y**2).sum(axis=1, keepdims=True), np.ones((len(y), 1), dtype)], axis=1)
        w = self._weights32[t] if dtype == np.float32 else self._weights[t].astype(dtype, copy=False)
        cell, cand = self._cells(flat, t)
        order = np.argsort(cell, kind="stable")
        bounds = np.searchsorted(cell[order], np.arange(len(cand) + 1))
        out: np.ndarray = np.empty(len(y), dtype)
        aug = aug[order]
        for c in np.flatnonzero(np.diff(bounds)):
            s, e = bounds[c], bounds[c + 1]
            out[order[s:e]] = _scores(aug[s:e], w[:, cand[c]]).max(axis=1)
        return _exp(out).reshape(x.shape[:-1])

    def _cells(self, flat: np.ndarray, t: int) -> tuple[np.ndarray, list[np.ndarray]]:
        """Cell index of every point, and each cell's candidate peaks (cached per generation)."""
        sp = self.spec
        n = self._n_cells
        size = (sp.high - sp.low) / n
        idx = np.clip(((flat - sp.low) / size).astype(np.int64), 0, n - 1)
        cell = np.ravel_multi_index(tuple(idx.T), (n,) * sp.dim)
        if self._cand_t != t:
            grid = np.stack(np.meshgrid(*[np.arange(n)] * sp.dim, indexing="ij"), axis=-1).reshape(-1, sp.dim)
            lo = sp.low + grid * size  # (cells, dim)
            hi = lo + size
            c = self.centres[t]  # (P, dim)
            near = np.clip(c[None], lo[:, None], hi[:, None]) - c[None]
            far = np.maximum(np.abs(c[None] - lo[:, None]), np.abs(hi[:, None] - c[None]))
            log_a = exactmath.log(self.amplitude)
            upper = log_a - self._inv * (near**2).sum(axis=2)  # (cells, P): the peak's best over the cell
            lower = (log_a - self._inv * (far**2).sum(axis=2)).max(axis=1, keepdims=True)  # someone's worst
            keep = upper >= lower - 1e-9
            self._cand = [np.flatnonzero(k) for k in keep]
            self._cand_t = t
        return cell, self._cand

    def fitness_dense(self, x: np.ndarray, t: int, *, dtype: type = np.float64, chunk: int = 2048) -> np.ndarray:
        """f(x) scoring every peak (one product per chunk of points)."""
        x = np.asarray(x)
        y = x.reshape(-1, self.spec.dim).astype(dtype) - dtype(self._mid)
        aug = np.concatenate([y, (y**2).sum(axis=1, keepdims=True), np.ones((len(y), 1), dtype)], axis=1)
        w = self._weights32[t] if dtype == np.float32 else self._weights[t].astype(dtype, copy=False)
        out: np.ndarray = np.empty(len(y), dtype)
        for s in range(0, len(y), chunk):
            out[s : s + chunk] = _scores(aug[s : s + chunk], w).max(axis=1)
        return _exp(out).reshape(x.shape[:-1])

    def fitness_direct(self, x: np.ndarray, t: int) -> np.ndarray:
        """The defining formula, peak by peak (slow; for checking :meth:`fitness`)."""
        x = np.asarray(x, dtype=np.float64)
        d2 = ((x[..., None, :] - self.centres[t]) ** 2).sum(axis=-1)
        return (self.amplitude * np.exp(-d2 * self._inv)).max(axis=-1)

