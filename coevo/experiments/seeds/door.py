"""``coevo seeds --task door``: Appendix B's door traversal over seeds, offline (once a script in benchmarks/).

Per seed, in one process: the GA learns with all sonars for ``generations`` generations; the sonars in
``failed`` fail; the best all-sonar rules are tried in the failed world (the drop); the GA restarts as the
report's does (half its population kept, half copies of the initial rules) and learns ``generations`` more.
External performance (report §8.1) after every generation: the best rules so far (before any, the default
rules) on 100 fresh trials; the table's four numbers also on 1000.  Time: the GA's own seconds per phase (one
process, one core), the external measurements apart.

Each seed is a replicate (a function) writing ``OUT/runs/door-seedN/result.json``, run by
:mod:`coevo.replicates`; the report is :mod:`.door_report`.
"""

from __future__ import annotations

import time
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from coevo.replicates.replicate import Replicate

if TYPE_CHECKING:
    from coevo.config import GAConfig
    from coevo.policy.rules import RuleSet
    from coevo.tasks.door.settings import DoorConfig

__all__ = ["EXTERNAL_TRIALS", "PRECISE_TRIALS", "run_seed", "replicates", "result_file", "rounded"]

EXTERNAL_TRIALS = 100  # report §8.1: "the number of times out of 100"
PRECISE_TRIALS = 1000


def _name(seed: int) -> str:
    return f"door-seed{seed}"


def result_file(root: Path, seed: int) -> Path:
    return Path(root) / "runs" / _name(seed) / "result.json"


def external(rules: RuleSet, cfg: DoorConfig, seed: int, g: int, trials: int = EXTERNAL_TRIALS) -> float:
    """% of ``trials`` fresh trials (their draw fixed by seed and generation) that reach the goal."""
    from coevo.tasks.door.evaluate import measure

    return float(measure(rules, cfg, trials=trials, seed=1_000_003 * (seed + 1) + g)["success"] or 0.0)


def behaviour(rules: RuleSet, cfg: DoorConfig, seed: int, trials: int = 200) -> dict[str, float]:
    """How ``rules`` drive (report §8.2): sway (mean |turn| and turn reversals per 10 decisions), the share
    of decisions not moving forward (speed <= 0, the 'fail-safe'), and the trials' outcomes."""
    from coevo.policy.matcher import CompiledPolicies
    from coevo.tasks.door.evaluate import outcome_rates, play
    from coevo.tasks.door.sensors import SPEED, TURN
    from coevo.tasks.door.world import draw_trials

    rng = np.random.default_rng(seed)
    out = play(cfg, CompiledPolicies([rules]), np.zeros(trials, dtype=np.int64), draw_trials(cfg, trials, rng), rng)
    order = np.argsort(out.lane, kind="stable")  # each trial's decisions in time order
    act = rules.action[out.rule[order]]
    turn = np.array(TURN.values, dtype=np.float64)[act[:, 0]]
    speed = np.array(SPEED.values, dtype=np.float64)[act[:, 1]]
    lane = out.lane[order]
    same = lane[1:] == lane[:-1]
    reversals = same & (np.sign(turn[1:]) * np.sign(turn[:-1]) < 0)
    return {"mean_abs_turn": float(np.abs(turn).mean()), "reversals_per_10": float(10 * reversals.sum() / len(turn)),
            "not_forward": float(100 * (speed <= 0).mean()), "decisions_per_trial": len(turn) / trials,
            **outcome_rates(out.outcome)}


def _learn(seed: int, generations: int, intact: DoorConfig, blind: DoorConfig, ga_cfg: GAConfig) -> dict[str, Any]:
    """The two phases of one seed: the curve, the GA's seconds per phase, the rows, both bests."""
    from coevo.ga import GA
    from coevo.tasks import get_task
    from coevo.tasks.door import DOOR, default_ruleset, restart

    ga = GA(get_task("door"), DOOR, world=intact, ga=ga_cfg, seed=seed)
    curve = [external(default_ruleset(), intact, seed, 0)]
    seconds = [0.0, 0.0]
    rows: list[dict[str, Any]] = []
    all_best = None
    for phase, cfg in enumerate((intact, blind)):
        if phase == 1:
            curve.append(external(ga.best_rules(), blind, seed, generations))  # the old rules meet the failure
            restart(ga, blind)
        for g in range(generations):
            t0 = time.perf_counter()
            rep = ga.generation({})
            seconds[phase] += time.perf_counter() - t0
            gen = phase * generations + g + 1
            curve.append(external(ga.best_rules(), cfg, seed, gen))
            rows.append({"generation": gen, "capabilities": list(cfg.capabilities), "best_fitness": rep.best_fitness,
                         "best_so_far": rep.best_so_far, "population_mean": rep.population_mean, **rep.measures})
        if phase == 0:
            all_best = ga.best_rules()
    return {"curve": curve, "seconds": seconds, "rows": rows, "all_best": all_best, "adapted": ga.best_rules()}


def run_seed(root: Path, *, seed: int, generations: int, world: dict[str, Any], failed: list[str],
             ga: dict[str, Any]) -> None:
    """One seed's experiment (a replicate's function): writes ``result_file(root, seed)`` when complete."""
    from coevo.config import build
    from coevo.policy.text import format_ruleset
    from coevo.rundir.layout import write_json
    from coevo.tasks.door import DoorConfig, default_ruleset, door_ga

    intact = build(DoorConfig, world)
    blind = build(DoorConfig, {**world, "failed": failed})
    got = _learn(seed, generations, intact, blind, door_ga(**ga))
    all_best, adapted = got["all_best"], got["adapted"]
    result = {
        "seed": seed,
        "default": external(default_ruleset(), intact, seed, 0, PRECISE_TRIALS),
        "all_sonars": external(all_best, intact, seed, generations, PRECISE_TRIALS),
        "drop": external(all_best, blind, seed, generations, PRECISE_TRIALS),
        "adapted": external(adapted, blind, seed, 2 * generations, PRECISE_TRIALS),
        "behaviour": {"all_sonars": behaviour(all_best, intact, seed), "just_failed": behaviour(all_best, blind, seed),
                      "adapted": behaviour(adapted, blind, seed)},
        "external_100": got["curve"],  # generation 0 (default), 1..G, the drop, G+1..2G
        "ga_seconds": got["seconds"],
        "rows": got["rows"],
        "best_all_sonars": format_ruleset(all_best),
        "best_adapted": format_ruleset(adapted),
    }
    f = result_file(root, seed)
    f.parent.mkdir(parents=True, exist_ok=True)
    write_json(f, rounded(result))


def _finished(seed: int, root: Path) -> bool:
    return result_file(root, seed).exists()


def replicates(seeds: list[int], *, generations: int, world: dict[str, Any], failed: list[str],
               ga: dict[str, Any]) -> list[Replicate]:
    """One seed per replicate: one process, one core, and a whole ``--jobs`` slot (weight 2), since ``coevo seeds``
    counts seeds at once (its timing target is per core)."""
    return [Replicate(name=_name(s), output=f"runs/{_name(s)}", finished=partial(_finished, s), function=run_seed,
                      kwargs={"seed": s, "generations": generations, "world": world, "failed": failed, "ga": ga},
                      weight=2, cost=2 * generations)
            for s in seeds]


def rounded(value: Any, digits: int = 4) -> Any:
    """``value`` with every float rounded (the JSON stays readable and small)."""
    if isinstance(value, float):
        return round(value, digits)
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, list):
        return [rounded(v, digits) for v in value]
    return value
