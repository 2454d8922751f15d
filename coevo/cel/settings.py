"""A live CEL run's own settings (``run.json``'s ``cel`` block; docs/spec.md §5).

A CEL run is a door-task run (:class:`~coevo.rundir.settings.RunSettings` with ``task =
"door"``) plus these: the failure schedule of the execution module's world, the
execution module's clock and monitor, and the learner's restart.  ``coevo cel``
writes them; the learner (``coevo worker``) and the execution module (``coevo
execution``) read them from the same ``run.json``.

The clock *(ours, as in the lockstep experiment, docs/cel.md)*: the execution module
plays ``trials_per_generation`` (K = 100) trials per learner generation.  Before the
learner has finished any generation it plays generation 0's K trials with the
initial rules; after the learner reports generation g it may play up to trial
``K (g + 1)``, always with the newest rules it has received.  It is the learner that
sets the pace (the robot's trials cost far less than a generation); the learner in
turn waits when it is more than ``RunSettings.max_lead`` generations ahead of the
robot, so the two stay together as in Figure 3 while each runs on its own.  A
schedule event ``(g, failed)`` fails those sonars of the robot's world from the
first trial of generation g on (report §7: "at the beginning of generation 50, the
three sonars fail").  When one of the two is gone (its liveliness token went: killed, crashed, or
finished before the other was restarted), the other waits ``patience`` (30) seconds for
it to come back, then goes on without it and waits for it again once it is back: the
robot plays on with the rules it has, the learner learns on with the model it has.  At
the start a robot waits for its learner to show up for as long as it takes (start
order does not matter); a resumed one waits ``patience``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, ClassVar

from pydantic import Field, field_validator

from coevo.cel.execution import EXTERNAL_WINDOW, FailureSchedule
from coevo.cel.learning import CASES, KEEP
from coevo.cel.monitor import REPAIR_RUN, ZERO_RUN
from coevo.config import Settings
from coevo.errors import ConfigError

__all__ = ["CelSettings", "FIGURE3_SCHEDULE", "ROBOT_SEED_OFFSET"]

#: Figure 3 (report §7): front, front-right and right fail at the beginning of generation 50.
FIGURE3_SCHEDULE: tuple[tuple[int, tuple[str, ...]], ...] = ((50, ("front", "front_right", "right")),)
#: The execution module's generator is seeded with the run's seed plus this (as in :func:`coevo.cel.experiment.run_cel`).
ROBOT_SEED_OFFSET = 1_000_003


class CelSettings(Settings):
    """See the module docstring."""

    schedule: tuple[tuple[int, tuple[str, ...]], ...] = Field(
        FIGURE3_SCHEDULE, description="(generation, failed sonars): the robot's world from that generation's first trial "
                                      "on; () repairs every sonar")
    trials_per_generation: int = Field(100, ge=1, le=100_000, description="K: the robot's trials per learner generation")
    chunk: int = Field(10, ge=1, le=100_000, description="(ours) trials the robot plays between two looks at the bus")
    window: int = Field(EXTERNAL_WINDOW, ge=1, le=100_000, description="external performance: over the last N trials")
    zero_run: int = Field(ZERO_RUN, ge=1, le=10_000, description="the monitor: zero readings in a row to mark a sonar defective")
    repair_run: int = Field(REPAIR_RUN, ge=1, le=10_000, description="the monitor: non-zero readings in a row to mark it working")
    case_base: bool = Field(False, description="restart from the case base's nearest cases (else copies of the initial rules)")
    keep: float = Field(KEEP, ge=0, le=1, description="the share of the population a restart keeps")
    cases: int = Field(CASES, ge=1, le=1_000, description="how many nearest cases fill the replaced half")
    patience: float = Field(30.0, gt=0, le=86400, description="(ours) seconds either module waits for the other once its "
                            "token is gone (a restart), before going on without it")
    robot: str = Field("robot", pattern=r"^[A-Za-z0-9_.-]{1,64}$", description="the execution module's id")

    @field_validator("schedule", mode="before")
    @classmethod
    def _events(cls, v: Any) -> Any:
        try:
            events = FailureSchedule(tuple((int(g), tuple(f)) for g, f in v)).events  # names checked, in order
        except (TypeError, ValueError) as exc:
            raise ValueError(f"a schedule is a list of (generation, [failed sonars]): {exc}") from None
        except ConfigError as exc:
            raise ValueError(str(exc).replace("trial", "generation")) from None
        return events

    #: The tasks a CEL run learns: the door task's robot has the sonars that fail (report Appendix B).
    TASKS: ClassVar[tuple[str, ...]] = ("door",)

    def check_fits(self, *, task: str, generations: int, worker_ids: Iterable[str]) -> None:
        """A ValueError unless these settings fit a run of ``task`` with ``generations`` and these worker ids."""
        if task not in self.TASKS:
            raise ValueError(f"a CEL run (cel settings) is a {' or '.join(self.TASKS)}-task run, not a {task!r} one")
        last = max((g for g, _ in self.schedule), default=0)
        if last > generations:
            raise ValueError(f"the failure schedule's last event is at generation {last}, after the run's "
                             f"{generations} generations")
        if self.robot in set(worker_ids):
            raise ValueError(f"the robot id {self.robot!r} is also a worker id of the roster")

    def failure_schedule(self) -> FailureSchedule:
        """The schedule in trials (the execution module's terms)."""
        return FailureSchedule.at_generations(self.schedule, self.trials_per_generation)

    def total_trials(self, generations: int) -> int:
        """Trials the robot plays in a run of ``generations``: generation 0's, then K per generation."""
        return self.trials_per_generation * (generations + 1)
