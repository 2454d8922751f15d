"""The CEL learner as a kind of learner (:class:`coevo.rundir.kinds.LearnerKind`), installed as the entry point
``cel`` of the group ``coevo.kinds``.

Its worker is :class:`~coevo.cel_service.learner.CelLearner`, its run :class:`~coevo.cel_service.run.CelRun`
(``coevo cel`` starts and resumes it), its settings :class:`~coevo.cel.settings.CelSettings` (run.json's ``cel``
block), its default task the door; ``coevo chaos --kind cel`` fails the robot's sonars halfway through, in
lockstep; ``coevo check`` and ``coevo replay`` read and replay its execution module and case base
(:mod:`coevo.cel_service.audit`).  Everything is imported when first used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from coevo.rundir.kinds import LearnerKind, later, later_class

if TYPE_CHECKING:
    from coevo.config import GAConfig

__all__ = ["CEL"]


def _chaos_settings(ga: GAConfig) -> dict[str, Any]:
    """A CEL run under ``coevo chaos``: Figure 3's failure halfway through, the learner in lockstep with the robot."""
    from coevo.cel.settings import FIGURE3_SCHEDULE

    return {"cel": {"schedule": [[ga.generations // 2, list(FIGURE3_SCHEDULE[0][1])]]}, "max_lead": 0}


_AUDIT = "coevo.cel_service.audit"

#: A CEL run's learner (``coevo cel``; ``coevo chaos --kind cel``).
CEL = LearnerKind("cel", "a CEL run", later_class("coevo.cel_service.learner", "CelLearner"),
                  later_class("coevo.cel_service.run", "CelRun"), settings=later_class("coevo.cel.settings", "CelSettings"),
                  default_task="door", chaos_settings=_chaos_settings, curve=later(_AUDIT, "learner_curve"),
                  present=lambda run: run.execution.meta_json.exists(),
                  check_run=later(_AUDIT, "check_execution"), replay_run=later(_AUDIT, "replay_execution"))
