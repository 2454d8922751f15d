"""Is one learning variant better than another over the same seeds?  The test behind docs/docking-learning.md.

    python benchmarks/paired_seeds.py BASE_DIR[,BASE_DIR...] VARIANT_DIR[,VARIANT_DIR...] [...]
        [--behaviour docking] [--measure docking_from_random_starts]

Each argument is one variant: one or more ``coevo seeds`` output folders (comma-separated, e.g. seeds 0-9 and
10-19 run apart), read from their ``summary.json``.  Runs are matched by seed, and only seeds every variant has
count.  For each variant after the first it prints the median and mean of ``--measure``, and against the first
(paired by seed): the mean difference with its standard error, how many seeds it wins, the sign test's and
Wilcoxon's signed-rank p-values (two-sided, scipy).

One configuration of Docking spreads over 25-75 % across seeds (a standard deviation of ~12 points), so a
difference of medians over ten seeds says little; a paired test over the same seeds is what a choice should
rest on.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from pathlib import Path


def load(spec: str, behaviour: str, measure: str) -> dict[int, float]:
    """seed -> ``measure`` over the ``coevo seeds`` folders in ``spec`` (comma-separated)."""
    out: dict[int, float] = {}
    for part in spec.split(","):
        if not part.strip():
            raise SystemExit(f"paired_seeds: an empty folder name in {spec!r}")
        path = Path(part) / "summary.json"
        try:
            runs = json.loads(path.read_text())["runs"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise SystemExit(f"paired_seeds: {path} is not a finished `coevo seeds` summary ({exc})") from None
        for r in runs:
            if r.get("behaviour") == behaviour and measure in r:
                out[int(r["seed"])] = float(r[measure])
    if not out:
        raise SystemExit(f"paired_seeds: no {behaviour} run with {measure!r} in {spec}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("variants", nargs="+", help="BASE then the variants: coevo seeds folders, comma-joined per variant")
    ap.add_argument("--behaviour", default="docking")
    ap.add_argument("--measure", default="docking_from_random_starts")
    a = ap.parse_args(argv)
    if len(a.variants) < 2:
        ap.error("give a base and at least one variant")
    from scipy import stats  # only here: the module's help stays light

    data = [load(v, a.behaviour, a.measure) for v in a.variants]
    seeds = sorted(set.intersection(*(set(d) for d in data)))
    if len(seeds) < 2:
        raise SystemExit(f"paired_seeds: the variants share {len(seeds)} seed(s); need 2 or more")
    base = [data[0][s] for s in seeds]
    print(f"{len(seeds)} seeds in common ({seeds[0]}-{seeds[-1]}); {a.measure}, {a.behaviour}")
    print(f"{'variant':40s} {'median':>7s} {'mean':>6s} {'diff':>6s} {'se':>5s} {'wins':>6s} {'sign p':>7s} {'Wilcoxon p':>10s}")
    print(f"{a.variants[0][:40]:40s} {statistics.median(base):7.1f} {statistics.mean(base):6.1f}")
    for spec, d in zip(a.variants[1:], data[1:]):
        v = [d[s] for s in seeds]
        diff = [x - y for x, y in zip(v, base)]
        se = statistics.stdev(diff) / math.sqrt(len(diff))
        wins, losses = sum(x > 0 for x in diff), sum(x < 0 for x in diff)
        sign_p = stats.binomtest(wins, wins + losses).pvalue if wins + losses else 1.0
        wil_p = stats.wilcoxon(v, base).pvalue if any(diff) else 1.0
        print(f"{spec[:40]:40s} {statistics.median(v):7.1f} {statistics.mean(v):6.1f} {statistics.mean(diff):+6.1f} "
              f"{se:5.1f} {wins:3d}/{len(seeds):<2d} {sign_p:7.3f} {wil_p:10.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
