"""The learning module as a process on the bus: a door worker whose model follows the robot's capabilities.

``coevo worker --settings RUN/run.json --behaviour door`` in a CEL run (its run.json
has a ``cel`` block) is a :class:`CelLearner`: the co-evolution worker (publication log,
store sync, checkpoints, heartbeats, resume; :mod:`coevo.agents.worker`) around a
:class:`~coevo.cel.learning.LearningModule` instead of a bare GA.  What it adds:

* **Capabilities in.**  It subscribes to the execution module's capability lists
  (:class:`~coevo.bus.messages.CapabilityUpdate`, key ``coevo/RUN/capabilities/ROBOT``)
  and, between generations, takes every one with a newer change number, in the
  monitor's order (as the lockstep run does).  A list other than its model's makes it
  remodel and restart (report §6).  Each change
  it takes goes to ``changes.jsonl``: after how many generations, which list, the case
  it stored and the cases it restarted from, which is all ``coevo replay`` needs.
* **Best since the last change out.**  It publishes a policy when a generation beats
  the best since the last change (report §7), not the GA's best of the whole run.
* **The case base in the broker's store.**  With ``cel.case_base`` its case base starts
  from the cases the store holds for the run (``coevo cel --cases-from`` puts an
  earlier run's there) and each case it stores on a change is put on
  ``coevo/RUN/case/door`` for the broker; ``cases.jsonl`` keeps every case it knows,
  fsynced before anything leaves, and everything in it is put again whenever a broker
  (re)appears, so the store ends up holding them all.
* **Paced by the robot.**  It starts generation g + 1 only once the robot has played
  the trials of generation ``g - max_lead`` (:class:`RobotPacer`; ``max_lead`` 0: the
  lockstep order of docs/cel.md, so a change seen during generation g's trials is
  learned from before generation g + 1).  An execution module whose token went is
  waited for ``cel.patience`` (30) seconds, a restart's time; after that the learner
  learns on with the model it has, and the robot, once back, catches up.  A fresh
  learner waits for its robot to show up for as long as it takes.
"""

from __future__ import annotations

import json
import logging
import math
import time
from contextlib import AbstractContextManager
from collections.abc import Callable
from typing import IO, TYPE_CHECKING, Any

from coevo.agents.inbox import Inbox
from coevo.agents.outbox import BrokerWatch
from coevo.agents.pacing import Pacer
from coevo.agents.worker import Worker
from coevo.bus import keys
from coevo.bus.messages import CapabilityUpdate, CaseUpdate, ExecutionStatus
from coevo.bus.session import drain_messages, query_messages, ring_subscriber, Session
from coevo.cel.casebase import Case, CaseBase
from coevo.cel.learning import LearningModule
from coevo.cel.settings import CelSettings
from coevo.errors import ConfigError, MessageError, ServiceError
from coevo.ga import GA, GenerationReport
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.rundir.layout import WorkerPaths, append_durably, read_cases, write_text

if TYPE_CHECKING:
    from coevo.bus.messages import Message
    from coevo.bus.session import Ring
    from coevo.rundir.settings import RunSettings

__all__ = ["CelLearner", "RobotPacer", "case_of"]

log = logging.getLogger(__name__)


def case_of(msg: CaseUpdate, seq: int) -> Case:
    return Case(tuple(msg.capabilities), msg.ruleset(), msg.fitness, msg.generation, seq)


class RobotPacer(Pacer):
    """A learner's pacing by its execution module: the robot has completed generation j's trials when it has
    played ``K (j + 1)`` trials (generation 0's are played with the initial rules)."""

    def __init__(self, session: Session, run: str, robot: str, *, trials_per_generation: int, max_lead: int | None,
                 patience: float, grace: float) -> None:
        self.K = trials_per_generation
        super().__init__(session, run, (robot,), max_lead=max_lead, grace=grace, settle=patience)
        self._progress[robot] = -1  # not even generation 0's trials played yet

    def _status_key(self, partner: str) -> str:
        return keys.execution(self.run, partner)

    def _alive_key(self) -> str:
        return keys.robot_alive(self.run)

    def _token_partner(self, parts: dict[str, str]) -> tuple[str, str]:
        return parts.get("robot", ""), parts.get("robot", "")

    def _progress_of(self, msg: Message) -> tuple[str, int, bool] | None:
        if not isinstance(msg, ExecutionStatus):
            return None
        return msg.robot, msg.trial // self.K - 1, msg.done


