"""Continuous and Embedded Learning (report Appendix B, Figure 3; issue 17 items 6-8), in process, lockstep.

    .venv/bin/python benchmarks/cel.py [--runs 10] [--cyclic-runs 5] [--jobs 1] [--out docs/cel]
                                       [--skip-cyclic] [--skip-monitor] [--skip-figure3]

1. Figure 3: ``--runs`` runs of :data:`coevo.cel.experiment.FIGURE3` (front, front-right and right fail at
   generation 50 of 100); the execution module plays 100 trials per generation; mean external
   performance per generation with its s.d., the monitor's detection delays, and what the robot does
   right after the failure (decisions not moving forward, timeouts, collisions; a path picture).
2. The monitor's N: for the default rules and each run's rules in use at the failure, the longest
   run of zero readings while moving forward of working sonars (false alarms) with sonar noise 0, 12
   and 24 in, and the decisions until a failed sonar is flagged, for several N.
3. The cyclic schedule :data:`coevo.cel.experiment.CYCLIC` (failure, repair, the same failure) with and
   without the case base: generations to get back over 60 % and 80 % after each failure.

Prints tables; writes ``figure3.json``, ``monitor.json``, ``cyclic.json`` and PNGs into ``--out``.
Times: wall clock of each part, and the learning and execution seconds of each run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from coevo.cel.experiment import CYCLIC, FAILED, FIGURE3, detection_decisions, recovery, run_cel, summarise, zero_runs
from coevo.policy.text import parse_ruleset
from coevo.tasks.door import DOOR, DoorConfig, default_ruleset

REPORT = {"default": 25.0, "all_sonars": 63.0, "drop": 37.0, "adapted": 60.0}
THRESHOLDS = (60.0, 80.0)
NOISES = (0.0, 12.0, 24.0)
N_CHOICES = (1, 2, 4, 6, 8, 10, 12)


def _run(args: tuple[int, dict[str, Any], bool]) -> dict[str, Any]:
    seed, schedule, case_base = args
    return run_cel(seed, case_base=case_base, **schedule)


def _many(jobs: int, tasks: list[tuple[int, dict[str, Any], bool]]) -> list[dict[str, Any]]:
    if jobs <= 1:
        return [_run(t) for t in tasks]
    with ProcessPoolExecutor(jobs) as pool:
        return list(pool.map(_run, tasks))


def ms(values: list[float]) -> str:
    a = np.asarray(values, dtype=float)
    return f"{a.mean():5.1f} ± {a.std(ddof=1) if len(a) > 1 else 0.0:4.1f}"


def column(runs: list[dict[str, Any]], key: str, g: int) -> list[float]:
    return [r["rows"][g][key] for r in runs]


# ------------------------------------------------------------------ 1. Figure 3
def figure3(runs: list[dict[str, Any]], out: Path) -> dict[str, Any]:
    e = FIGURE3["events"][0][0]
    G = FIGURE3["generations"]
    s = summarise(runs)
    key = {"default": 0, "all_sonars": e - 1, "drop": e, "adapted": G}
    table = {k: {"ours": column(runs, "external", g), "generation": g, "report": REPORT[k]} for k, g in key.items()}
    failsafe = {name: {k: column(runs, k, g) for k in ("not_forward", "timeout", "collision", "success")}
                for name, g in (("before", e - 1), ("at_failure", e), ("first_after_restart", e + 1), ("adapted", G))}
    print(f"\nFigure 3: {len(runs)} runs, {', '.join(FAILED)} fail at generation {e}; external performance "
          "(successes of the last 100 trials), mean ± s.d. over runs")
    print(f"{'':34s} {'generation':>10s} {'ours':>13s} {'report':>7s}")
    for k, v in table.items():
        print(f"{k:34s} {v['generation']:10d} {ms(v['ours']):>13s} {v['report']:7.0f}")
    print(f"monitor: detected {s['detected']}; trials {sorted(set(s['delay_trials']))}, decisions "
          f"{min(s['delay_decisions'], default=0)}..{max(s['delay_decisions'], default=0)}, learner generations on the "
          f"wrong model after the failure {sorted(set(s['delay_generations']))}")
    print("\nright after the failure: % of the stretch's 100 trials or decisions, mean ± s.d. over runs")
    print(f"{'generation':34s} {'not forward':>13s} {'timeout':>13s} {'collision':>13s} {'success':>13s}")
    for name, v in failsafe.items():
        print(f"{name:34s} {ms(v['not_forward']):>13s} {ms(v['timeout']):>13s} {ms(v['collision']):>13s} "
              f"{ms(v['success']):>13s}")
    _plot_figure3(out / "figure3.png", s, runs, e)
    pictures(max(runs, key=lambda r: r["rows"][e]["not_forward"]), out)
    return {"summary": s, "table": table, "failsafe": failsafe,
            "runs": [{"seed": r["seed"], "external": column_all(r, "external"), "not_forward": column_all(r, "not_forward"),
                      "timeout": column_all(r, "timeout"), "changes": r["changes"], "detections": r["detections"],
                      "seconds": r["seconds"]} for r in runs]}


def pictures(run: dict[str, Any], out: Path) -> None:
    """The fail-safe picture (the rules in use at the failure, blinded: the first of 20 trials, whatever
    its end) and the adapted rules at the end, of ``run`` (the benchmark picks the run whose robot
    stood still most right after the failure)."""
    from coevo.tasks.door.pictures import path_figure

    e, G = FIGURE3["events"][0][0], FIGURE3["generations"]
    blind = DoorConfig(failed=FAILED)
    seed = run["seed"]
    path_figure(out / "failsafe.png", parse_ruleset(run["rules_at_event"][str(e)], DOOR), blind, seed=0,
                prefer_success=False, title=f"seed {seed}: the rules in use when {', '.join(FAILED)} fail "
                f"(generation {e}), the first of 20 trials")
    path_figure(out / "adapted.png", parse_ruleset(run["final_rules"], DOOR), blind, seed=0,
                title=f"seed {seed}: the execution module's rules at generation {G}, adapted")


def column_all(run: dict[str, Any], key: str) -> list[float]:
    return [row[key] for row in run["rows"]]


def _plt():  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _plot_figure3(path: Path, s: dict[str, Any], runs: list[dict[str, Any]], e: int) -> None:
    plt = _plt()
    mean, sd = np.array(s["external_mean"]), np.array(s["external_sd"])
    x = np.arange(len(mean))
    fig, ax = plt.subplots(figsize=(7, 4))
    for r in runs:
        ax.plot(x, column_all(r, "external"), color="0.85", lw=0.6)
    ax.fill_between(x, mean - sd, mean + sd, color="tab:blue", alpha=0.2, label="± 1 s.d.")
    ax.plot(x, mean, color="tab:blue", lw=2, label=f"mean of {len(runs)} runs (ours, lockstep CEL)")
    ax.axvline(e - 0.5, color="black", ls=":", lw=1, label="front, front-right, right fail")
    ax.plot([0, e - 1, e, x[-1]], [REPORT["default"], REPORT["all_sonars"], REPORT["drop"], REPORT["adapted"]], "s",
            color="tab:red", label="the report's numbers (Figure 3 text)")
    ax.set_xlabel("generation")
    ax.set_ylabel("external performance: successes of 100 trials")
    ax.set_ylim(0, 100)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


# ------------------------------------------------------------------ 2. the monitor's N
def monitor(runs: list[dict[str, Any]], trials: int) -> dict[str, Any]:
    e = str(FIGURE3["events"][0][0])
    rules = {"default": default_ruleset(), **{f"seed{r['seed']}": parse_ruleset(r["rules_at_event"][e], DOOR)
                                              for r in runs}}
    longest = {}
    for noise in NOISES:
        w = DoorConfig(sonar_noise=noise)
        mx = np.concatenate([zero_runs(rs, w, trials=trials, seed=7).max(axis=1) for rs in rules.values()])
        longest[str(noise)] = np.bincount(mx).tolist()
    blind = DoorConfig(failed=FAILED)
    delay = {str(n): [detection_decisions(rs, blind, zero_run=n, trials=20, seed=3) for rs in rules.values()]
             for n in N_CHOICES}
    n_trials = trials * len(rules)
    print(f"\nthe monitor's N: {len(rules)} rule sets (the default and each run's rules at the failure), "
          f"{trials} trials each with every sonar working")
    print(f"{'N':>3s} " + " ".join(f"{'false alarms, noise ' + str(int(n)):>22s}" for n in NOISES)
          + f" {'decisions to flag (median, max)':>32s}")
    for n in N_CHOICES:
        fa = [sum(longest[str(noise)][n:]) for noise in NOISES]
        d = [x[1] for x in delay[str(n)] if x[1] is not None]
        print(f"{n:3d} " + " ".join(f"{f:>15d} / {n_trials:<5d}" for f in fa)
              + f" {int(np.median(d)) if d else -1:>20d}, {max(d) if d else -1:<4d} (flagged {len(d)}/{len(rules)})")
    return {"rule_sets": list(rules), "trials_each": trials,
            "longest_zero_run_histogram": longest,  # per noise: trials whose longest forward zero run was 0, 1, ...
            "detection": delay}


# ------------------------------------------------------------------ 3. cyclic
def _reached(values: list[int | None]) -> str:
    got = [v for v in values if v is not None]
    return f"{ms(got) if got else '   -':>13s} ({len(got)}/{len(values)})"


def cyclic(plain: list[dict[str, Any]], cased: list[dict[str, Any]], out: Path) -> dict[str, Any]:
    fails = [g for g, f in CYCLIC["events"] if f]
    res: dict[str, Any] = {"events": CYCLIC["events"], "thresholds": THRESHOLDS}
    print(f"\ncyclic schedule: {CYCLIC['events']}, {len(plain)} runs each; generations from a failure until the "
          "external performance is back over the threshold (0: the failure's own generation; mean ± s.d. of the runs "
          "that got there, and how many did)")
    print(f"{'':20s} {'failure at':>10s} " + " ".join(f"{'>= ' + str(int(t)) + ' %':>20s}" for t in THRESHOLDS)
          + f" {'first rules after restart':>26s} {'mean of 10 gens after':>22s}")
    for name, runs in (("restart (report)", plain), ("case base", cased)):
        for e in fails:
            end = next((g for g, _ in CYCLIC["events"] if g > e), CYCLIC["generations"] + 1)
            rec = {t: [recovery(column_all(r, "external")[:end], e, t) for r in runs] for t in THRESHOLDS}
            after = [float(np.mean(column_all(r, "external")[e:e + 10])) for r in runs]
            first = [column_all(r, "external")[e + 1] for r in runs]  # the learner's first best on the new model
            res[f"{name}@{e}"] = {"recovery": {str(t): v for t, v in rec.items()}, "mean_10_after": after,
                                  "first_after_restart": first}
            cells = " ".join(f"{_reached(rec[t]):>20s}" for t in THRESHOLDS)
            print(f"{name:20s} {e:10d} {cells} {ms(first):>26s} {ms(after):>22s}")
    res["curves"] = {name: summarise(runs) for name, runs in (("restart", plain), ("case_base", cased))}
    res["runs"] = {name: [{"seed": r["seed"], "external": column_all(r, "external"), "changes": r["changes"],
                           "detections": r["detections"], "seconds": r["seconds"]} for r in runs]
                   for name, runs in (("restart", plain), ("case_base", cased))}
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, color in (("restart", "tab:blue"), ("case_base", "tab:green")):
        m, sd = np.array(res["curves"][name]["external_mean"]), np.array(res["curves"][name]["external_sd"])
        x = np.arange(len(m))
        ax.fill_between(x, m - sd, m + sd, color=color, alpha=0.15)
        ax.plot(x, m, color=color, lw=2, label=f"{name.replace('_', ' ')} (mean of {len(plain)} runs)")
    for g, f in CYCLIC["events"]:
        ax.axvline(g - 0.5, color="black", ls=":", lw=1)
        ax.text(g, 3, "fail" if f else "repair", fontsize=8)
    ax.set_xlabel("generation")
    ax.set_ylabel("external performance: successes of 100 trials")
    ax.set_ylim(0, 100)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "cyclic.png", dpi=80)
    plt.close(fig)
    return res


def rounded(value: Any, digits: int = 3) -> Any:
    if isinstance(value, float):
        return round(value, digits)
    if isinstance(value, dict):
        return {k: rounded(v, digits) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [rounded(v, digits) for v in value]
    return value


def write(path: Path, data: dict[str, Any]) -> None:
    path.write_text(json.dumps(rounded(data), separators=(",", ":")) + "\n", encoding="utf-8")


def _figure3_and_monitor(a: argparse.Namespace, out: Path, machine: dict[str, Any]) -> None:
    t0 = time.perf_counter()
    runs = _many(a.jobs, [(s, FIGURE3, False) for s in range(a.runs)])
    wall = time.perf_counter() - t0
    fig = figure3(runs, out)
    fig["timing"] = {**machine, "wall_seconds": wall,
                     "learning_seconds": [r["seconds"]["learning"] for r in runs],
                     "execution_seconds": [r["seconds"]["execution"] for r in runs]}
    print(f"\ntime: {len(runs)} runs in {wall:.0f} s wall with {a.jobs} process(es); per run learning "
          f"{ms(fig['timing']['learning_seconds'])} s, execution {ms(fig['timing']['execution_seconds'])} s "
          f"(load average at the start {machine['load_average']:.1f})")
    write(out / "figure3.json", fig)
    if not a.skip_monitor:
        t0 = time.perf_counter()
        mon = monitor(runs, a.monitor_trials)
        mon["wall_seconds"] = time.perf_counter() - t0
        write(out / "monitor.json", mon)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--cyclic-runs", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=1, help="processes for the runs (each run is one process)")
    ap.add_argument("--monitor-trials", type=int, default=1000)
    ap.add_argument("--out", default="docs/cel")
    ap.add_argument("--skip-cyclic", action="store_true")
    ap.add_argument("--skip-monitor", action="store_true")
    ap.add_argument("--skip-figure3", action="store_true", help="only the cyclic schedule (the monitor needs Figure 3)")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    machine = {"cpus": os.cpu_count(), "python": platform.python_version(), "load_average": os.getloadavg()[0],
               "jobs": a.jobs}
    if not a.skip_figure3:
        _figure3_and_monitor(a, out, machine)
    if not a.skip_cyclic:
        t0 = time.perf_counter()
        both = _many(a.jobs, [(s, CYCLIC, cb) for cb in (False, True) for s in range(a.cyclic_runs)])
        cyc = cyclic(both[: a.cyclic_runs], both[a.cyclic_runs:], out)
        cyc["timing"] = {**machine, "wall_seconds": time.perf_counter() - t0}
        print(f"\ntime: cyclic {2 * a.cyclic_runs} runs in {cyc['timing']['wall_seconds']:.0f} s wall")
        write(out / "cyclic.json", cyc)


if __name__ == "__main__":
    main()
