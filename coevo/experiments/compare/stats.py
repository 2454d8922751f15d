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

**Small designs get exact p-values.**  The normal (Mann–Whitney) and χ² (Kruskal–Wallis) approximations can give a
p that no arrangement of so few runs could produce (two runs a regime, tied within each: 0.19 where the exact
test cannot go below 1/3).  Where the runs can be split among the groups in at most :data:`EXACT_ARRANGEMENTS`
ways, p is the exact permutation p of the rank statistic (mid-ranks for ties: for two groups the exact two-sided Mann–Whitney test, for
more the exact Kruskal–Wallis test); above it, the approximations, which are then accurate.  Every comparison also
carries ``min_p``, the smallest p its design can give (:func:`smallest_p`): two runs a
regime cannot give less than 0.33, three 0.1, five 0.0079.

**Means: the Student t interval, and none below** :data:`MIN_RUNS` **runs.**  Measured by simulation (2,000 samples
each, ``tests/test_compare.py``; docs/glossary.md has the table), the percentile bootstrap the reports used before
covers a mean in only 45–50 % of samples of two runs (its interval is then the two values), 80–86 % of five and
86–92 % of ten; BCa covers 79–85 % at five; the studentised bootstrap covers 80–96 % at five and cannot be computed
on the many resamples of three runs that repeat one value.  The t interval covers 92–95.5 % from three runs on for
the bounded, roughly symmetric shapes of the measures (normal, uniform, beta(2, 5)), and 89–94 % below fifty runs
for strongly skewed or zero-heavy ones.  With two runs its one degree of freedom makes it
±12.7 times half their gap, which says nothing a reader can use: below three runs no interval is given, and the text
says why.

**A bounded measure's interval is cut at its range.**  A t interval is symmetric about the mean, so for a measure that
cannot leave a range (a rate of episodes in 0–100 %, a payoff or fitness in 0–1) and whose runs sit near an end it
can reach outside: three runs at 0, 0 and 100 % give 33 % with [−110, 177].  Such an end is cut at the range, and
the text says so ("clipped at 0").  Cutting keeps the coverage exactly: the true mean lies in the range, so it lies
in the cut interval whenever it lay in the whole one (tests/test_interval_coverage.py measures both).  The other
choices were worse here: Wilson's interval is for k successes of n trials, not for a mean of runs' rates; the
bootstrap intervals, which stay inside the range by construction, cover far less than 95 % at these n (above);
a logit transform is undefined at the runs that score exactly 0 or 100 %, which are common (a starved Docking).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any
from itertools import combinations

import numpy as np
from scipy import stats

__all__ = ["RankComparison", "compare_samples", "magnitude", "GroupComparison", "compare_groups", "MeanInterval",
           "mean_interval", "mean_intervals", "holm", "format_p", "MIN_RUNS", "EXACT_ARRANGEMENTS", "rank_p",
           "smallest_p", "too_few_text", "design_floor", "Bounds", "clip", "clip_words"]

#: Fewest values a mean's 95 % interval is given for (module docstring: the coverage measured by n).
MIN_RUNS = 3
#: A measure's possible range, (lowest, highest): what its interval is cut at (module docstring).
Bounds = tuple[float, float]
#: Most ways of splitting the runs among the groups for which a rank test's p is exact (an enumeration).
EXACT_ARRANGEMENTS = 20_000


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
    min_p: float = 0.0  # the smallest p this design (n_a and n_b runs) can give

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
        p = rank_p([va, vb])
        if math.isnan(p):
            p = float(stats.mannwhitneyu(vb, va, alternative="two-sided").pvalue)
    return RankComparison(
        measure=measure, a=a, b=b, n_a=int(va.size), n_b=int(vb.size),
        median_a=float(np.median(va)), median_b=float(np.median(vb)),
        mean_a=float(va.mean()), mean_b=float(vb.mean()),
        u=u, p_value=p, a12=float(a12), magnitude=magnitude(float(a12)), min_p=smallest_p([va.size, vb.size]),
    )


def _arrangements(sizes: Sequence[int]) -> int:
    """The ways of splitting sum(sizes) runs into groups of these sizes (a multinomial coefficient)."""
    total, ways = 0, 1
    for k in sizes:
        total += k
        ways *= math.comb(total, k)
    return ways


