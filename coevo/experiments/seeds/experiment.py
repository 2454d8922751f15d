"""Tracking and Docking learned offline (``coevo learn``) at the report's parameters over seeds, against the
learning targets (``coevo seeds``, ``--task fuel``):

- Docking from random starts, median >= 75 % (docs/docking-learning.md; the first target was 60 %);
- Quality Tracking with the always-Track Executive, median > 60 %;
- every run under a minute on one core (meaningful with ``--jobs 1`` on an idle machine).

Each replicate is one ``coevo learn`` into ``OUT/runs/BEHAVIOUR-seedN``, run by :mod:`coevo.replicates`
(``--jobs`` here, or ``--cluster``); the report is ``report.md``, ``summary.json``, ``seeds.csv`` and
``seeds.png``.
"""

from __future__ import annotations

import csv
import json
import shutil
import statistics
import sys
from functools import partial
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.replicates.replicate import Replicate
from coevo.rundir.layout import not_a_file, read_json

__all__ = ["TARGETS", "REPORT_FILES", "problems", "replicates", "write_report"]

TARGETS = {"docking": ("docking_from_random_starts", 75.0), "tracking": ("quality_tracking", 60.0)}


def _name(behaviour: str, seed: int) -> str:
    return f"{behaviour}-seed{seed}"


def _argv(behaviour: str, seed: int, extra: tuple[str, ...], root: Path) -> list[str]:
    """The ``coevo learn`` of this seed, its folder removed first when it is there but not finished (a copy torn when
    it came back from a cluster's worker): ``coevo learn`` refuses a folder that is not empty, and what is there is
    not a run."""
    d = Path(root) / "runs" / _name(behaviour, seed)
    if d.is_dir() and not _finished(behaviour, seed, root):
        shutil.rmtree(d)
    return [sys.executable, "-m", "coevo", "learn", "--behaviour", behaviour, "--seed", str(seed), "--out", str(d),
            "--quiet", *extra]


def _finished(behaviour: str, seed: int, root: Path) -> bool:
    d = Path(root) / "runs" / _name(behaviour, seed)
    return (d / "measures.json").exists() and (d / "timing.json").exists()


def replicates(behaviours: list[str], seeds: list[int], extra: list[str], *, weight: int = 1) -> list[Replicate]:
    """One ``coevo learn`` per behaviour and seed.  An offline learner keeps one core busy: half a live run's slot
    (weight 1) where ``--jobs`` counts live runs, as in a study; ``coevo seeds`` counts learners (weight 2)."""
    return [Replicate(name=_name(b, s), output=f"runs/{_name(b, s)}", finished=partial(_finished, b, s),
                      command=partial(_argv, b, s, tuple(extra)), weight=weight)
            for b in behaviours for s in seeds]


#: What the report writes in ``--out``.
REPORT_FILES = ("report.md", "summary.json", "seeds.csv", "seeds.png")


def problems(out: Path, behaviours: list[str], seeds: list[int]) -> list[str]:
    """What would stop ``coevo seeds --resume`` in ``out``, one line a problem, found by reading what it reads and
    changing nothing: each finished run's measures.json and timing.json (JSON objects, the report's), and that only
    files stand where the report is written."""
    found = not_a_file([Path(out) / f for f in REPORT_FILES])
    for b in behaviours:
        for s in seeds:
            d = Path(out) / "runs" / _name(b, s)
            if not (d.exists() or d.is_symlink()):
                continue
            if not d.is_dir():
                found.append(f"{d} is not a directory")
            elif _finished(b, s, out):
                for f in (d / "measures.json", d / "timing.json"):
                    try:
                        read_json(f, what="coevo learn directory")
                    except RunDirError as exc:
                        found.append(str(exc))
    return found


def _rows(out: Path, behaviours: list[str], seeds: list[int]) -> list[dict[str, Any]]:
    rows = []
    for b in behaviours:
        for s in seeds:
            d = out / "runs" / _name(b, s)
            if _finished(b, s, out):
                m = json.loads((d / "measures.json").read_text())
                t = json.loads((d / "timing.json").read_text())
                rows.append({"behaviour": b, "seed": s, "seconds": t["seconds"], **m})
    return rows


