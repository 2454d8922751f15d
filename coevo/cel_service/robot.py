"""``coevo execution``: the execution module as a process on the bus (report Appendix B §5, §7).

It runs an :class:`~coevo.cel.execution.ExecutionModule` (the robot in its own world,
where sonars fail on the run's schedule, unknown to the learner, with its monitor)
one stretch of trials after another:

* **Rules in.**  It subscribes to the learner's policies (``coevo/RUN/policy/door``)
  and, before each stretch, takes the newest version that arrived; at its start, and
  whenever a broker (re)appears, it also asks the store for the latest.  Each one it
  takes goes to ``policies.jsonl`` with the trial it is first used on and how long it
  took from the learner's put to here.
* **The clock** (:mod:`coevo.cel.settings`): generation j's ``K`` trials are played
  once the learner has reported finishing j generations (0: the initial rules); the
  robot waits for its learner however slow it is, and for as long as it takes to show up
  at the start; once the learner's token is gone (a restart), or when a resumed robot
  does not see it, for ``patience`` seconds, then it plays on with the rules it has (a
  learner that finished while the robot was down never comes back).  A stretch is ``chunk`` trials (default K: a generation's trials as one batch,
  as the lockstep experiment plays them).
* **Capabilities out.**  Each change of the monitor's list is put on
  ``coevo/RUN/capabilities/ROBOT`` at once and logged (``changes.jsonl``, with the
  world's truth and the detection delay, which the monitor never sees); the current
  list is put again with every heartbeat, so a learner that missed it catches up.
* **Performance out.**  An :class:`~coevo.bus.messages.ExecutionStatus` heartbeat after
  each stretch and about every ``heartbeat_every`` seconds while waiting; one line per
  generation in ``performance.jsonl`` (Figure 3's point: the external performance, the
  outcome rates, the share of decisions not moving forward, the rules used).

A checkpoint after each stretch holds the module's state (rules, generator, window,
monitor) and the lengths of its logs; ``--resume`` cuts the logs back to it and goes
on from there (the same rules as :mod:`coevo.agents.checkpoint`).  What it writes in
``RUN/execution/`` (:class:`~coevo.rundir.layout.ExecutionPaths`): ``execution.json``,
the three logs, ``checkpoint.msgpack`` and, at the end, ``done.json``.
"""

from __future__ import annotations

import json
import logging
import math
import statistics
import threading
import time
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from coevo import __version__
from coevo.agents.checkpoint import cut_logs, load_checkpoint, prepare_dir, resume_problems, save_checkpoint
from coevo.agents.outbox import BrokerWatch
from coevo.agents.pacing import Pacer
from coevo.bus import keys
from coevo.bus.auth import RunKey
from coevo.bus.messages import CapabilityUpdate, Control, ExecutionStatus, PolicyUpdate
from coevo.bus.rejections import Rejections
from coevo.bus.lifecycle import Lifecycle, main_of
from coevo.bus.session import drain_messages, ring_subscriber, Session
from coevo.cel.execution import CapabilityChange, ExecutionModule, Stretch
from coevo.cel.monitor import Monitor
from coevo.cel.settings import ROBOT_SEED_OFFSET
from coevo.errors import ConfigError, MessageError, RunDirError, ServiceError
from coevo.policy.rules import RuleSet
from coevo.bus.session import fetch_latest
from coevo.rundir.layout import ExecutionPaths, read_jsonl, write_json
from coevo.rundir.settings import RunSettings
from coevo.tasks.door import DOOR, default_ruleset
from coevo.tasks.door.settings import SONARS, DoorConfig
from coevo.tasks.door.world import COLLISION, GOAL, TIMEOUT

if TYPE_CHECKING:
    import numpy as np

    from coevo.bus.messages import Message
    from coevo.bus.session import Config, Publisher, Ring

__all__ = ["Execution", "run_execution"]

log = logging.getLogger(__name__)


