"""Learn Tracking and Docking at the paper's parameters over several seeds; summarise.

    python benchmarks/learn_seeds.py --seeds 5 --jobs 2 --out runs/learn-seeds

Each run is a real ``coevo learn`` subprocess; the summary (time per run, best
fitness, Quality Tracking for Tracking, docking from random starts for Docking)
is printed as a Markdown table and written to OUT/summary.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path


def run(behaviour: str, seed: int, out: Path) -> dict[str, object]:
    d = out / f"{behaviour}-seed{seed}"
    subprocess.run([sys.executable, "-m", "coevo", "learn", "--behaviour", behaviour, "--seed", str(seed),
                    "--out", str(d), "--quiet"], check=True, stdout=subprocess.DEVNULL)
    m = json.loads((d / "measures.json").read_text())
    t = json.loads((d / "timing.json").read_text())
    return {"behaviour": behaviour, "seed": seed, "seconds": t["seconds"], **m}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="runs/learn-seeds")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=False)
    jobs = [(b, s) for b in ("tracking", "docking") for s in range(args.seeds)]
    with ThreadPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(lambda j: run(j[0], j[1], out), jobs))
    (out / "summary.json").write_text(json.dumps(rows, indent=2))
    print("| behaviour | seed | seconds | best fitness | Quality Tracking % | docking from random starts % |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        dock = r.get("docking_from_random_starts", float("nan"))
        print(f"| {r['behaviour']} | {r['seed']} | {r['seconds']:.0f} | {r['best_fitness']:.3f} | {r['quality_tracking']:.1f} | {dock:.1f} |")
    for b in ("tracking", "docking"):
        rs = [r for r in rows if r["behaviour"] == b]
        key = "quality_tracking" if b == "tracking" else "docking_from_random_starts"
        print(f"{b}: median {key} {statistics.median(r[key] for r in rs):.1f} %, median time {statistics.median(r['seconds'] for r in rs):.0f} s")


if __name__ == "__main__":
    main()
