"""A study's statistics beyond a comparison's: proportions with intervals, the Holm correction, and how small a
difference between two levels the data could have shown.

**Proportions: the Wilson score interval.**  A Table 1 class is k of n runs with n from 10 to a few hundred and k
often 0 or n (every Mutual run starved).  The Wald interval p ± 1.96 √(p(1−p)/n) collapses to a point there; the
exact (Clopper–Pearson) interval never undercovers but is conservative: wider than it needs to be, its actual
coverage well above 95 % at small n.  Wilson's interval keeps close to the nominal 95 % on average for every n and p
and is never degenerate at 0 or n (Brown, Cai & DasGupta 2001, "Interval estimation for a binomial proportion",
recommend it for small n); for 9 of 10 it is [0.596, 0.982], for 10 of 10 [0.722, 1]: the two overlap, which is
the issue's "9 of 10 and 10 of 10 cannot be told apart" in numbers.

**Many tests: Holm's step-down correction** controls the family-wise error rate at 5 % under any dependence between
the tests (they share runs), and is uniformly more powerful than Bonferroni.

**Resolution**: for two levels, a 95 % interval of the difference between them: of two shares, Newcombe's hybrid
score interval (his method 10, built from the two Wilson intervals, so it stays sensible at 0 of n and n of n);
of two means, Welch's t interval (unequal variances; none when either level has fewer than
:data:`~coevo.experiments.compare.stats.MIN_RUNS` runs, or neither has any spread: the percentile bootstrap used
before covered far less than 95 % at the study's usual 2–10 runs a level, see :mod:`coevo.experiments.compare.stats`).
A difference larger than the interval's farthest end would very likely have been seen.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

from coevo.experiments.compare.stats import MIN_RUNS

__all__ = ["Z95", "Proportion", "wilson", "Difference", "difference_interval", "share_difference"]

#: The standard normal's 97.5 % quantile: a two-sided 95 % interval.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Proportion:
    """k of n, with its 95 % Wilson interval (NaN when n is 0)."""

    k: int
    n: int
    low: float
    high: float

    @property
    def p(self) -> float:
        return self.k / self.n if self.n else float("nan")

    def as_dict(self) -> dict[str, float | int]:
        return {**asdict(self), "p": self.p}

    def text(self) -> str:
        if self.n == 0:
            return "–"
        return f"{self.k}/{self.n} [{100 * self.low:.0f}–{100 * self.high:.0f} %]"


def wilson(k: int, n: int, *, z: float = Z95) -> Proportion:
    """The Wilson score interval of k successes in n trials: the p whose score test does not reject at level z,
    (p̂ + z²/2n ± z √(p̂(1−p̂)/n + z²/4n²)) / (1 + z²/n)."""
    if n < 0 or k < 0 or k > n:
        raise ValueError(f"need 0 <= k <= n, got k={k}, n={n}")
    if n == 0:
        return Proportion(0, 0, float("nan"), float("nan"))
    p = k / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if k == 0 else max(0.0, centre - half)  # exactly 0 and 1 at the ends, not a rounding away from them
    high = 1.0 if k == n else min(1.0, centre + half)
    return Proportion(k, n, low, high)


@dataclass(frozen=True)
class Difference:
    """mean(b) − mean(a) with a 95 % interval (NaN when it cannot be given: :func:`difference_interval`)."""

    a: str
    b: str
    diff: float
    low: float
    high: float

    @property
    def bound(self) -> float:
        """The largest difference the interval allows, either way."""
        return max(abs(self.low), abs(self.high))

    def as_dict(self) -> dict[str, float | str]:
        return asdict(self)


def difference_interval(a: str, xa: Sequence[float], b: str, xb: Sequence[float], *, seed: int = 0) -> Difference:
    """mean(xb) − mean(xa) and Welch's 95 % t interval, d ± t(0.975, ν) √(s_a²/n_a + s_b²/n_b) with the
    Welch–Satterthwaite ν; NaN ends when either sample has fewer than MIN_RUNS values or neither varies (nothing to
    estimate the spread from).  ``seed`` is not used (nothing is drawn)."""
    va = np.asarray([v for v in xa if not math.isnan(v)], dtype=np.float64)
    vb = np.asarray([v for v in xb if not math.isnan(v)], dtype=np.float64)
    d = float(vb.mean() - va.mean()) if va.size and vb.size else float("nan")
    if va.size < MIN_RUNS or vb.size < MIN_RUNS:
        return Difference(a, b, d, float("nan"), float("nan"))
    qa, qb = va.var(ddof=1) / va.size, vb.var(ddof=1) / vb.size
    if qa + qb == 0:
        return Difference(a, b, d, float("nan"), float("nan"))
    nu = (qa + qb) ** 2 / (qa ** 2 / (va.size - 1) + qb ** 2 / (vb.size - 1))
    half = float(stats.t.ppf(0.975, nu)) * math.sqrt(qa + qb)
    return Difference(a, b, d, d - half, d + half)


def share_difference(a: str, ka: int, na: int, b: str, kb: int, nb: int) -> Difference:
    """kb/nb − ka/na and Newcombe's hybrid score 95 % interval (Newcombe 1998, method 10): with Wilson intervals
    (la, ua), (lb, ub), the difference d minus √((pb − lb)² + (ua − pa)²) to d plus √((ub − pb)² + (pa − la)²)."""
    wa, wb = wilson(ka, na), wilson(kb, nb)
    if na == 0 or nb == 0:
        return Difference(a, b, float("nan"), float("nan"), float("nan"))
    d = wb.p - wa.p
    low = d - math.sqrt((wb.p - wb.low) ** 2 + (wa.high - wa.p) ** 2)
    high = d + math.sqrt((wb.high - wb.p) ** 2 + (wa.p - wa.low) ** 2)
    return Difference(a, b, d, low, high)
