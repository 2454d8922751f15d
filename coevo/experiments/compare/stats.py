"""Comparing regimes on one measure: rank tests and effect sizes.

The runs of a regime are few (10 in the report) and their measures are bounded
and often tied at zero (a starved Docking agent docks in 0 % of episodes), so we
use the two-sided Mann–Whitney U test (scipy's, with its tie correction) and the
Vargha–Delaney A effect size, the probability that a random run of regime B
scores higher than a random run of regime A (ties count half); 0.5 is no effect,
and 0.71 / 0.64 / 0.56 are the customary large / medium / small thresholds.

Several groups (the rates of asynchrony of ``independent-offline``) are compared at
once with the Kruskal–Wallis H test (scipy's, tie-corrected) and its effect size
ε² = H / (n − 1), the share of rank variance explained by the grouping; 0.01 /
0.08 / 0.26 are the customary small / medium / large thresholds (Tomczak &
Tomczak 2014).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

__all__ = ["RankComparison", "compare_samples", "magnitude", "GroupComparison", "compare_groups", "MeanInterval",
           "mean_interval", "mean_intervals", "holm", "format_p"]


@dataclass(frozen=True)
class RankComparison:
    measure: str
    a: str
    b: str
    n_a: int
    n_b: int
    median_a: float
    median_b: float
    mean_a: float
    mean_b: float
    u: float  # Mann-Whitney U of sample b
    p_value: float
    a12: float  # P(b > a) + 0.5 P(b == a)
    magnitude: str

    def as_dict(self) -> dict[str, float | int | str]:
        return asdict(self)


def magnitude(a12: float) -> str:
    d = abs(a12 - 0.5)
    if d >= 0.21:
        return "large"
    if d >= 0.14:
        return "medium"
    if d >= 0.06:
        return "small"
    return "negligible"


def compare_samples(measure: str, a: str, xa: Sequence[float], b: str, xb: Sequence[float]) -> RankComparison:
    """Mann–Whitney U (two-sided) and Vargha–Delaney A of ``xb`` over ``xa``."""
    va = np.asarray(xa, dtype=float)
    vb = np.asarray(xb, dtype=float)
    if va.size == 0 or vb.size == 0:
        raise ValueError(f"{measure}: both samples need at least one run (got {va.size} and {vb.size})")
    if not (np.all(np.isfinite(va)) and np.all(np.isfinite(vb))):
        raise ValueError(f"{measure}: samples hold non-finite values")
    greater = (vb[:, None] > va[None, :]).sum()
    equal = (vb[:, None] == va[None, :]).sum()
    u = float(greater + 0.5 * equal)
    a12 = u / (va.size * vb.size)
    if np.ptp(np.concatenate([va, vb])) == 0:
        p = 1.0  # every run scored the same: no evidence of a difference (scipy would divide by zero)
    else:
        p = float(stats.mannwhitneyu(vb, va, alternative="two-sided").pvalue)
    return RankComparison(
        measure=measure, a=a, b=b, n_a=int(va.size), n_b=int(vb.size),
        median_a=float(np.median(va)), median_b=float(np.median(vb)),
        mean_a=float(va.mean()), mean_b=float(vb.mean()),
        u=u, p_value=p, a12=float(a12), magnitude=magnitude(float(a12)),
    )


@dataclass(frozen=True)
class GroupComparison:
    measure: str
    groups: tuple[str, ...]
    medians: tuple[float, ...]
    n: int
    h: float
    p_value: float
    epsilon2: float  # H / (n - 1)
    magnitude: str

    def as_dict(self) -> dict[str, object]:
        return asdict(self)

    @property
    def appreciable(self) -> bool:
        """A difference the data support (p < 0.05) and that is not negligible in size."""
        return self.p_value < 0.05 and self.magnitude != "negligible"


def _epsilon_magnitude(e2: float) -> str:
    if e2 >= 0.26:
        return "large"
    if e2 >= 0.08:
        return "medium"
    if e2 >= 0.01:
        return "small"
    return "negligible"


def compare_groups(measure: str, samples: dict[str, Sequence[float]]) -> GroupComparison:
    """Kruskal–Wallis H across the groups of ``samples`` and its ε² effect size."""
    names = tuple(samples)
    arrays = [np.asarray(samples[k], dtype=float) for k in names]
    if len(arrays) < 2 or any(a.size == 0 for a in arrays):
        raise ValueError(f"{measure}: need at least two groups of at least one run each")
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise ValueError(f"{measure}: samples hold non-finite values")
    n = int(sum(a.size for a in arrays))
    if np.ptp(np.concatenate(arrays)) == 0:
        h, p = 0.0, 1.0  # every run scored the same (scipy would divide by zero)
    else:
        res = stats.kruskal(*arrays)
        h, p = float(res.statistic), float(res.pvalue)
    e2 = h / (n - 1) if n > 1 else 0.0
    return GroupComparison(measure=measure, groups=names, medians=tuple(float(np.median(a)) for a in arrays), n=n,
                           h=h, p_value=p, epsilon2=e2, magnitude=_epsilon_magnitude(e2))


@dataclass(frozen=True)
class MeanInterval:
    """A sample's mean with a 95 % bootstrap interval (percentile method); the interval is NaN below 2 values."""

    n: int
    mean: float
    low: float
    high: float

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)

    def text(self, digits: int = 2) -> str:
        if self.n == 0:
            return "–"
        if np.isnan(self.low):
            return f"{self.mean:.{digits}f} (n = {self.n})"
        return f"{self.mean:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}] (n = {self.n})"


