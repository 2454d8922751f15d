"""The Appendix C report: CSV and JSON numbers, the survey's claims against what was measured, figures.

Writes into a directory: ``grid_q.csv`` (per state and action: the exact Q, Table 1's legible value,
Q-learning's final values, EARL1's implicit estimate), ``table4.csv`` (the implicit estimate of the
survey's own Table 2 population beside its legible Table 4), ``grid_q_curve.csv`, `grid_ea_curve.csv``,
``hidden_curves.csv`` (the counterpart of Figure 14), ``hidden_policies.csv``, ``results.json``
(spec, numbers, every claim with its verdict), ``report.md`` and, when matplotlib is installed,
``fig_grid.png`` and ``fig14_hidden.png``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from coevo.experiments.earl import gridworld, hidden
from coevo.experiments.earl.earl1 import implicit_values
from coevo.experiments.earl.experiment import TABLE2, TABLE2_FITNESS, EarlSpec
from coevo.rundir.layout import write_csv, write_json, write_text

__all__ = ["TABLE1_D", "TABLE4", "claims", "write_report"]

# Table 1 as legible in the report's text: only the D row survives (a1..e5).
TABLE1_D = (16, 11, 10, 7, 1, 17, 8, 1, 3, 1, 15, 14, 12, 8, 2, 6, 7, 7, 3, 1, 7, 6, 4, 3, 1)
# Table 4 as legible (rows R and D, a1..e5); None = the survey's "?" or an unreadable cell.
_Q = None
TABLE4 = (
    (16, 7, _Q, 17, 12, 8, 12, 11, 11, 12, 14, 7, 12, 13, 9, 12, 11, 12, 12, 11, _Q, 12, 7, _Q, 9),
    (9, 13, 12, 11, _Q, 15, _Q, 17, 16, _Q, 11, 13, 12, 7, 14, 11, 12, _Q, 11, 16, 12, _Q, 13, 12, 16),
)


def _f(x: float, nd: int = 3) -> float | None:
    """A JSON-safe rounded float (NaN becomes null)."""
    return None if x is None or not math.isfinite(float(x)) else round(float(x), nd)


def _table4_match(fitness: np.ndarray) -> tuple[int, int]:
    """How many legible Table 4 numbers the implicit estimate of Table 2 (with these fitnesses) reproduces, rounded."""
    est = np.round(implicit_values(TABLE2, fitness))  # numpy rounds halves to even, as the table appears to
    ok = n = 0
    for a in (0, 1):
        for s, v in enumerate(TABLE4[a]):
            if v is not None:
                n += 1
                ok += int(np.isfinite(est[s, a]) and est[s, a] == v)
    return ok, n


def claims(spec: EarlSpec, grid: dict[str, Any], hid: dict[str, Any]) -> list[dict[str, Any]]:
    """Each claim of the survey, the number it gives, the number measured here and a verdict."""
    out: list[dict[str, Any]] = []

    def add(section: str, claim: str, survey: str, measured: str, verdict: str, **numbers: Any) -> None:
        out.append({"section": section, "claim": claim, "survey": survey, "measured": measured,
                    "verdict": verdict, "numbers": numbers})

    _grid_claims(add, spec, grid)
    _hidden_claims(add, spec, hid)
    return out


Add = Callable[..., None]


def _grid_claims(add: Add, spec: EarlSpec, grid: dict[str, Any]) -> None:
    """The grid world's claims (Figure 1, Tables 1-4)."""
    qstar = grid["qstar"]
    paths = grid["optimal_paths"]
    add("grid", "The optimal score from a1 is 17, e.g. along R,D,R,D,D,R,R,D", "17",
        f"{grid['optimum']:g} (exact, reconstructed payoffs); {len(paths)} optimal paths: {', '.join(paths)}",
        "holds" if grid["optimum"] == 17 and gridworld.OPTIMAL_PATH in paths else "does not hold",
        optimum=grid["optimum"], optimal_paths=paths)
    legible = int(sum(int(qstar[s, 1]) == v for s, v in enumerate(TABLE1_D)))
    add("grid", "Table 1 is the grid's Q-function", "D row legible (25 values)",
        f"exact Q of the reconstruction equals {legible} of 25 legible values; Q(b2,R) = {qstar[6, 0]:g}, "
        f"Q(b2,D) = {qstar[6, 1]:g}", "holds" if legible == 25 and tuple(qstar[6]) == (15, 8) else "does not hold",
        table1_matches=legible)
    err = grid["q_error"][-1]
    greedy = grid["q_greedy_return"][-1]
    first_opt = _first_stable(grid["q_greedy_return"] == grid["optimum"])
    add("grid", "Tabular Q-learning learns the Q-function (Watkins & Dayan: converges to the correct values)",
        "Table 1",
        f"after {spec.grid_episodes} episodes (alpha {spec.grid_alpha}, epsilon {spec.grid_epsilon}): max abs(Q - Q*) "
        f"median {np.median(err):.3g}, worst run {err.max():.3g}; {int((err < 0.01).sum())}/{spec.runs} runs within "
        f"0.01 everywhere; greedy policy scores 17 in {int((greedy == 17).sum())}/{spec.runs} runs "
        f"(optimal from episode {np.median(first_opt):.0f}, median)",
        "holds" if (greedy == 17).all() and (err < 0.01).mean() >= 0.95 else "holds in part",
        max_error_median=_f(np.median(err)), max_error_worst=_f(err.max()), runs_within_001=int((err < 0.01).sum()),
        greedy_optimal_runs=int((greedy == 17).sum()), episodes_to_optimal_median=_f(np.median(first_opt)))
    ea = grid["ea"]
    chose, on = grid["ea_chose_optimal"], grid["ea_on_path"]
    on_share = chose[on].mean()
    opt_pop = (ea.fitness == grid["optimum"]).mean(axis=1)
    gen17 = _first_stable(ea.best == grid["optimum"])
    add("grid", "EARL1 converges its population on the profitable state-action pairs", "Table 2 (converged alleles)",
        f"after {spec.generations} generations: best policy scores 17 in {int((ea.best[-1] == 17).sum())}/{spec.runs} "
        f"runs (first at generation {np.median(gen17):.0f}, median: {np.median(gen17 + 1) * spec.population:.0f} "
        f"evaluations); {opt_pop.mean():.0%} of the population scores 17; on the boxes a policy visits "
        f"{on_share:.0%} of genes hold an optimal action",
        "holds" if (ea.best[-1] == 17).mean() >= 0.9 and on_share >= 0.8 else "holds in part",
        best17_runs=int((ea.best[-1] == 17).sum()), population_at_17=_f(opt_pop.mean()),
        visited_genes_optimal=_f(on_share), generations_to_17_median=_f(np.median(gen17)))
    ok8, n = _table4_match(TABLE2_FITNESS)
    f7 = TABLE2_FITNESS.copy()
    f7[0] = 7.0
    ok7, _ = _table4_match(f7)
    add("grid", "Table 4 is the implicit value estimate of the Table 2 population (mean fitness per state-action)",
        f"{n} legible numbers",
        f"{ok8}/{n} reproduced with Table 2's fitnesses as printed; {ok7}/{n} if policy 1 scores 7 (not 8); "
        f"our payoffs give policy 1 {grid['table2_returns'][0]:g} and the others "
        f"{', '.join(f'{v:g}' for v in grid['table2_returns'][1:])} as printed",
        "holds" if max(ok7, ok8) == n else "holds in part", legible=n, matches_as_printed=ok8, matches_policy1_7=ok7)
    implicit = grid["ea_implicit"]
    missing = np.isnan(implicit).any(axis=2).sum(axis=1)
    add("grid", "A converged population has no statistics on the actions it dropped ('?' in Table 4), unlike TD",
        "7 converged states in Table 2",
        f"final populations: {np.mean(missing):.1f} of 25 states (mean over runs) have an action no policy takes; "
        f"the Q-table holds all 50 values",
        "holds" if np.mean(missing) > 0 else "does not hold", states_without_estimate_mean=_f(np.mean(missing)))
    off = ~on
    majority = np.maximum(ea.population.mean(axis=1), 1 - ea.population.mean(axis=1))  # (runs, 25)
    visited_any = on.any(axis=1)
    add("grid", "Genes of states the policies never visit drift (mutations accumulate there, section 9.2)", "-",
        f"allele agreement in the final population: {majority[visited_any].mean():.0%} on boxes some policy visits, "
        f"{majority[~visited_any].mean():.0%} on boxes none visits; {off.mean():.0%} of all genes are off-path",
        "holds" if majority[~visited_any].mean() < majority[visited_any].mean() else "does not hold",
        agreement_visited=_f(majority[visited_any].mean()), agreement_unvisited=_f(majority[~visited_any].mean()))


