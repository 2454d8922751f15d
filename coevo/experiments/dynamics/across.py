"""``coevo dynamics DIR`` over a directory of runs (a comparison, a study, or any folder of run directories): each
run's dynamics through the replicate runner (``--jobs`` here, ``--cluster`` on Dask), then a summary across them.

The summary, in ``DIR/dynamics/``, is per pair (learner, partner) and per group of runs of the same regime and
partner model: for each generation ``g``, each run's master-tournament score of the learner's version in play at
``g`` (the last published by then): its mean payoff against the partner's version in play at every generation, each
partner version weighted by the generations it was in play (Floreano & Nolfi's tournament of every generation
against every generation; the generations before a partner's first published version have none, and are left
out), then the mean across the runs with a 95 % t interval (none below three runs).  ``summary-LEARNER-PARTNER.csv``
and ``.png``; a rising line is an arms race (later generations beat more of the other side's history), a flat or
falling one no progress or forgetting.  ``rise.json`` says it per pair and group in numbers: each run's score at
its last generation minus its first, paired within the run, averaged across the runs with a 95 % t interval, and
how many runs rose.
"""

from __future__ import annotations

import csv
import functools
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coevo.errors import ConfigError, RunDirError
from coevo.experiments.dynamics.matrix import DONE, interval
from coevo.replicates.replicate import Replicate

__all__ = ["find_runs", "replicates", "summarise"]



def find_runs(root: Path) -> list[Path]:
    """Every run directory under ``root`` (a folder holding run.json), hidden folders (staged copies) left out."""
    runs = [p.parent for p in Path(root).rglob("run.json")
            if not any(part.startswith(".") for part in p.parent.relative_to(root).parts)]
    if not runs:
        raise RunDirError(f"{str(root)!r} is neither a run directory nor a folder of runs (no run.json under it)")
    return sorted(runs)


def _played(rel: str, wanted: dict[str, Any], root: Path) -> bool:
    """Does the run ``rel`` under ``root`` hold dynamics played as ``wanted`` asks?"""
    f = Path(root) / rel / "dynamics" / DONE
    try:
        return {k: v for k, v in json.loads(f.read_text(encoding="utf-8")).items() if k in wanted} == wanted
    except (OSError, ValueError):
        return False


def _argv(rel: str, wanted: dict[str, Any], root: Path) -> list[str]:
    span = wanted["generations"]
    return [sys.executable, "-m", "coevo", "dynamics", rel, "--episodes", str(wanted["episodes"]), "--seed",
            str(wanted["seed"]), "--generations", f"{span[0]}:{span[1]}", "--quiet"]


def replicates(root: Path, runs: Sequence[Path], wanted: Callable[[Path], dict[str, Any]]) -> list[Replicate]:
    """One replicate per run: ``coevo dynamics RUN`` with what ``wanted(run)`` says (episodes, seed, generations)."""
    out = []
    for run in runs:
        rel = str(run.relative_to(root))
        w = wanted(run)
        # weight 2, a live run's: one process, but busy on a whole core, so --jobs N plays N at a time, as its help
        # says (weight 1, an offline learner's, played 2N)
        out.append(Replicate(name="dynamics-" + rel.replace("/", "-"), output=f"{rel}/dynamics",
                             finished=functools.partial(_played, rel, w), command=functools.partial(_argv, rel, w),
                             inputs=(rel,), weight=2))
    return out


@dataclass(frozen=True)
class _Scores:
    group: str
    learner: str
    partner: str
    by_generation: dict[int, float]  # the learner's version in play at g: its generation-weighted master score


def _in_play(generations: Sequence[int], span: tuple[int, int]) -> list[int | None]:
    """For each generation of ``span`` (from 1), the index of the version in play (the last published by then), or
    None."""
    out: list[int | None] = []
    for g in range(max(1, span[0]), span[1] + 1):
        before = [i for i, x in enumerate(generations) if x <= g]
        out.append(before[-1] if before else None)
    return out


