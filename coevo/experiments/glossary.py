"""One name for each measure, with its unit and its definition: what the reports, the dashboard and
``docs/glossary.md`` call it (a test holds the three to this table).

The combined robot's measures are the fuel task's (:mod:`coevo.tasks.fuel.terms`, which ``coevo run`` prints
with); the fitnesses, Table 1's classes and the statistics are the experiments'.  The fields on the left are the
names in the run files (``summary.json``, ``curve.jsonl``, ``results.json``); a reader sees only the name on the
right, with its unit.  Two fitnesses are easily confused, and are kept apart by
name: a **generation's best** is the fitness of one generation's best individual, re-evaluated on
``best_episodes`` episodes (the report's learning curve); the **best so far** is the highest such re-evaluation of
any generation until then (with ``best_candidates``, the highest mean of a few policies' repeated re-evaluations):
the policy the worker publishes, and a maximum over noisy values, so it mostly sits above the curve.
"""

from __future__ import annotations

from coevo.tasks.base import Term
from coevo.tasks.fuel.terms import MEASURES, UNIT

__all__ = ["Term", "MEASURES", "CLASSES", "FITNESSES", "STATISTICS", "label", "with_unit", "bounds_of", "TERMS",
           "markdown"]

#: Table 1's docking classes as a study counts them, per cell: the share of its runs in the class.
CLASSES: dict[str, Term] = {
    "good_docking": Term("Good Docking", " % of runs", "runs whose docked of picked is 20 % or more (Table 1)."),
    "no_docking": Term("No Docking", " % of runs", "runs whose Executive picked Docking in under 5 % of episodes "
                       "(Table 1)."),
}

#: The fitnesses a curve or a table shows (module docstring).
FITNESSES: dict[str, Term] = {
    "best_fitness": Term("generation's best", "", "the fitness of one generation's best individual, re-evaluated "
                         "on best_episodes episodes against the partners of that moment: the report's learning curve."),
    "best_so_far": Term("best so far", "", "the fitness of the policy the worker publishes: the highest generation's "
                        "best of the run until then (with best_candidates, Docking's default, the highest mean of the "
                        "few best policies' repeated re-evaluations, which can fall). A maximum over noisy "
                        "re-evaluations, so mostly above the curve; 'final' is its value at the last generation (the "
                        "comparison's tests on Executive fitness use it)."),
    "final_executive_fitness": Term("Executive's final best so far", "", "the Executive's best so far at the "
                                    "last generation, per run: what a comparison's first rank test compares.", UNIT),
    "executive_end": Term("Executive end", "", "the Executive's generation's best at the last generation (the "
                          "report's learning curve's end), a study's mean over a cell's runs.", UNIT),
}

#: The statistics the reports print beside the measures.
STATISTICS: dict[str, Term] = {
    "interval": Term("95 % interval", "", "of a mean: Student's t interval, mean ± t(0.975, n − 1) s/√n; none below "
                     "3 runs; cut at the measure's range where it reaches beyond it (and said: 'clipped at 0'). Of a "
                     "share (k of n runs): Wilson's score interval. Of a difference: Welch's t interval (means), "
                     "Newcombe's (shares)."),
    "p": Term("p", "", "the rank test's p-value (Mann–Whitney for two groups, Kruskal–Wallis for more): exact when "
              "the runs split among the groups in at most 20,000 ways."),
    "min_p": Term("smallest p possible", "", "the lowest p any outcome of a design of this many runs can give: "
                  "two runs a regime cannot give less than 0.33, so a p of 1 there says nothing."),
    "holm": Term("Holm p", "", "a study's p corrected with Holm's method for all its tests together."),
    "a12": Term("A", "", "Vargha–Delaney's effect size: the chance that a run of one regime scores above a run of "
                "the other (ties half); 0.5 no effect, below 0.29 or above 0.71 large."),
    "epsilon2": Term("ε²", "", "Kruskal–Wallis's effect size, H / (n − 1): the share of the ranks' variance the "
                     "groups explain; 0.26 or more large."),
}

#: Every term, by field name.
TERMS: dict[str, Term] = {**MEASURES, **CLASSES, **FITNESSES, **STATISTICS}


def label(field: str) -> str:
    """A field's readable name ('quality_tracking' -> 'Quality Tracking'); the field itself when it has none."""
    term = TERMS.get(field)
    return term.name if term else field


def bounds_of(field: str) -> tuple[float, float] | None:
    """A field's possible range (what its mean's 95 % interval is cut at), None when it has none or no term."""
    term = TERMS.get(field)
    return term.bounds if term else None


def with_unit(field: str, value: float, digits: int = 1) -> str:
    """'Quality Tracking 72.2 %', 'Average Epoch Length 7.05 episodes', 'Executive payoff 0.660'."""
    term = TERMS.get(field)
    return f"{field} {value:.{digits}f}" if term is None else term.text(value, digits)


def markdown() -> str:
    """docs/glossary.md's entries, section by section: each term once, '- **name** (unit): definition.'"""
    sections = (("Measures of the combined robot", MEASURES), ("Table 1's docking classes, counted by a study", CLASSES),
                ("Fitnesses", FITNESSES), ("Statistics", STATISTICS))
    lines: list[str] = []
    for title, terms in sections:
        lines += [f"## {title}", ""]
        for field, t in terms.items():
            span = f"{t.bounds[0]:g} to {t.bounds[1]:g}" if t.bounds else ""
            unit = f" ({'; '.join(x for x in (t.unit.strip(), span) if x)})" if t.unit.strip() or span else ""
            where = "" if terms is STATISTICS else f" Field: `{field}`."
            lines.append(f"- **{t.name}**{unit}: {t.definition}{where}")
        lines.append("")
    return "\n".join(lines)