def _hidden_claims(add: Add, spec: EarlSpec, hid: dict[str, Any]) -> None:
    """The hidden-state claims (Figure 13, Table 5, Figure 14)."""
    qpol = hid["q_policy"]
    every = (qpol == np.array(hidden.Q_POLICY)).all(axis=1)
    qb = hid["q_final"][:, hidden.BLUE]
    add("hidden", "A table Q-learner converges to (red R, green L, blue R) in every run", "every run (Table 5)",
        f"{int(every.sum())}/{spec.runs} runs", "holds" if every.all() else "does not hold", runs=int(every.sum()))
    add("hidden", "Q(blue, L) -> -0.5 and Q(blue, R) -> 1", "-0.5, 1",
        f"Q(blue,L) mean {qb[:, 0].mean():.3f} (runs {qb[:, 0].min():.2f} .. {qb[:, 0].max():.2f}); Q(blue,R) mean "
        f"{qb[:, 1].mean():.3f} (runs {qb[:, 1].min():.2f} .. {qb[:, 1].max():.2f}) after {spec.hidden_episodes} "
        f"episodes (alpha 1/n, epsilon {spec.hidden_epsilon})",
        "holds" if abs(qb[:, 0].mean() + 0.5) < 0.05 and np.allclose(qb[:, 1], 1, atol=1e-6) else "does not hold",
        q_blue_l_mean=_f(qb[:, 0].mean()), q_blue_l_min=_f(qb[:, 0].min()), q_blue_l_max=_f(qb[:, 0].max()),
        q_blue_r_mean=_f(qb[:, 1].mean()))
    add("hidden", "The Q-learner's policy earns 1.0", "1.0", f"{hid['q_expected'].mean():.3f} (mean of runs)",
        "holds" if np.allclose(hid["q_expected"], 1.0) else "does not hold", expected=_f(hid["q_expected"].mean()))
    vals = hid["policy_values"]
    best = hid["policies"][int(np.argmax(vals))]
    add("hidden", "The best policy for what the agent senses is (red R, green R, blue L), earning 1.875", "1.875",
        f"exhaustive over the 8 policies: ({', '.join(hidden.ACTIONS[a] for a in best)}) earns {vals.max():g}",
        "holds" if tuple(best) == hidden.OPTIMAL_POLICY and vals.max() == 1.875 else "does not hold")
    shares = {t: float(e.share[-1].mean()) for t, e in hid["ea"].items()}
    head = spec.hidden_trials[0]
    desc = "; ".join(f"{_trials_label(t)} {s:.0%}" for t, s in shares.items())
    add("hidden", "An EA (binary tournament, 50, crossover 0.8, mutation 0.01) converges about 80 % of its "
        "population on (red R, green R, blue L), mean of 100 runs (Figure 14); holds here at >= 75 % with exact fitness",
        "about 80 %",
        f"share at generation {spec.generations} by fitness evaluation: {desc}",
        "holds" if shares[head] >= 0.75 else ("holds in part" if shares[head] >= 0.5 else "does not hold"),
        shares={_trials_label(t): _f(s) for t, s in shares.items()})
    ea_value = {t: float(hidden.expected_reward(e.population).mean()) for t, e in hid["ea"].items()}
    add("hidden", "The EA's policies earn more than the Q-learner's in the presence of hidden state", "1.875 vs 1.0",
        f"mean expected reward of the final populations: "
        f"{'; '.join(f'{_trials_label(t)} {v:.3f}' for t, v in ea_value.items())}; Q-learner {hid['q_expected'].mean():.3f}",
        "holds" if ea_value[head] > hid["q_expected"].mean() else "does not hold",
        ea={_trials_label(t): _f(v) for t, v in ea_value.items()}, q=_f(hid["q_expected"].mean()))


