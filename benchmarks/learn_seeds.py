"""Learn Tracking and Docking at the report's parameters over several seeds; summarise against the targets.

    python benchmarks/learn_seeds.py --seeds 5 [--first-seed 100] [--jobs 1] [--out runs/learn-seeds]

Each run is a real ``coevo learn`` subprocess with the defaults (each behaviour starts
from its shipped direction-only rule set; Docking trains on fresh random starts).  The
summary (time per run, best fitness, Quality Tracking for Tracking, docking from random
starts for Docking) is printed as a Markdown table, with the medians against the
learning targets of the issue "The report's Table 1, reproduced":

- Docking from random starts, median >= 60 %;
- Quality Tracking with the always-Track Executive, median > 60 %;
- every run under a minute on one core (run with ``--jobs 1`` on an idle machine for the timing).

Extra ``coevo learn`` arguments go after ``--``, e.g. ``-- --initial random``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

TARGETS = {"docking": ("docking_from_random_starts", 60.0), "tracking": ("quality_tracking", 60.0)}


def run(behaviour: str, seed: int, out: Path, extra: list[str]) -> dict[str, object]:
    d = out / f"{behaviour}-seed{seed}"
    subprocess.run([sys.executable, "-m", "coevo", "learn", "--behaviour", behaviour, "--seed", str(seed),
                    "--out", str(d), "--quiet", *extra], check=True, stdout=subprocess.DEVNULL)
    m = json.loads((d / "measures.json").read_text())
    t = json.loads((d / "timing.json").read_text())
    return {"behaviour": behaviour, "seed": seed, "seconds": t["seconds"], **m}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--behaviours", nargs="+", default=["docking", "tracking"], choices=sorted(TARGETS))
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", default="runs/learn-seeds")
    ap.add_argument("extra", nargs="*", help="arguments passed on to coevo learn (after --)")
    args = ap.parse_args()
    if args.seeds < 1 or args.jobs < 1:
        ap.error(f"--seeds and --jobs must be at least 1 (got {args.seeds}, {args.jobs})")
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=False)
    except FileExistsError:
        ap.error(f"--out {out} already exists")
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    jobs = [(b, s) for b in args.behaviours for s in seeds]
    with ThreadPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(lambda j: run(j[0], j[1], out, args.extra), jobs))
    (out / "summary.json").write_text(json.dumps(rows, indent=2))
    print("| behaviour | seed | seconds | best fitness | Quality Tracking % | docking from random starts % |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        dock = r.get("docking_from_random_starts", float("nan"))
        print(f"| {r['behaviour']} | {r['seed']} | {r['seconds']:.0f} | {r['best_fitness']:.3f} "
              f"| {r['quality_tracking']:.1f} | {dock:.1f} |")
    for b in args.behaviours:
        rs = [r for r in rows if r["behaviour"] == b]
        key, target = TARGETS[b]
        med = statistics.median(r[key] for r in rs)
        slowest = max(r["seconds"] for r in rs)
        verdict = "met" if med > target or (b == "docking" and med >= target) else "MISSED"
        print(f"{b}: median {key} {med:.1f} % (target {'≥' if b == 'docking' else '>'} {target:.0f} %: {verdict}); "
              f"median time {statistics.median(r['seconds'] for r in rs):.0f} s, slowest {slowest:.0f} s "
              f"(target < 60 s on one core: {'met' if slowest < 60 else 'MISSED'})")


if __name__ == "__main__":
    main()