def _splits(sizes: Sequence[int]) -> np.ndarray:
    """Every way of giving sum(sizes) runs to groups of these sizes: an (arrangements, runs) array of group indices."""
    rows: list[list[int]] = []

    def fill(labels: list[int], free: tuple[int, ...], group: int) -> None:
        if group == len(sizes) - 1:
            for i in free:
                labels[i] = group
            rows.append(list(labels))
            return
        for chosen in combinations(free, sizes[group]):
            for i in chosen:
                labels[i] = group
            taken = set(chosen)
            fill(labels, tuple(i for i in free if i not in taken), group + 1)

    fill([0] * sum(sizes), tuple(range(sum(sizes))), 0)
    return np.asarray(rows, dtype=np.int64)


def rank_p(samples: Sequence[np.ndarray]) -> float:
    """The exact permutation p of the rank test across ``samples`` (mid-ranks for ties; two groups: two-sided
    Mann–Whitney, more: Kruskal–Wallis), or NaN when the runs split in more than EXACT_ARRANGEMENTS ways.

    The statistic is Σ R_i² / n_i over the groups' rank sums: the Kruskal–Wallis H up to constants that no
    rearrangement changes (with two groups, a monotone function of |U − n_a n_b / 2|); p is the share of all the
    rearrangements of the runs among the groups at least as extreme as the one observed."""
    sizes = [int(np.size(x)) for x in samples]
    if _arrangements(sizes) > EXACT_ARRANGEMENTS:
        return float("nan")
    ranks = stats.rankdata(np.concatenate([np.asarray(x, dtype=float) for x in samples]))
    splits = _splits(sizes)
    sums = np.stack([(splits == g) @ ranks for g in range(len(sizes))], axis=1)
    stat = (sums ** 2 / np.asarray(sizes, dtype=float)).sum(axis=1)
    observed = float(np.sum([r.sum() ** 2 / r.size for r in np.split(ranks, np.cumsum(sizes)[:-1])]))
    return float(np.mean(stat >= observed * (1 - 1e-12)))


def smallest_p(sizes: Sequence[int]) -> float:
    """The smallest p a rank test of groups of these sizes can give: the arrangements of the runs as extreme as the
    most extreme one, over all of them.  Relabelling two groups of the same size never changes the statistic, so at
    least (the product over the sizes of their multiplicity's factorial) arrangements are that extreme, and runs
    constant within each group, the groups apart, reach it: two groups of n give 2 / C(2n, n) (2 runs a regime:
    1/3); groups of 2 and 3, 1 / C(5, 2) = 0.1."""
    sizes = [int(k) for k in sizes]
    if len(sizes) < 2 or min(sizes) < 1:
        return 1.0
    same = math.prod(math.factorial(sizes.count(k)) for k in set(sizes))
    return min(1.0, same / _arrangements(sizes))


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
    min_p: float = 0.0  # the smallest p this design (the groups' sizes) can give

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
        h, p = float(res.statistic), rank_p(arrays)
        if math.isnan(p):
            p = float(res.pvalue)
    e2 = h / (n - 1) if n > 1 else 0.0
    return GroupComparison(measure=measure, groups=names, medians=tuple(float(np.median(a)) for a in arrays), n=n,
                           h=h, p_value=p, epsilon2=e2, magnitude=_epsilon_magnitude(e2),
                           min_p=smallest_p([a.size for a in arrays]))


def too_few_text(n: int) -> str:
    """Why a mean of ``n`` values has no interval (None of that below MIN_RUNS: '' from MIN_RUNS on)."""
    return "too few runs for an interval" if 0 < n < MIN_RUNS else ""


@dataclass(frozen=True)
class MeanInterval:
    """A sample's mean with its 95 % Student t interval: NaN below MIN_RUNS values (the text says why), the value
    itself when every value is the same (the text says so: no spread, so no interval to speak of)."""

    n: int
    mean: float
    low: float
    high: float
    #: The ends of the measure's range the t interval reached beyond and was cut at (module docstring), in order.
    clipped: tuple[float, ...] | list[float] = ()

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def clip_text(self) -> str:
        """'clipped at 0', 'clipped at 0 and 100', '' when the interval lies inside the measure's range."""
        return clip_words(self.clipped)

    def text(self, digits: int = 2, *, runs: bool = True) -> str:
        """'0.42 [0.31, 0.53] (n = 10)'; '0.07 (n = 2: too few runs for an interval)'; '0.00 (all 10 runs equal)'.
        ``runs=False`` leaves the count out where a column shows it."""
        if self.n == 0:
            return "–"
        m = f"{self.mean:.{digits}f}"
        if self.n < MIN_RUNS or math.isnan(self.low):
            return f"{m} (n = {self.n}: {too_few_text(self.n) or 'no interval'})" if runs else \
                f"{m} ({too_few_text(self.n) or 'no interval'})"
        if self.low == self.high == self.mean:
            return f"{m} (all {self.n} runs equal)"
        notes = [f"n = {self.n}"] * runs + [self.clip_text()] * bool(self.clipped)
        return f"{m} [{self.low:.{digits}f}, {self.high:.{digits}f}]" + (f" ({'; '.join(notes)})" if notes else "")