class _Point:
    """What the trials of one generation did so far (a generation may take several stretches)."""

    def __init__(self, state: dict[str, Any] | None = None) -> None:
        s = state or {}
        self.trials = int(s.get("trials", 0))
        self.goal, self.collision, self.timeout = (int(s.get(k, 0)) for k in ("goal", "collision", "timeout"))
        self.decisions, self.not_forward = int(s.get("decisions", 0)), int(s.get("not_forward", 0))
        self.versions: list[int] = [int(v) for v in s.get("versions", [])]
        self.learner = int(s.get("learner", 0))

    def add(self, st: Stretch, version: int, learner: int) -> None:
        self.trials += len(st.outcome)
        self.goal += int((st.outcome == GOAL).sum())
        self.collision += int((st.outcome == COLLISION).sum())
        self.timeout += int((st.outcome == TIMEOUT).sum())
        self.decisions += st.decisions
        self.not_forward += st.not_forward
        if version not in self.versions:
            self.versions.append(version)
        self.learner = max(self.learner, learner)

    def state(self) -> dict[str, Any]:
        return {"trials": self.trials, "goal": self.goal, "collision": self.collision, "timeout": self.timeout,
                "decisions": self.decisions, "not_forward": self.not_forward, "versions": self.versions,
                "learner": self.learner}

    def row(self, generation: int, ex: ExecutionModule, first: int) -> dict[str, Any]:
        n = max(self.trials, 1)
        return {"generation": generation, "first_trial": first, "external": ex.performance,
                "success": round(100.0 * self.goal / n, 2), "collision": round(100.0 * self.collision / n, 2),
                "timeout": round(100.0 * self.timeout / n, 2),
                "not_forward": round(100.0 * self.not_forward / max(self.decisions, 1), 2),
                "rules_versions": self.versions, "learner_generation": self.learner,
                "world_failed": list(ex.schedule.failed_at(first, ex.world.failed)),
                "capabilities": list(ex.capabilities), "played_at": time.time()}


