"""The report's Table 1: nine classes of a finished run, and the report's own counts.

A run is classed by its combined robot's measures (docs/spec.md §2, report Appendix A §7):

- Docking: *No Docking* when the Executive picks Docking in under 5 % of episodes
  (starvation); otherwise *Good Docking* when at least 20 % of the episodes in
  which the Executive picked Docking end docked, else *Poor Docking*.  The report
  says "≥ 20 % episodes with successful docking"; with the fuel as it states it one
  docking per epoch keeps the robot going, so an ideal robot docks in only ~10 % of
  all its episodes, and a threshold on all episodes would class it Poor Docking and
  contradict the report's 10 of 10 Good Docking Independent runs.  docs/spec.md §2
  ("Measures") therefore reads the 20 % on the picked episodes; reports show both
  numbers (``docking_success_rate`` and ``successful_docking``).
- Tracking: *Hi* over 60 % quality tracking, *Med* over 30 %, else *Lo*.

The report's counts come from its Table 1 and its text: Mutual, 9 of 10 runs
never picked Docking (4 Hi, 3 Med, 2 Lo tracking) and the one run that docked
"was not high" in tracking; Independent, 10 of 10 dock well, 5 Hi and 5 Med.
The scan of the table lost the column of Mutual's docking run; the text says
docking "was integrated into the Robot's behavior", which we read as Good
Docking with Med tracking *(our reading)*.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

from coevo.experiments.compare.reading import Panel, Reading
# the thresholds are the fuel task's, defined once with its terms
from coevo.tasks.fuel.terms import GOOD_DOCKING, HI_TRACKING, MED_TRACKING, NO_DOCKING_CHOICE

__all__ = ["BEHAVIOURS", "CURVE", "DOCKING", "TRACKING", "CLASSES", "REPORT_COUNTS", "PANELS", "READING", "classify",
           "count"]

#: The behaviours of the runs Table 1 classes (the fuel task's), and the one whose learning curve a comparison draws.
BEHAVIOURS = ("tracking", "docking", "executive")
CURVE = "executive"

DOCKING = ("Good Docking", "Poor Docking", "No Docking")
TRACKING = ("Hi", "Med", "Lo")
CLASSES = tuple(f"{d} / {t}" for d in DOCKING for t in TRACKING)


REPORT_COUNTS: dict[str, dict[str, int]] = {
    "mutual": {"Good Docking / Med": 1, "No Docking / Hi": 4, "No Docking / Med": 3, "No Docking / Lo": 2},
    "independent": {"Good Docking / Hi": 5, "Good Docking / Med": 5},
}


def docking_class(docking_success_rate: float, dock_choice: float) -> str:
    """From the % of picked Docking episodes that docked and the % of episodes Docking was picked."""
    if dock_choice < NO_DOCKING_CHOICE:
        return "No Docking"
    return "Good Docking" if docking_success_rate >= GOOD_DOCKING else "Poor Docking"


def tracking_class(quality_tracking: float) -> str:
    if quality_tracking > HI_TRACKING:
        return "Hi"
    return "Med" if quality_tracking > MED_TRACKING else "Lo"


def classify(measures: Mapping[str, float]) -> str:
    """The Table 1 class of one run from its combined robot's measures."""
    d = docking_class(float(measures["docking_success_rate"]), float(measures["dock_choice"]))
    return f"{d} / {tracking_class(float(measures['quality_tracking']))}"


def count(classes: Iterable[str]) -> dict[str, int]:
    """Counts in all nine classes (zeros included), in the table's order."""
    c = Counter(classes)
    unknown = set(c) - set(CLASSES)
    if unknown:
        raise ValueError(f"not Table 1 classes: {sorted(unknown)}")
    return {k: c.get(k, 0) for k in CLASSES}


#: The report's panels (its Figures 5 and 6: each behaviour's learning curve), then Docking's own measure and how often
#: the Executive picked Docking.
PANELS = (
    Panel("Executive learning curve", "executive", "best_fitness", "generation's best fitness", 1.0),
    Panel("Docking learning curve", "docking", "best_fitness", "generation's best fitness", 1.0),
    Panel("Tracking learning curve", "tracking", "best_fitness", "generation's best fitness", 1.0),
    Panel("Quality Tracking (Executive's generation's best)", "executive", "quality_tracking", "% of episodes", 100.0),
    Panel("Docking alone (Docking's generation's best)", "docking", "docking_from_random", "% of fresh starts", 100.0),
    Panel("Docking picked (Executive's generation's best)", "executive", "dock_choice", "% of episodes", 100.0),
)

#: How the fuel task's comparisons are read (its ``comparison``): Table 1, the Executive's curve, the Docking probe.
READING = Reading(panels=PANELS, report="coevo.experiments.compare.report:write_report", classify=classify,
                  classes=CLASSES, report_counts=REPORT_COUNTS, curve=CURVE, rules_read=("docking",))