def _scores(run: Path, group: str, span: tuple[int, int]) -> list[_Scores]:
    out = []
    for f in sorted((run / "dynamics").glob("ciao-*.csv")):
        rows = list(csv.DictReader(open(f, encoding="utf-8")))
        if not rows:
            continue
        cols = [k for k in rows[0] if "@" in k]
        learner, partner = f.stem[len("ciao-"):].split("-", 1)
        fitness = np.array([[float(r[c]) for c in cols] for r in rows])
        col_in_play = [i for i in _in_play([int(c.split("@")[1]) for c in cols], span) if i is not None]
        weights = np.bincount(col_in_play, minlength=len(cols)).astype(float)
        score = fitness @ weights / weights.sum() if weights.sum() else np.full(len(rows), np.nan)
        rows_in_play = _in_play([int(r["generation"]) for r in rows], span)
        out.append(_Scores(group, learner, partner,
                           {max(1, span[0]) + k: float(score[i]) for k, i in enumerate(rows_in_play) if i is not None}))
    return out


def summarise(root: Path, runs: Sequence[Path], groups: dict[Path, str], spans: dict[Path, tuple[int, int]],
              out: Path) -> list[str]:
    """The summary files in ``out`` (a staged folder); their names."""
    from coevo.rundir.layout import write_csv, write_json

    scores = [s for run in runs for s in _scores(run, groups[run], spans[run])]
    if not scores:
        raise ConfigError(f"{root}: no run under it has a matrix to summarise")
    written = []
    rises = []
    for learner, partner in sorted({(s.learner, s.partner) for s in scores}):
        rows = []
        for group in sorted({s.group for s in scores}):
            mine = [s for s in scores if (s.learner, s.partner, s.group) == (learner, partner, group)]
            for g in sorted({g for s in mine for g in s.by_generation}):
                x = np.array([s.by_generation[g] for s in mine if g in s.by_generation])
                lo, hi = interval(x)
                rows.append({"group": group, "generation": g, "runs": len(x), "mean": round(float(x.mean()), 6),
                             "low95": lo, "high95": hi})
            rises.append({"learner": learner, "partner": partner, "group": group, **_rise(mine)})
        name = f"summary-{learner}-{partner}"
        write_csv(out / f"{name}.csv", rows)
        _draw(out / f"{name}.png", learner, partner, rows)
        written += [f"{name}.csv", f"{name}.png"]
    write_json(out / "rise.json", {"rise": rises})
    write_json(out / "runs.json", {"runs": [str(r.relative_to(root)) for r in runs],
                                   "groups": {str(r.relative_to(root)): groups[r] for r in runs}})
    return [*written, "rise.json"]


def _rise(mine: Sequence[_Scores]) -> dict[str, Any]:
    """Each run's master score at the last generation minus at the first it has one (the same two generations in
    every run of the group: the latest first and the earliest last), then across the runs: their mean with a 95 % t
    interval (none below three runs) and how many rose, fell or stayed.  Paired within each run, so the interval is
    of the rise itself, not of two levels whose intervals overlap."""
    first = max(min(s.by_generation) for s in mine if s.by_generation)
    last = min(max(s.by_generation) for s in mine if s.by_generation)
    d = np.array([s.by_generation[last] - s.by_generation[first] for s in mine
                  if first in s.by_generation and last in s.by_generation])
    lo, hi = interval(d)
    return {"first": first, "last": last, "runs": len(d), "mean": round(float(d.mean()), 6) if len(d) else None,
            "low95": lo, "high95": hi, "rose": int((d > 0).sum()), "fell": int((d < 0).sum()),
            "same": int((d == 0).sum())}


def _draw(path: Path, learner: str, partner: str, rows: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=90)
    for group in dict.fromkeys(r["group"] for r in rows):
        mine = [r for r in rows if r["group"] == group]
        n = max(r["runs"] for r in mine)
        line, = ax.plot([r["generation"] for r in mine], [r["mean"] for r in mine], label=f"{group} ({n} runs)")
        band = [r for r in mine if r["low95"] is not None]
        if band:
            ax.fill_between([r["generation"] for r in band], [r["low95"] for r in band], [r["high95"] for r in band],
                            color=line.get_color(), alpha=0.2)
    ax.set_xlabel(f"generation (the {learner} version in play then)")
    ax.set_ylabel(f"{learner}'s mean payoff")
    ax.set_title(f"master tournament across runs: {learner} against every generation of {partner}; mean, 95 % "
                 "interval", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