def _trials_label(t: int) -> str:
    return "exact" if t == 0 else f"{t}-trial"


def _first_stable(ok: np.ndarray) -> np.ndarray:
    """(runs,) the first index from which ``ok`` (steps, runs) stays true to the end; steps if never."""
    steps = ok.shape[0]
    tail = np.flip(np.logical_and.accumulate(np.flip(ok, axis=0), axis=0), axis=0)
    return np.where(tail.any(axis=0), np.argmax(tail, axis=0), steps).astype(float)


def _grid_rows(grid: dict[str, Any]) -> list[dict[str, Any]]:
    q, qs, imp = grid["q_final"], grid["qstar"], grid["ea_implicit"]
    t4 = grid["table4_from_table2"]
    rows = []
    for s in range(gridworld.N_STATES):
        for a, name in enumerate(gridworld.ACTIONS):
            col = imp[:, s, a]
            rows.append({"state": gridworld.STATE_NAMES[s], "action": name, "payoff": gridworld.PAYOFF[s],
                         "q_exact": qs[s, a], "table1": TABLE1_D[s] if a == 1 else "",
                         "q_learned_mean": _f(q[:, s, a].mean(), 4), "q_learned_min": _f(q[:, s, a].min(), 4),
                         "q_learned_max": _f(q[:, s, a].max(), 4),
                         "earl1_implicit_mean": _f(np.nanmean(col), 3) if np.isfinite(col).any() else "",
                         "earl1_runs_without_estimate": int(np.isnan(col).sum()),
                         "table2_implicit": _f(t4[s, a], 3) if np.isfinite(t4[s, a]) else "?",
                         "table4_legible": "" if TABLE4[a][s] is None else TABLE4[a][s]})
    return rows


