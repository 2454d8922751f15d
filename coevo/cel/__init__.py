"""Continuous and Embedded Learning (report Appendix B; docs/spec.md §5), the in-process core.

An execution module (:mod:`.execution`) runs the robot in its own world, where sonars
fail on a schedule unknown to the learner, always with the newest rules it has; its
monitor (:mod:`.monitor`) marks a sonar defective from what the robot senses and does
and reports the new capability list; a learning module (:mod:`.learning`) runs a GA
on a simulation model that follows that list, restarts on a change (half its
population kept, half copies of the initial rules or the nearest cases of a case
base, :mod:`.casebase`) and hands each new best to the execution module.
:mod:`.experiment` steps the two in lockstep, deterministically, for the Figure 3
experiment and the cyclic schedule.

:mod:`.settings` is a run's ``cel`` block (part of its ``run.json``).

Nothing here touches the network: the live service builds on it, the learner and the
robot as processes in :mod:`coevo.cel_service`, a whole run on one machine
(``coevo cel``) in :mod:`coevo.cel_service.run`.
"""

from __future__ import annotations

from coevo.cel.casebase import Case, CaseBase, distance
from coevo.cel.execution import CapabilityChange, ExecutionModule, FailureSchedule, Stretch
from coevo.cel.learning import GenerationStep, LearningModule
from coevo.cel.monitor import Monitor, check_capabilities

__all__ = ["Monitor", "check_capabilities", "ExecutionModule", "FailureSchedule", "CapabilityChange", "Stretch",
           "LearningModule", "GenerationStep", "CaseBase", "Case", "distance"]
