"""Comparing two regimes on one measure: a rank test and an effect size.

The runs of a regime are few (10 in the report) and their measures are bounded
and often tied at zero (a starved Docking agent docks in 0 % of episodes), so we
use the two-sided Mann–Whitney U test (scipy's, with its tie correction) and the
Vargha–Delaney A effect size, the probability that a random run of regime B
scores higher than a random run of regime A (ties count half); 0.5 is no effect,
and 0.71 / 0.64 / 0.56 are the customary large / medium / small thresholds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats

__all__ = ["RankComparison", "compare_samples", "magnitude"]


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