def _plots(out: Path, spec: EarlSpec, grid: dict[str, Any], hid: dict[str, Any]) -> list[str]:
    """The two figures, or none (with the reason printed) when matplotlib is not installed."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no figures (pip install matplotlib, then rerun with --report-only)")
        return []
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8))
    gq = grid["q_greedy_return"].mean(axis=1)
    ax1.plot(np.arange(1, len(gq) + 1), gq, label="Q-learning: greedy policy's score")
    ea = grid["ea"]
    evals = (np.arange(ea.best.shape[0]) + 1) * spec.population
    ax1.plot(evals, ea.best.mean(axis=1), label="EARL1: best of population")
    ax1.plot(evals, ea.mean.mean(axis=1), label="EARL1: population mean")
    ax1.set(xscale="log", xlabel="episodes (policy evaluations for EARL1)", ylabel=f"score, mean of {spec.runs} runs",
            title="Grid world (optimum 17)")
    ax1.legend(fontsize=8)
    ax2.semilogy(np.arange(1, len(gq) + 1), np.median(grid["q_error"], axis=1))
    ax2.set(xlabel="episode", ylabel="max |Q - Q*|, median of runs", title="Q-learning: error of the table")
    fig.tight_layout()
    fig.savefig(out / "fig_grid.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    for t, e in hid["ea"].items():
        ax.plot(np.arange(e.share.shape[0]), 100 * e.share.mean(axis=1), label=f"fitness: {_trials_label(t)}")
    ax.axhline(80, color="grey", ls=":", label="survey: about 80 %")
    ax.set(xlabel="generation", ylabel="% of population on (R, R, L)", ylim=(0, 100),
           title=f"Hidden state: EA population on the optimum ({spec.runs} runs)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fig14_hidden.png", dpi=110)
    plt.close(fig)
    return ["fig_grid.png", "fig14_hidden.png"]


def write_report(out: Path, spec: EarlSpec, grid: dict[str, Any], hid: dict[str, Any], *,
                 seconds: dict[str, float]) -> dict[str, Any]:
    """Write every file into ``out`` (an existing directory) and return what went into results.json."""
    out = Path(out)
    found = claims(spec, grid, hid)
    write_csv(out / "grid_q.csv", _grid_rows(grid))
    write_csv(out / "table4.csv", [{"state": gridworld.STATE_NAMES[s], "action": gridworld.ACTIONS[a],
                                    "from_table2": _f(grid["table4_from_table2"][s, a], 3),
                                    "table4_legible": "" if TABLE4[a][s] is None else TABLE4[a][s]}
                                   for a in (0, 1) for s in range(gridworld.N_STATES)])
    ea = grid["ea"]
    write_csv(out / "grid_q_curve.csv", [
        {"episode": i + 1, "greedy_return_mean": _f(grid["q_greedy_return"][i].mean(), 4),
         "max_error_median": _f(np.median(grid["q_error"][i]), 5), "max_error_worst": _f(grid["q_error"][i].max(), 5)}
        for i in range(grid["q_error"].shape[0])])
    write_csv(out / "grid_ea_curve.csv", [
        {"generation": g, "evaluations": (g + 1) * spec.population, "best_mean": _f(ea.best[g].mean(), 4),
         "population_mean": _f(ea.mean[g].mean(), 4)} for g in range(ea.best.shape[0])])
    write_csv(out / "hidden_curves.csv", [
        {"generation": g, **{f"share_{_trials_label(t)}": _f(e.share[g].mean(), 4) for t, e in hid["ea"].items()}}
        for g in range(spec.generations + 1)])
    pol_rows = []
    for p, v in zip(hid["policies"], hid["policy_values"]):
        row = {"red": hidden.ACTIONS[p[0]], "green": hidden.ACTIONS[p[1]], "blue": hidden.ACTIONS[p[2]],
               "expected_reward": float(v), "q_learner_runs": int((hid["q_policy"] == p).all(axis=1).sum())}
        for t, e in hid["ea"].items():
            row[f"ea_share_{_trials_label(t)}"] = _f((e.population == p).all(axis=2).mean(), 4)
        pol_rows.append(row)
    write_csv(out / "hidden_policies.csv", pol_rows)
    figures = _plots(out, spec, grid, hid)
    results = {"spec": spec.as_dict(), "seconds": {k: round(v, 2) for k, v in seconds.items()},
               "claims": found, "figures": figures}
    write_json(out / "results.json", results)
    write_text(out / "report.md", _markdown(spec, found, figures, seconds))
    return results


def _markdown(spec: EarlSpec, found: list[dict[str, Any]], figures: list[str], seconds: dict[str, float]) -> str:
    lines = [
        "# Appendix C: evolutionary vs temporal-difference learning, reproduced",
        "",
        f"{spec.runs} runs of each learner per experiment, seed {spec.seed}; EARL1: binary tournament, population "
        f"{spec.population}, crossover {spec.crossover}, mutation {spec.mutation}, {spec.generations} generations. "
        "The grid payoffs and the hidden-state rewards are our reconstruction from the survey's text "
        "(docs/earl/reconstruction.md in the repository).",
        "",
        f"Time: grid {seconds.get('grid', 0):.1f} s, hidden state {seconds.get('hidden', 0):.1f} s.",
        "",
        "| | the survey's claim | survey | measured here | verdict |",
        "|---|---|---|---|---|",
    ]
    for c in found:
        lines.append(f"| {c['section']} | {c['claim']} | {c['survey']} | {c['measured']} | **{c['verdict']}** |")
    lines += ["", "Files: `grid_q.csv` (Q-values: exact, Table 1, learned, EARL1's implicit estimate), `table4.csv`, "
              "`grid_q_curve.csv`, `grid_ea_curve.csv`, `hidden_curves.csv` (Figure 14), `hidden_policies.csv`, `results.json`.", ""]
    lines += [f"![{f}]({f})" for f in figures]
    return "\n".join(lines) + "\n"
