"""What one line of each JSON-lines log of a run directory holds: one schema per file kind.

    RUN/workers/B/curve.jsonl       :class:`CurveLine`   (and any columns of the learner's report)
    RUN/workers/B/adoptions.jsonl   :class:`AdoptionLine`
    RUN/workers/B/published.jsonl   :class:`~coevo.bus.messages.PolicyUpdate` (as the store keeps it)
    RUN/store/B.jsonl               :class:`~coevo.bus.messages.PolicyUpdate`
    RUN/store/cases/B.jsonl         :class:`~coevo.bus.messages.CaseUpdate`

:func:`coevo.rundir.layout.read_jsonl` checks each line against its file's schema, so a damaged
line (a field missing or of the wrong type, a NaN fitness) is a RunDirError naming the file and
line, never a TypeError deep inside a reader. A schema names the fields the readers use; other
columns are kept as they are (a curve line's columns are the learner's to choose).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, StrictInt, StrictStr

from coevo.bus.messages import BehaviourName, CaseUpdate, Fitness, PolicyUpdate, Rules

__all__ = ["CurveLine", "AdoptionLine", "LOG_SCHEMAS"]


class _Line(BaseModel):
    model_config = ConfigDict(frozen=True, extra="allow", strict=True)


class CurveLine(_Line):
    """One generation of a worker's learning curve."""

    generation: StrictInt = Field(ge=1)


class AdoptionLine(_Line):
    """A partner version a worker took after ``generation`` of its own generations (:mod:`coevo.agents.inbox`)."""

    generation: StrictInt = Field(ge=0)
    partner: BehaviourName
    version: StrictInt = Field(ge=1)
    from_worker: StrictStr
    fitness: Fitness
    received_at: float
    rules: Rules | None = None  # the rules adopted, so a replay needs nothing but this log
    rules_digest: StrictStr | None = None


#: The schema of each append-only log a process's checkpoint keeps in step, by its file name (a log not named here:
#: any JSON object a line).  What a resume checks the logs against before it starts anything.
LOG_SCHEMAS: dict[str, type[BaseModel]] = {"curve.jsonl": CurveLine, "adoptions.jsonl": AdoptionLine,
                                           "published.jsonl": PolicyUpdate, "cases.jsonl": CaseUpdate}
