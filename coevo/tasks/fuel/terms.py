"""The fuel task's measures as a reader reads them, and a run's class in the report's Table 1.

:data:`MEASURES` names each field of the combined robot's measures (docs/spec.md §2 "Measures"): the names the
reports, the dashboard, ``coevo run``'s last lines and docs/glossary.md use (:mod:`coevo.experiments.glossary`
gathers them with the fitnesses and statistics).  :func:`verdict` says in words what a run's final measures mean
by Table 1's classes (docs/spec.md §2; the thresholds are those of :mod:`coevo.experiments.compare.table1`, which
classes the runs of a comparison, and a test holds the two together).
"""

from __future__ import annotations

from collections.abc import Mapping

from coevo.tasks.base import Term

__all__ = ["MEASURES", "verdict"]

PERCENT = (0.0, 100.0)  # a rate of episodes
UNIT = (0.0, 1.0)  # a payoff

#: The combined robot's measures (docs/spec.md §2 "Measures"), by field name.
MEASURES: dict[str, Term] = {
    "quality_tracking": Term("Quality Tracking", " %", "% of episodes in which the robot was within the tracking "
                             "range (40–60 in from the Target) for at least 80 % of the steps.", PERCENT),
    "successful_docking": Term("Successful Docking", " %", "% of all episodes in which the Executive picked Docking "
                               "and the robot docked.", PERCENT),
    "docking_success_rate": Term("docked of picked", " %", "% of the episodes in which the Executive picked Docking "
                                 "that ended docked; Table 1's Good Docking is 20 % or more.", PERCENT),
    "dock_choice": Term("Docking picked", " %", "% of episodes for which the Executive picked Docking; Table 1's No "
                        "Docking is under 5 %.", PERCENT),
    "average_epoch_length": Term("Average Epoch Length", " episodes", "episodes per complete epoch: 4 for a robot "
                                 "that never docks, up to 10 for one that docks well."),
    "executive_payoff": Term("Executive payoff", "", "the Executive's payoff per epoch, t / (600 + p): t steps "
                             "spent tracking, p the towing penalty; 0 to 1, the mean over the measured epochs.", UNIT),
    "collision_rate": Term("collisions", " %", "% of episodes that ended in a collision (with a wall, the Target or "
                           "the dock), which also ends the epoch.", PERCENT),
    "dry_rate": Term("ran dry", " %", "% of episodes that ended out of fuel.", PERCENT),
    "tracking_payoff": Term("Tracking payoff", "", "Tracking's mean payoff over its episodes: the share of the "
                            "steps in range, 0 after a collision.", UNIT),
    "docking_payoff": Term("Docking payoff", "", "Docking's mean payoff over its episodes: 0.5 + 0.5 m/t when it "
                           "docked, else 0.", UNIT),
    "docking_from_random_starts": Term("Docking alone", " %", "% of fresh single episodes, from random starts, in "
                                       "which a run's final Docking policy docks on its own (300 episodes); it tells "
                                       "a starved Docking agent from one that never learned.", PERCENT),
}

NO_DOCKING_CHOICE = 5.0  # % of episodes the Executive picks Docking, below which Docking is starved
GOOD_DOCKING = 20.0  # % of the episodes Docking was picked for that ended docked
HI_TRACKING = 60.0  # % quality tracking
MED_TRACKING = 30.0


def verdict(m: Mapping[str, float | int | None]) -> str | None:
    """'Table 1 class Good Docking / Hi: the Executive picked Docking in 9.4 % of episodes and 85.9 % of those
    docked (Good Docking: 20 % or more); Quality Tracking 72.2 % (Hi: over 60 %).'  None without the measures."""
    choice, docked, qt = (m.get(k) for k in ("dock_choice", "docking_success_rate", "quality_tracking"))
    if choice is None or docked is None or qt is None:
        return None
    if choice < NO_DOCKING_CHOICE:
        dock, why = "No Docking", f"picked Docking in only {choice:.1f} % of episodes (No Docking: under 5 %)"
    else:
        dock = "Good Docking" if docked >= GOOD_DOCKING else "Poor Docking"
        bar = "20 % or more" if dock == "Good Docking" else "under 20 %"
        why = f"picked Docking in {choice:.1f} % of episodes and {docked:.1f} % of those docked ({dock}: {bar})"
    if qt > HI_TRACKING:
        track, bar = "Hi", "over 60 %"
    else:
        track, bar = ("Med", "over 30 %") if qt > MED_TRACKING else ("Lo", "30 % or less")
    return f"Table 1 class {dock} / {track}: the Executive {why}; Quality Tracking {qt:.1f} % ({track}: {bar})."