class Execution:
    """The execution module's process; see the module docstring."""

    def __init__(self, settings: RunSettings, *, out_dir: Path, conf: Config, resume: bool = False,
                 run_key: RunKey | None = None, heartbeat_every: float = 0.5, store_timeout: float = 2.0,
                 broker_wait: float = 30.0) -> None:
        if settings.block("cel") is None:
            raise ConfigError("the execution module needs a CEL run's run.json (one with a cel block, made by coevo cel)")
        if run_key is not None and run_key.run != settings.run:
            raise ConfigError(f"the key is run {run_key.run!r}'s, not run {settings.run!r}'s")
        self.cel = settings.block("cel")
        self.run_id, self.robot = settings.run, settings.block("cel").robot
        self.world: DoorConfig = settings.world_config()  # type: ignore[assignment]
        self.K = self.cel.trials_per_generation
        self.generations = settings.ga.generations
        self.total = self.cel.total_trials(self.generations)
        self.seed = settings.seed + ROBOT_SEED_OFFSET
        self.paths = ExecutionPaths(Path(out_dir))
        self.conf, self.resume = conf, resume
        self.heartbeat_every, self.store_timeout, self.broker_wait = heartbeat_every, store_timeout, broker_wait
        self.rejected = Rejections(self.robot, log)
        self.gate = settings.gate(run_key, reject=self._reject)
        self.module = ExecutionModule(self.world, default_ruleset(), seed=self.seed, schedule=self.cel.failure_schedule(),
                                      monitor=Monitor(zero_run=self.cel.zero_run, repair_run=self.cel.repair_run,
                                                      capabilities=self.world.capabilities), window=self.cel.window)
        self.changes = 0  # the monitor's verdicts so far (CapabilityUpdate.change)
        self.last_change: int | None = None
        self.event_decisions = 0  # decisions since the latest schedule event began (for the detection delay)
        self.point = _Point()
        self.stop = threading.Event()  # a stop message arrived
        self._unsent: list[CapabilityChange] = []  # the monitor's changes of the last stretch, put after its checkpoint
        self._learner = 0  # generations the learner reported finishing
        self._session: Session | None = None
        self._pubs: dict[str, Publisher] = {}
        self._logs: dict[str, IO[str]] = {}

    def _reject(self, err: MessageError, key: str) -> None:
        self.rejected.note(err, key)

    # ------------------------------------------------------------ the directory
    def _ident(self) -> dict[str, Any]:
        return {"run": self.run_id, "robot": self.robot, "seed": self.seed}

    def _meta(self) -> dict[str, Any]:
        return {"coevo": __version__, **self._ident(), "generations": self.generations,
                "world": self.world.model_dump(mode="json"), "cel": self.cel.model_dump(mode="json")}

    def _load(self) -> dict[str, Any] | None:
        """The checkpoint to resume from (None: none, and no logs either); a RunDirError if it cannot be resumed."""
        p = self.paths
        state = load_checkpoint(p.checkpoint, self._ident(), advice=". Put back an intact checkpoint, or start the "
                                "run again as a new run")
        if state is None and any(f.exists() and f.stat().st_size for f in (p.dir / n for n in ExecutionPaths.LOGS)):
            raise RunDirError(f"execution directory {str(p.dir)!r} holds logs but no checkpoint ({p.checkpoint} is "
                              "missing); it cannot be resumed")
        return state

    def resume_problems(self) -> list[str]:
        """What would stop this module's ``--resume`` (:meth:`_prepare`), found by reading every file of its directory
        that it reads, changing nothing: one line a problem."""
        p = self.paths
        return resume_problems(p.dir, what="execution", meta_file=p.meta_json, meta=self._meta(),
                               logs=[p.dir / n for n in ExecutionPaths.LOGS], checkpoint=p.checkpoint, load=self._load,
                               sizes=lambda s: s["log_sizes"], writes=[p.done])

    def _prepare(self) -> None:
        """Create the directory, or check it, cut its logs back to the checkpoint and restore the state (``resume``)."""
        p = self.paths
        logs = [p.dir / n for n in ExecutionPaths.LOGS]
        prepare_dir(p.dir, what="execution", meta_file=p.meta_json, meta=self._meta(), logs=logs, checkpoint=p.checkpoint,
                    resume=self.resume)
        if not self.resume:
            return
        state = self._load()
        cut_logs(logs, state["log_sizes"] if state else {})
        if state is None:
            return
        self.module.load_state(state["module"])
        self.changes, self.last_change = int(state["changes"]), state["last_change"]
        self.event_decisions = int(state["event_decisions"])
        self.point = _Point(state["point"])
        self._learner = int(state["learner"])
        self.rejected.load(state["rejected"])
        log.info("%s resumed at trial %d", self.robot, self.module.trial)

    def _checkpoint(self) -> None:
        for f in self._logs.values():
            f.flush()
        save_checkpoint(self.paths.checkpoint, self._ident(), {
            "module": self.module.state_dict(), "changes": self.changes, "last_change": self.last_change,
            "event_decisions": self.event_decisions, "point": self.point.state(), "learner": self._learner,
            "rejected": self.rejected.as_dict(),
            "log_sizes": {n: (self.paths.dir / n).stat().st_size for n in ExecutionPaths.LOGS}})

    def _write(self, log_name: str, row: dict[str, Any]) -> None:
        self._logs[log_name].write(json.dumps(row) + "\n")

    # ------------------------------------------------------------ the loop
    def run(self) -> dict[str, Any]:
        self._prepare()
        self._logs = {n: open(self.paths.dir / n, "a", encoding="utf-8") for n in ExecutionPaths.LOGS}
        try:
            if not self.paths.checkpoint.exists():
                self._checkpoint()  # from now on, logs without a checkpoint mean it was removed
            self._loop()
        finally:
            for f in self._logs.values():
                f.close()
            self.rejected.flush()
        done = self._done()
        write_json(self.paths.done, done)
        return done

    def _loop(self) -> None:
        with Lifecycle(self.conf, what="execution module session", gate=self.gate) as life:
            s = self._session = life.session
            broker = life.enter(BrokerWatch(s))
            clock = life.enter(Pacer(s, self.run_id, (DOOR,), max_lead=0, wait_limit=math.inf, settle=self.cel.patience,
                                     grace=self.cel.patience if self.module.trial else math.inf))
            policies = life.declare(ring_subscriber(s, keys.policy(self.run_id, DOOR), 32))
            control = life.declare(ring_subscriber(s, keys.control(self.run_id), 16))
            self._pubs = {"caps": life.declare(s.declare_publisher(keys.capabilities(self.run_id, self.robot))),
                          "status": life.declare(s.declare_publisher(keys.execution(self.run_id, self.robot)))}
            life.declare(s.liveliness().declare_token(keys.robot_alive(self.run_id, self.robot)))
            if self.gate.open:
                log.warning("%s: run %s is OPEN: no key, its messages are not authenticated", self.robot, self.run_id)
            if not broker.wait(self.broker_wait, self.stop):
                log.warning("%s: no coevo broker seen after %.0f s; going on", self.robot, self.broker_wait)
            self._put_capabilities()
            while self.module.trial < self.total and not self._stop_asked(control) and not life.stop.is_set():
                generation = self.module.trial // self.K
                clock.wait(generation, self.stop, tick=lambda: self._beat(control), tick_every=self.heartbeat_every,
                           poll=0.002)
                if self.stop.is_set():
                    break
                self._learner = max(self._learner, clock.progress(DOOR))
                if broker.back.is_set():
                    broker.back.clear()
                    self._fetch_latest()
                self._take([m for _, m in drain_messages(policies, 32, self._reject)])
                self._play(min(self.cel.chunk, self.K * (generation + 1) - self.module.trial))
                # Checkpoint before anything of the stretch leaves: a change put on the bus is always in a
                # checkpoint, so a resumed robot never numbers a different change the same (the learner skips it).
                self._checkpoint()
                for c in self._unsent:
                    self._put_capabilities(c)
                self._unsent.clear()
                self._beat(control)
            if self.stop.is_set():
                log.info("%s stopping at trial %d", self.robot, self.module.trial)
            self._beat(control, done=self.module.trial >= self.total)
            life.linger()

    def _stop_asked(self, control: Ring) -> bool:
        for _, msg in drain_messages(control, 16, self._reject):
            if isinstance(msg, Control) and msg.command == "stop":
                self.stop.set()
        return self.stop.is_set()

    # ------------------------------------------------------------ rules in
    def _fetch_latest(self) -> None:
        """The store's latest policy (a robot that starts late, or was restarted)."""
        if self._session is None:
            return  # no session open yet: nothing to ask
        try:
            latest = fetch_latest(self._session, self.run_id, timeout=self.store_timeout, gate=self.gate).get(DOOR)
        except ServiceError as exc:
            log.info("%s", exc)
            return
        self._take([] if latest is None else [latest])

    def _take(self, msgs: list[Message]) -> None:
        """Use the newest policy among ``msgs`` if it is newer than the one in use; log it."""
        got = time.time()
        newest: PolicyUpdate | None = None
        for msg in msgs:
            if isinstance(msg, PolicyUpdate) and msg.version > self.module.version and \
                    (newest is None or msg.version > newest.version):
                newest = msg
        if newest is None:
            return
        rules: RuleSet = newest.ruleset()
        self.module.receive(rules)
        self.module.version = newest.version  # the learner's numbering: versions it skipped were never sent to us
        self._write("policies.jsonl", {"version": newest.version, "generation": newest.generation,
                                       "fitness": newest.fitness, "first_trial": self.module.trial,
                                       "sent_at": newest.sent_at, "received_at": got,
                                       "latency_ms": round(1000.0 * (got - newest.sent_at), 3),
                                       "rules": newest.rules})

    # ------------------------------------------------------------ trials
    def _event_start(self, trial: int) -> int | None:
        """The first trial of the schedule event in force during ``trial`` (None: before any)."""
        return max((t for t, _ in self.module.schedule.events if t <= trial), default=None)

    def _decisions_since(self, start: int, trial: int, first: int, per_trial: np.ndarray) -> int:
        """Decisions of trials ``start .. trial - 1``, given this stretch's (from ``first``) and ``event_decisions``
        (those of the event in force before the stretch, up to it)."""
        before = self.event_decisions if start < first else 0
        return before + int(per_trial[max(start, first) - first:trial - first].sum())

    def _play(self, n: int) -> None:
        ex = self.module
        first, version = ex.trial, ex.version
        st = ex.run(n)
        for c in st.changes:
            self._changed(c, st.trial_decisions, first)
        start = self._event_start(ex.trial - 1)
        if start is not None:
            self.event_decisions = self._decisions_since(start, ex.trial, first, st.trial_decisions)
        self.point.add(st, version, self._learner)
        if ex.trial % self.K == 0 or ex.trial >= self.total:
            generation = (ex.trial - 1) // self.K
            self._write("performance.jsonl", self.point.row(generation, ex, generation * self.K))
            self.point = _Point()

    def _changed(self, c: CapabilityChange, per_trial: np.ndarray, first: int) -> None:
        self.changes += 1
        self.last_change = c.trial
        world_failed = self.module.schedule.failed_at(c.trial, self.world.failed)
        truth = [s for s in SONARS if s not in world_failed]
        start = self._event_start(c.trial)
        row: dict[str, Any] = {"change": self.changes, "trial": c.trial, "decision": c.decision,
                               "generation": c.trial // self.K, "capabilities": list(c.capabilities),
                               "world_working": truth, "matches_world": list(c.capabilities) == truth,
                               "detected_at": time.time()}
        if start is not None:
            row.update(event_trial=start, delay_trials=c.trial - start + 1,
                       delay_decisions=self._decisions_since(start, c.trial, first, per_trial) + c.decision + 1)
        self._write("changes.jsonl", row)
        self._unsent.append(c)
        log.info("%s: monitor says %s at trial %d (change %d)", self.robot, ",".join(c.capabilities) or "none",
                 c.trial, self.changes)

    # ------------------------------------------------------------ out
    def _put_capabilities(self, c: CapabilityChange | None = None) -> None:
        trial, decision = (c.trial, c.decision) if c is not None else (self.last_change or 0, 0)
        msg = CapabilityUpdate(run=self.run_id, robot=self.robot, change=self.changes, trial=trial, decision=decision,
                               capabilities=list(self.module.capabilities if c is None else c.capabilities),
                               sent_at=time.time())
        self._pubs["caps"].put(self.gate.seal(msg, keys.capabilities(self.run_id, self.robot)))

    def _beat(self, control: Ring, *, done: bool = False) -> None:
        self._stop_asked(control)
        ex = self.module
        msg = ExecutionStatus(run=self.run_id, robot=self.robot, trial=ex.trial, trials=self.total,
                              generation=min(ex.trial // self.K, self.generations), performance=ex.performance,
                              rules_version=ex.version, capabilities=list(ex.capabilities), changes=self.changes,
                              last_change=self.last_change, rejected=self.rejected.as_dict(), done=done,
                              open=self.gate.open, sent_at=time.time())
        self._put_capabilities()  # again: a learner that missed the change, or started later, catches up
        self._pubs["status"].put(self.gate.seal(msg, keys.execution(self.run_id, self.robot)))

    def _done(self) -> dict[str, Any]:
        lat = [r["latency_ms"] for r in read_jsonl(self.paths.policies)]
        return {"trials": self.module.trial, "finished": self.module.trial >= self.total, "changes": self.changes,
                "performance": self.module.performance, "capabilities": list(self.module.capabilities),
                "rules_version": self.module.version, "rejected": self.rejected.as_dict(), "open": self.gate.open,
                "policies": len(lat), "latency_ms_median": statistics.median(lat) if lat else None}


def run_execution(settings: RunSettings, *, out: Path, conf: Config, resume: bool, run_key: RunKey | None = None) -> int:
    """``coevo execution``: run the robot to its last trial (exit 0), or until SIGINT/SIGTERM (130)."""
    ex = Execution(settings, out_dir=out, conf=conf, resume=resume, run_key=run_key)
    done = main_of(ex.run)
    if done is None:
        return 130
    print(f"{ex.robot}: {done['trials']} trials, external performance {done['performance']:.0f} %, "
          f"{done['changes']} capability changes")
    return 0
