"""The door traversal experiment of report Appendix B (Figure 3), issue 16 item 7: 10 seeds.

    .venv/bin/python benchmarks/door.py [--seeds 10] [--generations 50] [--fail front,front_right,right]
                                        [--json docs/door/benchmark.json] [--figures docs/door]
                                        [--world NAME=JSON ...] [--ga NAME=JSON ...]

Per seed: the GA learns with all sonars for ``--generations`` generations; the three
sonars fail; the best all-sonar rules are tried in the failed world (the drop); the GA
restarts as the report's does (half its population kept, half copies of the initial
rules) and learns ``--generations`` more with the sonars failed.  External performance
(report §8.1) after every generation: the execution module's rules (the best found
since the last change; before any, the default rules) on 100 fresh trials; the table's
key numbers also on 1000.  Time: the GA's own seconds per ``--generations`` generations
(one process, one core), the external measurements apart.  Prints a table and writes
the JSON (and with ``--figures``, the Figure 3-5 counterparts as PNGs).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from coevo.config import GAConfig, build
from coevo.ga import GA
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.tasks import get_task
from coevo.tasks.door import DOOR, DoorConfig, capability_label, default_ruleset, restart
from coevo.tasks.door.evaluate import measure, outcome_rates, play
from coevo.tasks.door.sensors import SPEED, TURN
from coevo.tasks.door.world import draw_trials

EXTERNAL_TRIALS = 100  # report §8.1: "the number of times out of 100"
PRECISE_TRIALS = 1000
REPORT = {"default": 25.0, "all_sonars": 63.0, "drop": 37.0, "adapted": 60.0}


def external(rules: RuleSet, cfg: DoorConfig, seed: int, g: int, trials: int = EXTERNAL_TRIALS) -> float:
    """% of ``trials`` fresh trials (their draw fixed by seed and generation) that reach the goal."""
    return float(measure(rules, cfg, trials=trials, seed=1_000_003 * (seed + 1) + g)["success"])


def behaviour(rules: RuleSet, cfg: DoorConfig, seed: int, trials: int = 200) -> dict[str, float]:
    """How ``rules`` drive (report §8.2): sway (mean |turn| and turn reversals per 10 decisions), the share
    of decisions not moving forward (speed <= 0, the 'fail-safe'), and the trials' outcomes."""
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


def one_seed(seed: int, generations: int, intact: DoorConfig, blind: DoorConfig, ga_cfg: GAConfig) -> dict[str, Any]:
    task = get_task("door")
    ga = GA(task, DOOR, world=intact, ga=ga_cfg, seed=seed)
    curve = [external(default_ruleset(), intact, seed, 0)]
    ga_seconds = [0.0, 0.0]
    rows: list[dict[str, Any]] = []
    all_best: RuleSet | None = None
    for phase, cfg in enumerate((intact, blind)):
        if phase == 1:
            before = ga.best
            curve.append(external(before, blind, seed, generations))  # the old rules meet the failure
            restart(ga, blind)
        for g in range(generations):
            t0 = time.perf_counter()
            rep = ga.generation({})
            ga_seconds[phase] += time.perf_counter() - t0
            gen = phase * generations + g + 1
            curve.append(external(ga.best, cfg, seed, gen))
            rows.append({"generation": gen, "capabilities": list(cfg.capabilities), "best_fitness": rep.best_fitness,
                         "best_so_far": rep.best_so_far, "population_mean": rep.population_mean, **rep.measures})
        if phase == 0:
            all_best = ga.best
    if all_best is None or ga.best is None:  # GAConfig allows no fewer than one generation, so this is a bug
        raise RuntimeError("no generation ran: the GA has no best rules")
    return {
        "seed": seed,
        "default": external(default_ruleset(), intact, seed, 0, PRECISE_TRIALS),
        "all_sonars": external(all_best, intact, seed, generations, PRECISE_TRIALS),
        "drop": external(all_best, blind, seed, generations, PRECISE_TRIALS),
        "adapted": external(ga.best, blind, seed, 2 * generations, PRECISE_TRIALS),
        "behaviour": {"all_sonars": behaviour(all_best, intact, seed), "just_failed": behaviour(all_best, blind, seed),
                      "adapted": behaviour(ga.best, blind, seed)},
        "external_100": curve,  # generation 0 (default), 1..G, the drop, G+1..2G
        "ga_seconds": ga_seconds,
        "rows": rows,
        "best_all_sonars": format_ruleset(all_best),
        "best_adapted": format_ruleset(ga.best),
    }


