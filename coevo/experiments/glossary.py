"""One name for each measure, with its unit and its definition: what the reports, the dashboard and
``docs/glossary.md`` call it (a test holds the three to this table).

The fields on the left are the names in the run files (``summary.json``, ``curve.jsonl``, ``results.json``); a
reader sees only the name on the right, with its unit.  Two fitnesses are easily confused, and are kept apart by
name: a **generation's best** is the fitness of one generation's best individual, re-evaluated on
``best_episodes`` episodes (the report's learning curve); the **best so far** is the highest such re-evaluation of
any generation until then (with ``best_candidates``, the highest mean of a few policies' repeated re-evaluations):
the policy the worker publishes, and a maximum over noisy values, so it mostly sits above the curve.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Term", "MEASURES", "CLASSES", "FITNESSES", "STATISTICS", "label", "with_unit", "TERMS", "markdown"]


@dataclass(frozen=True)
class Term:
    """A measure's readable name, its unit (printed after a value: '%', ' episodes'; '' for none) and what it is."""

    name: str
    unit: str
    definition: str


#: The combined robot's measures (docs/spec.md §2 "Measures"), by field name.
MEASURES: dict[str, Term] = {
    "quality_tracking": Term("Quality Tracking", " %", "% of episodes in which the robot was within the tracking "
                             "range (40–60 in from the Target) for at least 80 % of the steps."),
    "successful_docking": Term("Successful Docking", " %", "% of all episodes in which the Executive picked Docking "
                               "and the robot docked."),
    "docking_success_rate": Term("docked of picked", " %", "% of the episodes in which the Executive picked Docking "
                                 "that ended docked; Table 1's Good Docking is 20 % or more."),
    "dock_choice": Term("Docking picked", " %", "% of episodes for which the Executive picked Docking; Table 1's No "
                        "Docking is under 5 %."),
    "average_epoch_length": Term("Average Epoch Length", " episodes", "episodes per complete epoch: 4 for a robot "
                                 "that never docks, up to 10 for one that docks well."),
    "executive_payoff": Term("Executive payoff", "", "the Executive's payoff per epoch, t / (600 + p): t steps "
                             "spent tracking, p the towing penalty; 0 to 1, the mean over the measured epochs."),
    "collision_rate": Term("collisions", " %", "% of episodes that ended in a collision (with a wall, the Target or "
                           "the dock), which also ends the epoch."),
    "dry_rate": Term("ran dry", " %", "% of episodes that ended out of fuel."),
    "tracking_payoff": Term("Tracking payoff", "", "Tracking's mean payoff over its episodes: the share of the "
                            "steps in range, 0 after a collision."),
    "docking_payoff": Term("Docking payoff", "", "Docking's mean payoff over its episodes: 0.5 + 0.5 m/t when it "
                           "docked, else 0."),
    "docking_from_random_starts": Term("Docking alone", " %", "% of fresh single episodes, from random starts, in "
                                       "which a run's final Docking policy docks on its own (300 episodes); it tells "
                                       "a starved Docking agent from one that never learned."),
}

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
                                    "last generation, per run: what a comparison's first rank test compares."),
    "executive_end": Term("Executive end", "", "the Executive's generation's best at the last generation (the "
                          "report's learning curve's end), a study's mean over a cell's runs."),
}

#: The statistics the reports print beside the measures.
STATISTICS: dict[str, Term] = {
    "interval": Term("95 % interval", "", "of a mean: Student's t interval, mean ± t(0.975, n − 1) s/√n; none below "
                     "3 runs. Of a share (k of n runs): Wilson's score interval. Of a difference: Welch's t interval "
                     "(means), Newcombe's (shares)."),
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


def with_unit(field: str, value: float, digits: int = 1) -> str:
    """'Quality Tracking 72.2 %', 'Average Epoch Length 7.05 episodes', 'Executive payoff 0.660'."""
    term = TERMS.get(field)
    if term is None:
        return f"{field} {value:.{digits}f}"
    places = 3 if term.unit == "" else digits
    return f"{term.name} {value:.{places}f}{term.unit}"


def markdown() -> str:
    """docs/glossary.md's entries, section by section: each term once, '- **name** (unit): definition.'"""
    sections = (("Measures of the combined robot", MEASURES), ("Table 1's docking classes, counted by a study", CLASSES),
                ("Fitnesses", FITNESSES), ("Statistics", STATISTICS))
    lines: list[str] = []
    for title, terms in sections:
        lines += [f"## {title}", ""]
        for field, t in terms.items():
            unit = f" ({t.unit.strip()})" if t.unit.strip() else ""
            where = "" if terms is STATISTICS else f" Field: `{field}`."
            lines.append(f"- **{t.name}**{unit}: {t.definition}{where}")
        lines.append("")
    return "\n".join(lines)