def mean_interval(values: Sequence[float] | np.ndarray, *, seed: int = 0) -> MeanInterval:
    """The mean of ``values`` (NaNs left out) and its 95 % bootstrap interval: 9,999 resamples from a fixed seed, so
    a report reads the same when it is written again.  The percentile method, not BCa: BCa fails on samples whose
    values are all equal, which small comparisons give."""
    x = np.asarray([v for v in values if not np.isnan(v)], dtype=np.float64)
    if x.size == 0:
        return MeanInterval(0, float("nan"), float("nan"), float("nan"))
    if x.size < 2 or np.all(x == x[0]):
        lo = hi = float(x[0]) if x.size >= 2 else float("nan")
        return MeanInterval(int(x.size), float(x.mean()), lo, hi)
    ci = stats.bootstrap((x,), np.mean, confidence_level=0.95, method="percentile",
                         rng=np.random.default_rng(seed)).confidence_interval
    return MeanInterval(int(x.size), float(x.mean()), float(ci.low), float(ci.high))


def mean_intervals(runs: np.ndarray, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per column of ``runs`` (runs x generations, NaN where a run has no value): the mean and the 95 % interval of
    :func:`mean_interval`, (mean, low, high) arrays.  The columns without NaN are resampled together in one bootstrap
    (whole runs drawn, the same draws for every generation: one call instead of one per generation, and a band that is
    smooth along the generations); column j then equals ``mean_interval(runs[:, j], seed=seed)``, so a band ends where
    the report's interval at the last generation is.  Columns with NaN go one at a time."""
    x = np.asarray(runs, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"runs x generations expected, got shape {x.shape}")
    n_cols = x.shape[1]
    mean, low, high = np.full(n_cols, np.nan), np.full(n_cols, np.nan), np.full(n_cols, np.nan)
    whole = ~np.isnan(x).any(axis=0)
    if x.shape[0] >= 2 and whole.any():
        w = x[:, whole]
        ci = stats.bootstrap((w,), np.mean, axis=0, confidence_level=0.95, method="percentile",
                             rng=np.random.default_rng(seed)).confidence_interval
        lo, hi = np.asarray(ci.low, dtype=np.float64), np.asarray(ci.high, dtype=np.float64)
        same = np.all(w == w[0], axis=0)  # every run equal: mean_interval's point interval, not scipy's NaN
        lo[same], hi[same] = w[0, same], w[0, same]
        mean[whole], low[whole], high[whole] = w.mean(axis=0), lo, hi
    for j in np.flatnonzero(~whole if x.shape[0] >= 2 else np.ones(n_cols, bool)):
        m = mean_interval(x[:, j], seed=seed)
        mean[j], low[j], high[j] = m.mean, m.low, m.high
    return mean, low, high


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm–Bonferroni adjusted p-values, in the input's order: the i-th smallest of m is multiplied by (m − i + 1),
    made monotone (never below the one before it) and capped at 1."""
    m = len(p_values)
    order = sorted(range(m), key=lambda i: p_values[i])
    adjusted = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * float(p_values[i])))
        adjusted[i] = running
    return adjusted


def format_p(p: float) -> str:
    """A p-value as the reports print it: two significant digits, or "< 0.001"."""
    return f"{p:.2g}" if p >= 0.001 else "< 0.001"