def _t_half_widths(sd: np.ndarray, n: int) -> np.ndarray:
    return np.asarray(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n), dtype=np.float64)


def clip(low: np.ndarray, high: np.ndarray, bounds: Bounds | None) -> tuple[np.ndarray, np.ndarray, tuple[float, ...]]:
    """Intervals' ends cut at ``bounds`` (module docstring; NaN stays NaN), and the bounds any end was cut at."""
    low, high = np.asarray(low, dtype=np.float64), np.asarray(high, dtype=np.float64)
    if bounds is None:
        return low, high, ()
    lo, hi = bounds
    cut = tuple(float(b) for b, out in ((lo, low < lo), (hi, high > hi)) if np.any(out))
    return np.where(low < lo, lo, low), np.where(high > hi, hi, high), cut


def clip_words(cut: Sequence[float]) -> str:
    """What :func:`clip` did, in words: 'clipped at 0', 'clipped at 0 and 100'; '' when it cut nothing."""
    return "clipped at " + " and ".join(f"{b:g}" for b in cut) if cut else ""


def mean_interval(values: Sequence[float] | np.ndarray, *, seed: int = 0, bounds: Bounds | None = None) -> MeanInterval:
    """The mean of ``values`` (NaNs left out) and its 95 % Student t interval, mean ± t(0.975, n − 1) s / √n; NaN
    below MIN_RUNS values (module docstring: why, measured); cut at ``bounds``, the measure's possible range, where
    it reaches beyond (``clipped`` says which).  ``seed`` is not used (the interval is not drawn); kept for the
    callers written when it was a bootstrap."""
    x = np.asarray([v for v in values if not np.isnan(v)], dtype=np.float64)
    if x.size == 0:
        return MeanInterval(0, float("nan"), float("nan"), float("nan"))
    if x.size < MIN_RUNS:
        return MeanInterval(int(x.size), float(x.mean()), float("nan"), float("nan"))
    if np.all(x == x[0]):
        return MeanInterval(int(x.size), float(x[0]), float(x[0]), float(x[0]))
    half = float(_t_half_widths(np.asarray(x.std(ddof=1)), x.size))
    m = float(x.mean())
    low, high, cut = clip(np.asarray(m - half), np.asarray(m + half), bounds)
    return MeanInterval(int(x.size), m, float(low), float(high), cut)


def mean_intervals(runs: np.ndarray, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per column of ``runs`` (runs x generations, NaN where a run has no value): the mean and the 95 % interval of
    :func:`mean_interval`, (mean, low, high) arrays; column j equals ``mean_interval(runs[:, j])``, so a band ends
    where the report's interval at the last generation is (a bounded measure's band: :func:`clip` it)."""
    x = np.asarray(runs, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"runs x generations expected, got shape {x.shape}")
    n_cols = x.shape[1]
    mean, low, high = np.full(n_cols, np.nan), np.full(n_cols, np.nan), np.full(n_cols, np.nan)
    whole = ~np.isnan(x).any(axis=0)
    if x.shape[0] >= MIN_RUNS and whole.any():  # the columns without NaN at once
        w = x[:, whole]
        m = w.mean(axis=0)
        half = _t_half_widths(w.std(axis=0, ddof=1), w.shape[0])
        same = np.all(w == w[0], axis=0)
        half[same] = 0.0
        m[same] = w[0, same]
        mean[whole], low[whole], high[whole] = m, m - half, m + half
    elif whole.any():
        mean[whole] = x[:, whole].mean(axis=0)
    for j in np.flatnonzero(~whole):
        one = mean_interval(x[:, j], seed=seed)
        mean[j], low[j], high[j] = one.mean, one.low, one.high
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


def design_floor(min_p: float, runs: str) -> str:
    """What the smallest p a design can give means, for the text beside its p ('' when it is below 0.001, too
    small to matter); ``runs`` names the design ('2 and 2 runs')."""
    if min_p < 0.001:
        return ""
    if min_p >= 0.05:
        return (f"with {runs} no p below {format_p(min_p)} is possible, so this test cannot detect a difference at "
                "the 5 % level whatever the runs score")
    return f"the smallest p possible with {runs} is {format_p(min_p)}"
