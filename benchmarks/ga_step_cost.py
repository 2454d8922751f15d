"""CPU seconds of a GA generation, its population's evaluation and its best's re-evaluation apart.

    python benchmarks/ga_step_cost.py [--behaviour tracking executive] [--generations 8] [--seed 1] [--repeats 1]

The GA at the report's size (``GAConfig()``: 50 individuals, 90 episodes each, the best re-evaluated
on 120), Tracking against no partner (the trivial Executive), the Executive against the shipped
Tracking and Docking rules.  A warm-up generation of another GA first (numba's loading, the worlds'
construction), then ``--generations`` generations from ``--seed``; ``time.process_time`` around every
``evaluate`` call: the first of a generation is the population's, the second its best's.  Prints one
JSON line per repeat and behaviour (the minimum over repeats is the figure to read: the machine is shared).
"""

from __future__ import annotations

import argparse
import json
import time

from coevo.config import GAConfig
from coevo.ga import GA
from coevo.tasks import get_task
from coevo.tasks.fuel import default_ruleset
from coevo.tasks.fuel.settings import WorldConfig


def partners_of(behaviour: str) -> dict:
    if behaviour == "executive":
        return {"tracking": default_ruleset("tracking"), "docking": default_ruleset("docking")}
    return {}


def timed_run(behaviour: str, generations: int, seed: int) -> dict[str, float]:
    """CPU seconds per generation: all of it, the population's evaluation, the best's re-evaluation."""
    task, world, ga = get_task("fuel"), WorldConfig(), GAConfig()
    partners = partners_of(behaviour)
    GA(task, behaviour, world=world, ga=ga, seed=seed + 10_000).generation(partners)  # warm-up
    engine = GA(task, behaviour, world=world, ga=ga, seed=seed)
    calls: list[float] = []
    evaluate = engine.evaluator.evaluate

    def timed(*args, **kwargs):
        t0 = time.process_time()
        try:
            return evaluate(*args, **kwargs)
        finally:
            calls.append(time.process_time() - t0)

    engine.evaluator.evaluate = timed  # type: ignore[method-assign]
    total = population = best = 0.0
    for _ in range(generations):
        calls.clear()
        t0 = time.process_time()
        engine.generation(partners)
        total += time.process_time() - t0
        population += calls[0]
        best += calls[1]
    n = generations
    return {"generation": total / n, "population": population / n, "best": best / n,
            "best_fitness": float(engine.best_fitness)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--behaviour", nargs="+", default=["tracking", "executive"])
    p.add_argument("--generations", type=int, default=8)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--repeats", type=int, default=1)
    a = p.parse_args()
    for _ in range(a.repeats):
        for beh in a.behaviour:
            print(json.dumps({"behaviour": beh, **timed_run(beh, a.generations, a.seed)}), flush=True)


if __name__ == "__main__":
    main()
