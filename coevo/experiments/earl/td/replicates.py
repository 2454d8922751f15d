"""``coevo td-baseline``'s runs as replicates for :mod:`coevo.replicates` (``--jobs`` here, or ``--cluster``).

Per task: one replicate per GA seed (``parts/TASK/ga-seedN.json``); then, after all of them, the TD runs
(one batched world for every seed, at the GA runs' mean robot-steps: ``parts/TASK/td.json``) and one more per
variant (``parts/TASK/td-VARIANT.json``).  Each piece is the function :func:`~.runs.run_task` runs in turn,
so :func:`collect` gives the same results, the seconds apart (tested).  A finished piece is kept by ``--resume``.
"""

from __future__ import annotations

import json
import time
from functools import partial
from pathlib import Path
from typing import Any

from coevo.experiments.earl.td.runs import (
    checkpoint_marks,
    run_ga,
    run_td,
    task_results,
    variant_specs,
)
from coevo.experiments.earl.td.spec import TDSpec
from coevo.replicates.replicate import Replicate

__all__ = ["replicates", "collect", "timing", "TARGET_SECONDS"]

#: The issue's target: one task's GA and main TD runs under 5 minutes (the variants timed apart).
TARGET_SECONDS = 300


def _ga_file(task: str, seed: int) -> str:
    return f"parts/{task}/ga-seed{seed}.json"


def _td_file(task: str, variant: str | None) -> str:
    return f"parts/{task}/td.json" if variant is None else f"parts/{task}/td-{variant}.json"


def _write(root: Path, rel: str, data: dict[str, Any]) -> None:
    from coevo.rundir.layout import write_json

    f = Path(root) / rel
    f.parent.mkdir(parents=True, exist_ok=True)
    write_json(f, data)


def run_ga_part(root: Path, *, spec: TDSpec, seed: int) -> None:
    """One GA run of the task (a replicate's function)."""
    t0 = time.perf_counter()
    curve = run_ga(spec, seed)
    _write(root, _ga_file(spec.task, seed), {"curve": curve.as_dict(), "wall": time.perf_counter() - t0})


def run_td_part(root: Path, *, spec: TDSpec, variant: str | None) -> None:
    """The task's TD runs (or a variant's) at the GA runs' mean robot-steps (a replicate's function)."""
    steps = [json.loads((Path(root) / _ga_file(spec.task, spec.seed + i)).read_text())["curve"]["robot_steps"]
             for i in range(spec.seeds)]
    marks = checkpoint_marks(spec, steps)
    td_spec = spec if variant is None else variant_specs(spec, (variant,))[variant]
    t0 = time.perf_counter()
    curves = run_td(td_spec, marks)
    _write(root, _td_file(spec.task, variant), {"marks": marks, "curves": [c.as_dict() for c in curves],
                                                  "wall": time.perf_counter() - t0})


def _exists(rel: str, root: Path) -> bool:
    return (Path(root) / rel).exists()


def replicates(specs: list[tuple[TDSpec, tuple[str, ...]]]) -> list[Replicate]:
    """Every task's GA runs, then its TD run and variants after them (each one core: weight 1)."""
    reps = []
    for spec, variants in specs:
        t, seeds = spec.task, [spec.seed + i for i in range(spec.seeds)]
        for s in seeds:
            reps.append(Replicate(name=f"{t}-ga-seed{s}", output=_ga_file(t, s), finished=partial(_exists, _ga_file(t, s)),
                                  function=run_ga_part, kwargs={"spec": spec, "seed": s}, weight=1,
                                  cost=spec.generations))
        for v in (None, *variants):
            rel = _td_file(t, v)
            reps.append(Replicate(name=f"{t}-td" + (f"-{v}" if v else ""), output=rel, finished=partial(_exists, rel),
                                  function=run_td_part, kwargs={"spec": spec, "variant": v}, weight=1,
                                  inputs=tuple(_ga_file(t, s) for s in seeds), after=tuple(f"{t}-ga-seed{s}" for s in seeds),
                                  cost=spec.generations))
    return reps


def collect(out: Path, specs: list[tuple[TDSpec, tuple[str, ...]]]) -> dict[str, dict[str, Any]]:
    """The results of every task whose pieces all finished, as :func:`~.runs.run_task` gives them."""
    results = {}
    for spec, variants in specs:
        t = spec.task
        files = [_ga_file(t, spec.seed + i) for i in range(spec.seeds)] + [_td_file(t, v) for v in (None, *variants)]
        if not all((out / f).exists() for f in files):
            continue
        ga = [json.loads((out / _ga_file(t, spec.seed + i)).read_text()) for i in range(spec.seeds)]
        td = json.loads((out / _td_file(t, None)).read_text())
        extra = {v: json.loads((out / _td_file(t, v)).read_text()) for v in variants}
        results[t] = task_results(spec, td["marks"], [g["curve"] for g in ga], td["curves"],
                                  {v: e["curves"] for v, e in extra.items()},
                                  {"ga": sum(g["wall"] for g in ga), "td": td["wall"],
                                   "variants": sum(e["wall"] for e in extra.values())})
    return results


def timing(results: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Each task's seconds (its pieces' own, summed: what one core would take) against the target."""
    tasks = {}
    for t, res in results.items():
        main = res["seconds"]["ga"] + res["seconds"]["td"]
        tasks[t] = {"seconds_ga_and_td": round(main, 1), "seconds_variants": round(res["seconds"]["variants"], 1),
                    "under_target": main < TARGET_SECONDS}
    return {"tasks": tasks, "target_seconds_one_task": TARGET_SECONDS}
