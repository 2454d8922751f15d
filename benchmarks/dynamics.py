"""The cross-generation tournament of one finished run, timed: ``coevo dynamics``' matrices, CPU and wall seconds.

    python benchmarks/dynamics.py RUN_DIR [--episodes 60] [--seed 1] [--every-generation]

Plays what ``coevo dynamics RUN_DIR`` plays (every published version, or in a run modelled by each generation's
best every generation's best the partners adopted, of each behaviour against every published
version of each partner it learned against, ``--episodes`` fresh episodes a cell), in this process, without
writing; the run's reading and the imports are not timed.  ``--every-generation`` plays the tournament a run that
published a new best every generation would need: for each generation 1..G the version in play then (the last
published by then), so 50 x 50 versions per pair for a 50-generation run, whatever the run published: the worst
case of the command.  Prints one JSON line: the run, its task, the cells, the CPU seconds (this process: the
tournament runs in one) and the wall seconds.  The runs measured in docs/competition.md were made with

    coevo run --task pursuit --regime mutual --seed 5200 --run pursuit-full --quiet
    coevo run --regime mutual --seed 5200 --run fuel-full --quiet
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from coevo.errors import CoevoError
from coevo.experiments.dynamics.matrix import (Versions, adopted_versions, check_finished, pairs_of, play_matrix, read_run,
                                               versions_of)


def every_generation(v: Versions, generations: int) -> Versions:
    """For each generation 1..``generations``, the version of ``v`` in play at its end."""
    picks = [max([i for i, g in enumerate(v.generation) if g <= gen] or [0]) for gen in range(1, generations + 1)]
    return Versions(v.behaviour, tuple(v.version[i] for i in picks), tuple(range(1, generations + 1)),
                    tuple(v.rules[i] for i in picks))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("--episodes", type=int, default=60)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--every-generation", action="store_true")
    a = p.parse_args()
    if a.episodes < 1:
        p.error(f"--episodes must be at least 1, got {a.episodes}")
    try:
        settings, task, world, ga, paths = read_run(a.run)
        check_finished(paths, task, settings.ga.generations)
        pairs = pairs_of(task, settings.regime)
        generational = settings.model in ("current", "hall")  # as the command plays them: what the partners met
        versions = {b: adopted_versions(paths, b, task, settings.regime) if generational else versions_of(paths, b)
                    for pair in pairs for b in pair}
    except CoevoError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    if a.every_generation:
        versions = {b: every_generation(v, settings.ga.generations) for b, v in versions.items()}
    final = {b: v.rules[-1] for b, v in versions.items()}
    cells = 0
    c0, w0 = time.process_time(), time.perf_counter()
    for x, y in pairs:
        others = {k: final[k] for k in task.partners_needed(x, settings.regime) if k != y}
        m = play_matrix(task, world, ga, versions[x], versions[y], others, episodes=a.episodes, seed=a.seed)
        cells += m.fitness.size
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    print(json.dumps({"run": str(a.run), "task": task.name, "regime": settings.regime,
                      "generations": settings.ga.generations, "population": settings.ga.population,
                      "every_generation": a.every_generation, "pairs": len(pairs), "cells": cells,
                      "episodes": a.episodes, "cpu_s": round(cpu, 2), "wall_s": round(wall, 2)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