def figure3(path: Path, runs: list[dict[str, Any]], generations: int, blind: DoorConfig) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c = np.array([r["external_100"] for r in runs])  # (seeds, 2G + 2)
    G = generations
    x = np.r_[np.arange(G + 1), G, np.arange(G + 1, 2 * G + 1)]
    fig, ax = plt.subplots(figsize=(7, 4))
    for row in c:
        ax.plot(x, row, color="0.8", lw=0.6)
    ax.plot(x, c.mean(axis=0), color="tab:blue", lw=2, label=f"mean of {len(runs)} runs (ours)")
    ax.axvline(G, color="black", ls=":", lw=1)
    ax.plot([0, G, G, 2 * G], [REPORT["default"], REPORT["all_sonars"], REPORT["drop"], REPORT["adapted"]], "s",
            color="tab:red", label="the report's numbers (Figure 3 text)")
    ax.set_xlabel("generation")
    ax.set_ylabel("successes out of 100 trials")
    ax.set_ylim(0, 100)
    ax.set_title(f"door traversal: all sonars, then {capability_label(blind)}", fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def rounded(value: Any, digits: int = 4) -> Any:
    """``value`` with every float rounded (the JSON stays readable and small)."""
    if isinstance(value, float):
        return round(value, digits)
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, list):
        return [rounded(v, digits) for v in value]
    return value


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=0, help="seeds first-seed .. first-seed + seeds - 1 (held-out checks)")
    ap.add_argument("--generations", type=int, default=50)
    ap.add_argument("--fail", default="front,front_right,right")
    ap.add_argument("--json", default="docs/door/benchmark.json")
    ap.add_argument("--figures", help="write figure3.png, figure4.png and figure5.png here")
    ap.add_argument("--world", action="append", default=[], metavar="NAME=JSON",
                    help="a DoorConfig setting for both phases, e.g. sonar_noise=12 (a sensitivity check; repeatable)")
    ap.add_argument("--ga", action="append", default=[], metavar="NAME=JSON", help="a GAConfig override, e.g. episodes=20")
    args = ap.parse_args()
    world_over, ga_over = (dict((k, json.loads(v)) for k, v in (i.split("=", 1) for i in items))
                           for items in (args.world, args.ga))
    intact = build(DoorConfig, world_over)
    blind = build(DoorConfig, {**world_over, "failed": args.fail})
    ga_cfg = get_task("door").default_ga(**ga_over)  # type: ignore[attr-defined]
    t0 = time.perf_counter()
    runs = []
    for s in range(args.first_seed, args.first_seed + args.seeds):
        r = one_seed(s, args.generations, intact, blind, ga_cfg)
        runs.append(r)
        print(f"seed {s}: default {r['default']:.1f} %, all sonars {r['all_sonars']:.1f} %, {capability_label(blind)} "
              f"{r['drop']:.1f} %, adapted {r['adapted']:.1f} %; GA {r['ga_seconds'][0]:.1f} + {r['ga_seconds'][1]:.1f} s",
              flush=True)
    keys = ("default", "all_sonars", "drop", "adapted")
    mean = {k: float(np.mean([r[k] for r in runs])) for k in keys}
    sd = {k: float(np.std([r[k] for r in runs], ddof=1)) if len(runs) > 1 else 0.0 for k in keys}
    per50 = [x for r in runs for x in r["ga_seconds"]]
    G = args.generations
    summary = {
        "seeds": args.seeds, "generations": G, "failed": list(blind.failed), "capabilities": list(blind.capabilities),
        "mean_success_1000_trials": mean, "sd_over_seeds": sd, "report": REPORT,
        "mean_external_100_at": {"0": float(np.mean([r["external_100"][0] for r in runs])),
                                 str(G): float(np.mean([r["external_100"][G] for r in runs])),
                                 f"{G} (failed)": float(np.mean([r["external_100"][G + 1] for r in runs])),
                                 str(2 * G): float(np.mean([r["external_100"][-1] for r in runs]))},
        "seeds_all_sonars_at_least_60": sum(r["all_sonars"] >= 60 for r in runs),
        "seeds_adapted_over_60": sum(r["adapted"] > 60 for r in runs),
        "ga_seconds_per_generations": {"mean": float(np.mean(per50)), "max": float(np.max(per50)), "runs": len(per50)},
        "wall_seconds": time.perf_counter() - t0, "cpus": os.cpu_count(),
        "load_average_at_end": [round(x, 2) for x in os.getloadavg()], "python": platform.python_version(),
        "ga": ga_cfg.model_dump(),
        "world": intact.model_dump(),
    }
    print()
    print(f"| measure (success %, 1000 fresh trials; mean ± sd over {args.seeds} seeds) | ours | report |")
    print("|---|---|---|")
    names = {"default": "default rules, all sonars", "all_sonars": f"best after {G} generations, all sonars",
             "drop": f"that best with {', '.join(blind.failed)} failed", "adapted": f"best after {G} more generations, failed"}
    for k in keys:
        rep = ("> " if k == "adapted" else "") + f"{REPORT[k]:.0f}"
        print(f"| {names[k]} | {mean[k]:.1f} ± {sd[k]:.1f} | {rep} |")
    print("\n| how the rules drive (200 trials; mean over seeds) | mean abs turn (deg/s) | turn reversals per 10 "
          "decisions | decisions not moving forward (%) | collisions (%) | timeouts (%) |")
    print("|---|---|---|---|---|---|")
    stats = {}
    for k, label in (("all_sonars", "best, all sonars"), ("just_failed", "that best, just after the failure"),
                     ("adapted", "best after adapting")):
        m = {q: float(np.mean([r["behaviour"][k][q] for r in runs])) for q in runs[0]["behaviour"][k]}
        stats[k] = m
        print(f"| {label} | {m['mean_abs_turn']:.1f} | {m['reversals_per_10']:.2f} | {m['not_forward']:.1f} | "
              f"{m['collision']:.1f} | {m['timeout']:.1f} |")
    summary["behaviour_means"] = stats
    print(f"\nGA time per {G} generations: mean {summary['ga_seconds_per_generations']['mean']:.1f} s, "
          f"max {summary['ga_seconds_per_generations']['max']:.1f} s (target < 60 s); wall {summary['wall_seconds']:.0f} s")
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rounded({"summary": summary, "runs": runs})) + "\n")
    print(f"wrote {out}")
    if args.figures:
        from coevo.policy.text import parse_ruleset
        from coevo.tasks.door.pictures import path_figure

        fig_dir = Path(args.figures)
        fig_dir.mkdir(parents=True, exist_ok=True)
        figure3(fig_dir / "figure3.png", runs, G, blind)
        path_figure(fig_dir / "figure4.png", parse_ruleset(runs[0]["best_all_sonars"]), intact, seed=0,
                    title=f"seed 0, best after {G} generations, all sonars")
        path_figure(fig_dir / "figure5.png", parse_ruleset(runs[0]["best_adapted"]), blind, seed=0,
                    title=f"seed 0, best after {G} more generations, {capability_label(blind)}")
        print(f"wrote {fig_dir}/figure3.png, figure4.png, figure5.png")


if __name__ == "__main__":
    main()