class _Capabilities:
    """The ring of capability lists from the run's robot (the gate checks it is the run's robot)."""

    def __init__(self, session: Session, run: str, reject: Callable[[MessageError, str], None]) -> None:
        self._session, self.run, self._reject = session, run, reject
        self._ring: Ring | None = None

    def __enter__(self) -> _Capabilities:
        self._ring = ring_subscriber(self._session, keys.capabilities(self.run), 64)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._ring is not None:
            self._ring.undeclare()
            self._ring = None

    def since(self, after: int) -> list[CapabilityUpdate]:
        """The lists whose change number is above ``after`` that arrived, one per change, in the monitor's order
        (two changes within one generation's trials are both taken, as the lockstep run takes them)."""
        if self._ring is None:  # not entered yet, or closed: nothing can have arrived
            return []
        got: dict[int, CapabilityUpdate] = {}
        for _, msg in drain_messages(self._ring, 64, self._reject):
            if isinstance(msg, CapabilityUpdate) and msg.change > after:
                got.setdefault(msg.change, msg)
        return [got[c] for c in sorted(got)]


class CelLearner(Worker):
    """The learning module as a worker; see the module docstring."""

    def __init__(self, settings: RunSettings, **kwargs: Any) -> None:
        if settings.block("cel") is None:
            raise ConfigError("a CEL learner needs a run.json with a cel block (made by coevo cel)")
        super().__init__(settings, **kwargs)
        self.cel: CelSettings = settings.block("cel")
        self.logs = WorkerPaths.LOGS + WorkerPaths.CEL_LOGS
        self.module: LearningModule | None = None
        self.change = -1  # the monitor's change number of the list the model follows (-1: none taken yet)
        self.cases_put = 0  # cases this learner stored (its CaseUpdate versions)
        self._cases_found = False  # the store's cases were looked up (a fresh start) or read from the log
        self._caps: _Capabilities | None = None
        self._case_log: IO[str] | None = None

    def meta(self) -> dict[str, Any]:
        return {**super().meta(), "cel": self.cel.model_dump(mode="json")}

    # ------------------------------------------------------------ the learner
    def make_ga(self) -> GA:
        self.module = LearningModule(self.world, self.ga_cfg, seed=self.seed,  # type: ignore[arg-type]
                                     case_base=CaseBase() if self.cel.case_base else None, keep=self.cel.keep,
                                     cases=self.cel.cases)
        return self.module.ga

    @property
    def _m(self) -> LearningModule:
        if self.module is None:
            raise RuntimeError("the learning module is made in run()")
        return self.module

    def learner_state(self, ga: GA) -> dict[str, Any]:
        return {"module": self._m.state_dict(), "change": self.change, "cases_put": self.cases_put}

    def load_learner(self, ga: GA, state: dict[str, Any]) -> None:
        self._m.load_state(state["module"])
        self.change, self.cases_put = int(state["change"]), int(state["cases_put"])

    def restore(self, ga: GA, state: dict[str, Any] | None) -> float:
        paced = super().restore(ga, state)
        if state is not None:
            self._best = float(self._m.best_fitness) if self._m.best is not None else 0.0
            if self._m.best is not None:  # the robot's rules: the best since the last change, not the GA's of the run
                write_text(self.paths.best_rules, format_ruleset(self._m.best))
            self._load_cases()
        return paced

    def _load_cases(self) -> None:
        """A resumed learner's case base: its log, cut back to the checkpoint (every case it knew then)."""
        base = self._m.case_base
        if base is None:
            return
        msgs = read_cases(self.paths.cases)
        self._m.case_base = CaseBase(case_of(m, i) for i, m in enumerate(msgs))
        self._cases_found = bool(msgs) or self._m.generation_no > 0

    def generation(self, ga: GA) -> tuple[GenerationReport, RuleSet | None, float]:
        step = self._m.generation(tick=self._tick)
        return step.report, step.new_best, float(self._m.best_fitness) if self._m.best is not None else 0.0

    def pacer(self, session: Session) -> Pacer:
        return RobotPacer(session, self.run_id, self.cel.robot, trials_per_generation=self.cel.trials_per_generation,
                          max_lead=self.max_lead, patience=self.cel.patience,
                          grace=self.cel.patience if self._m.generation_no else math.inf)  # a fresh learner: start order free

    def services(self, session: Session, broker: BrokerWatch) -> list[AbstractContextManager[object]]:
        self._session, self._broker = session, broker
        self._caps = _Capabilities(session, self.run_id, self._reject)
        self._case_log = open(self.paths.cases, "a", encoding="utf-8")
        return [self._caps, self._case_log]

    # ------------------------------------------------------------ between generations
    def take_in(self, inbox: Inbox, completed: int) -> None:
        super().take_in(inbox, completed)
        if not self._cases_found:
            self._find_cases()
        if self._broker.back.is_set():
            self._put_cases()  # a (re)appeared broker: it may lack some (the store ignores what it holds)
        for msg in self._caps.since(self.change) if self._caps is not None else []:
            self._take_change(msg, completed)

    def _take_change(self, msg: CapabilityUpdate, completed: int) -> None:
        """Follow the monitor's list (remodel and restart) if it is not the model's; log it for replay."""
        self.change = msg.change
        caps = tuple(msg.capabilities)
        try:
            changed = self._m.set_capabilities(caps)
        except ConfigError as exc:  # a list of sonars this task does not have: nothing to learn from
            self._reject(MessageError("invalid", str(exc)), keys.capabilities(self.run_id, msg.robot))
            return
        if not changed:
            return
        case = self._m.last_case
        if case is not None:
            self._store_case(case)
        entry = {"generation": completed, "change": msg.change, "capabilities": list(caps), "robot": msg.robot,
                 "trial": msg.trial, "decision": msg.decision, "received_at": time.time(), "sent_at": msg.sent_at,
                 "stored_case": None if case is None else self.cases_put,
                 "restart_cases": [c.to_dict() for c in self._m.last_cases]}
        with open(self.paths.changes, "a", encoding="utf-8") as f:
            f.write(json.dumps(entry) + "\n")
        log.info("%s: capabilities now %s (change %d, robot trial %d); restarted after generation %d",
                 self.worker_id, ",".join(caps) or "none", msg.change, msg.trial, completed)

    def _find_cases(self) -> None:
        """A fresh learner's case base starts from what the store holds for this run (an earlier run's cases)."""
        self._cases_found = True
        if self._m.case_base is None or not self._broker.up.is_set():
            return
        try:
            found = [m for m in query_messages(self._session, keys.store_cases(self.run_id, self.behaviour),
                                               timeout=self.store_timeout, what="the store's cases", gate=self.gate)
                     if isinstance(m, CaseUpdate)]
        except ServiceError as exc:
            log.warning("%s: %s; starting with an empty case base", self.worker_id, exc)
            return
        self.cases_put = max((m.version for m in found if m.worker == self.worker_id), default=0)  # imported ones
        for msg in found:
            self._log_case(msg)
            self._m.case_base.add(msg.capabilities, msg.ruleset(), fitness=msg.fitness, generation=msg.generation)
        if found:
            log.info("%s: %d cases from the store", self.worker_id, len(found))

    def _log_case(self, msg: CaseUpdate) -> None:
        if self._case_log is None:
            raise RuntimeError("the case log is closed")
        append_durably(self._case_log, msg.model_dump(mode="json"))

    def _store_case(self, case: Case) -> None:
        """Log a case this learner stored (fsynced), then put it for the broker's store."""
        self.cases_put += 1
        msg = CaseUpdate(run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, version=self.cases_put,
                         generation=case.generation, fitness=case.fitness, capabilities=list(case.capabilities),
                         rules=case.rules.to_dict(), sent_at=time.time())
        self._log_case(msg)
        self._put(msg)

    def _put(self, msg: CaseUpdate) -> None:
        key = keys.case(self.run_id, self.behaviour)
        self._session.put(key, self.gate.seal(msg, key))

    def _put_cases(self) -> None:
        """Put again every case this learner stored (the broker keeps one copy of each)."""
        for msg in read_cases(self.paths.cases):
            if msg.worker == self.worker_id:
                self._put(msg)