def write_report(out: Path, behaviours: list[str], seeds: list[int], *, elapsed: float | None,
                 caveat: str = "") -> dict[str, Any]:
    """report.md, summary.json, seeds.csv and seeds.png from the finished runs in ``out``; returns the verdicts.
    ``caveat``: a line under the verdicts (settings below the report's, :func:`coevo.experiments.common.below_report`)."""
    rows = _rows(out, behaviours, seeds)
    verdicts = []
    for b in behaviours:
        rs = [r for r in rows if r["behaviour"] == b]
        if not rs:
            verdicts.append({"behaviour": b, "runs": 0, "text": f"{b}: no finished runs"})
            continue
        key, target = TARGETS[b]
        med = statistics.median(r[key] for r in rs)
        slowest = max(r["seconds"] for r in rs)
        met = med > target or (b == "docking" and med >= target)
        verdicts.append({"behaviour": b, "runs": len(rs), "measure": key, "median": med, "target": target, "met": met,
                         "median_seconds": statistics.median(r["seconds"] for r in rs), "slowest_seconds": slowest,
                         "text": f"{b}: median {key} {med:.1f} % (target {'≥' if b == 'docking' else '>'} {target:.0f} %: "
                                 f"{'met' if met else 'MISSED'}); median time "
                                 f"{statistics.median(r['seconds'] for r in rs):.0f} s, slowest {slowest:.0f} s "
                                 f"(target < 60 s on one core: {'met' if slowest < 60 else 'MISSED'})"})
    results = {"behaviours": behaviours, "seeds": seeds, "runs": rows, "verdicts": verdicts, "caveat": caveat or None,
               "seconds": elapsed,
               "runs_expected": len(behaviours) * len(seeds), "runs_finished": len(rows)}
    (out / "summary.json").write_text(json.dumps(results, indent=2))
    cols = ["behaviour", "seed", "seconds", "best_fitness", "quality_tracking", "docking_from_random_starts"]
    with open(out / "seeds.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    _plot(out / "seeds.png", rows, behaviours)
    lines = ["# Learning targets over seeds", "",
             f"{len(rows)} of {results['runs_expected']} runs finished" + (f" in {elapsed:.0f} s" if elapsed else "") + ".",
             "", "## Verdicts", "", *[f"- {v['text']}" for v in verdicts], *([f"\n{caveat}"] if caveat else []), "",
             "![seeds.png](seeds.png)", "",
             "## Runs", "", "| behaviour | seed | seconds | best fitness | Quality Tracking % | docking from random starts % |",
             "|---|---|---|---|---|---|"]
    for r in rows:  # a measure a behaviour's run does not take (Tracking's docking from random starts) is "–"
        lines.append(f"| {r['behaviour']} | {r['seed']} | {r['seconds']:.0f} | {r['best_fitness']:.3f} "
                     f"| {_cell(r.get('quality_tracking'))} | {_cell(r.get('docking_from_random_starts'))} |")
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return results


def _cell(value: Any) -> str:
    """A percentage to one decimal, or "–" when there is none (absent, or NaN)."""
    return "–" if not isinstance(value, (int, float)) or value != value else f"{value:.1f}"


def _plot(path: Path, rows: list[dict[str, Any]], behaviours: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")  # files only, no display needed
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig, axes = plt.subplots(1, len(behaviours), figsize=(4 * len(behaviours), 3.2), squeeze=False)
    for ax, b in zip(axes[0], behaviours):
        key, target = TARGETS[b]
        vals = [r[key] for r in rows if r["behaviour"] == b]
        ax.scatter(range(len(vals)), vals, color="tab:blue")
        ax.axhline(target, color="tab:red", ls="--", label=f"target {target:.0f} %")
        if vals:
            ax.axhline(statistics.median(vals), color="tab:blue", ls=":", label="median")
        ax.set(title=b, xlabel="seed (run)", ylabel=f"{key} %", ylim=(0, 100))
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # seeds are whole numbers
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
