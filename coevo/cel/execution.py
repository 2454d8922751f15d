"""The execution module (report Appendix B §5, §7): the robot in the "real" world, with its monitor.

It owns a world of its own, a :class:`~coevo.tasks.door.DoorConfig` in which sonars
fail when a :class:`FailureSchedule` says so, unknown to the learner.  It plays one
trial after another with the newest rules it has received (:meth:`ExecutionModule.receive`),
feeds each decision's sonar readings and motion to its :class:`~coevo.cel.monitor.Monitor`,
and keeps the external performance: successes out of the last ``window`` (100) trials
(report §8.1).

Trials run one after another; :meth:`ExecutionModule.run` plays a stretch of them
with the same rules and the same failures as one batch (the door world is batched),
split wherever the schedule changes, and hands the monitor each trial's decisions
in order.  Nothing in a stretch depends on the monitor's verdict (a capability
change goes to the learner, whose rules arrive between stretches), so this is the
same as stepping one trial at a time.  Deterministic given the seed and the
sequence of calls.
"""

from __future__ import annotations

import json
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coevo.cel.monitor import Monitor
from coevo.config import build
from coevo.errors import ConfigError
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.tasks.door.evaluate import outcome_rates
from coevo.tasks.door.sensors import DOOR, action_values, sense
from coevo.tasks.door.settings import DoorConfig
from coevo.tasks.door.world import GOAL, DoorWorld, draw_trials

__all__ = ["FailureSchedule", "CapabilityChange", "Stretch", "ExecutionModule", "EXTERNAL_WINDOW"]

EXTERNAL_WINDOW = 100  # report §8.1: "the number of times out of 100 that the robot succeeded"


@dataclass(frozen=True)
class FailureSchedule:
    """Which sonars are failed from which trial on: ``events`` are (first trial, failed sonars), the
    failed set replacing the previous one (``()`` is a repair of them all).  Before the first event,
    the world's own ``failed``."""

    events: tuple[tuple[int, tuple[str, ...]], ...] = ()

    def __post_init__(self) -> None:
        events = []
        for trial, failed in self.events:
            if int(trial) < 0:
                raise ConfigError(f"a failure schedule's trial must be >= 0, got {trial}")
            events.append((int(trial), build(DoorConfig, {"failed": failed}).failed))  # names checked, put in order
        starts = [t for t, _ in events]
        if starts != sorted(set(starts)):
            raise ConfigError(f"a failure schedule's trials must increase, got {starts}")
        object.__setattr__(self, "events", tuple(events))

    @classmethod
    def at_generations(cls, events: Iterable[tuple[int, Sequence[str] | str]], trials_per_generation: int
                       ) -> FailureSchedule:
        """A lockstep schedule (:mod:`coevo.cel.experiment`): (generation g, failed) means from trial
        ``g * trials_per_generation`` on, the first of the trials played with generation g's rules."""
        if trials_per_generation < 1:
            raise ConfigError(f"trials_per_generation must be at least 1, got {trials_per_generation}")
        return cls(tuple((g * trials_per_generation, f) for g, f in events))  # type: ignore[misc]

    def failed_at(self, trial: int, base: tuple[str, ...] = ()) -> tuple[str, ...]:
        """The failed sonars during ``trial``."""
        failed = base
        for start, f in self.events:
            if start > trial:
                break
            failed = f
        return failed

    def next_change(self, trial: int) -> int | None:
        """The first trial after ``trial`` whose failures differ from ``trial``'s, or None."""
        return next((start for start, _ in self.events if start > trial), None)


@dataclass(frozen=True)
class CapabilityChange:
    """The monitor's verdict: from the ``decision``-th decision (0-based) of trial ``trial`` on, the robot's
    working sonars are ``capabilities``."""

    trial: int
    decision: int
    capabilities: tuple[str, ...]


@dataclass
class Stretch:
    """What a :meth:`ExecutionModule.run` call did: trials ``first .. first + n - 1``, their outcomes and
    decisions, the monitor's changes, and the external performance after it."""

    first: int
    outcome: np.ndarray
    time: np.ndarray
    decisions: int
    not_forward: int  # decisions with speed <= 0 (the report's "refusing to move forward")
    trial_decisions: np.ndarray  # decisions of each trial
    changes: list[CapabilityChange] = field(default_factory=list)
    performance: float = 0.0

    def rates(self) -> dict[str, float]:
        """% success, collision and timeout of these trials, and % of decisions not moving forward."""
        return {**outcome_rates(self.outcome), "not_forward": 100.0 * self.not_forward / max(self.decisions, 1)}


class ExecutionModule:
    """The robot in its world; see the module docstring."""

    def __init__(self, world: DoorConfig, rules: RuleSet, *, seed: int, schedule: FailureSchedule | None = None,
                 monitor: Monitor | None = None, window: int = EXTERNAL_WINDOW) -> None:
        if window < 1:
            raise ConfigError(f"window must be at least 1 trial, got {window}")
        self.world = world
        self.schedule = schedule or FailureSchedule()
        self.monitor = monitor or Monitor()
        self.rng = np.random.default_rng(seed)
        self.trial = 0  # trials played so far
        self.version = 0  # how many rule sets were received
        self._recent: deque[bool] = deque(maxlen=window)
        self._set(rules)

    def _set(self, rules: RuleSet) -> None:
        if rules.behaviour != DOOR:
            raise ConfigError(f"the execution module runs door rules, got a {rules.behaviour} rule set")
        self.rules = rules
        self._compiled = CompiledPolicies([rules])

    def receive(self, rules: RuleSet) -> None:
        """The learner's newest rules: used from the next trial on."""
        self._set(rules)
        self.version += 1

    @property
    def performance(self) -> float:
        """External performance: % of the last ``window`` trials (fewer at the start) that reached the goal."""
        return 100.0 * sum(self._recent) / len(self._recent) if self._recent else 0.0

    @property
    def capabilities(self) -> tuple[str, ...]:
        """The monitor's capability list (what the learner is told), not the world's truth."""
        return self.monitor.capabilities

    def failed_now(self) -> tuple[str, ...]:
        """The world's failed sonars for the next trial (the experiment's truth; the monitor never reads it)."""
        return self.schedule.failed_at(self.trial, self.world.failed)

    def state_dict(self) -> dict[str, Any]:
        """Everything the next trials depend on besides the settings (world, schedule, window), as plain
        data: a module built with the same settings and :meth:`load_state` plays on exactly as this one."""
        return {"rules": self.rules.to_dict(), "version": self.version, "trial": self.trial,
                "rng": json.dumps(self.rng.bit_generator.state), "recent": [bool(x) for x in self._recent],
                "monitor": self.monitor.state_dict()}

    def load_state(self, state: dict[str, Any]) -> None:
        try:
            rules = RuleSet.from_dict(state["rules"])
            version, trial, recent = int(state["version"]), int(state["trial"]), [bool(x) for x in state["recent"]]
            self.rng.bit_generator.state = json.loads(state["rng"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"not an execution module state: {exc!r}") from exc
        self._set(rules)
        self.version, self.trial = version, trial
        self._recent.clear()
        self._recent.extend(recent)
        self.monitor.load_state(state["monitor"])

    def run(self, trials: int) -> Stretch:
        """Play the next ``trials`` trials with the current rules."""
        if trials < 1:
            raise ConfigError(f"trials must be at least 1, got {trials}")
        first, end = self.trial, self.trial + trials
        parts: list[Stretch] = []
        while self.trial < end:
            nxt = self.schedule.next_change(self.trial)
            stop = end if nxt is None else min(end, nxt)
            parts.append(self._play(stop - self.trial))
        out = Stretch(first, np.concatenate([p.outcome for p in parts]), np.concatenate([p.time for p in parts]),
                      sum(p.decisions for p in parts), sum(p.not_forward for p in parts),
                      np.concatenate([p.trial_decisions for p in parts]), [c for p in parts for c in p.changes])
        out.performance = self.performance
        return out

    def _play(self, n: int) -> Stretch:
        """``n`` trials under one failure setting, batched; the monitor sees them in trial order."""
        cfg = self.world.model_copy(update={"failed": self.failed_now()})
        world = DoorWorld(cfg, draw_trials(cfg, n, self.rng), rng=self.rng)
        lanes = np.arange(n)
        log_r, log_f, log_l = [], [], []
        while lanes.size:
            reading = world.sonars(lanes)
            bins = sense(world, lanes, reading)
            rank, _ = self._compiled.decide(np.zeros(len(lanes), dtype=np.int64), bins, rng=self.rng)
            speed, turn = action_values(self._compiled.action_values(np.zeros(len(lanes), dtype=np.int64), rank))
            log_r.append(reading)
            log_f.append(speed > 0)
            log_l.append(lanes)
            world.act(lanes, speed, turn)
            lanes = lanes[world.outcome[lanes] == 0]
        reading, forward, lane = np.concatenate(log_r), np.concatenate(log_f), np.concatenate(log_l)
        order = np.argsort(lane, kind="stable")  # trial by trial, each in time order
        reading, forward, lane = reading[order], forward[order], lane[order]
        starts = np.searchsorted(lane, np.arange(n))
        changes = [CapabilityChange(self.trial + int(lane[i]), int(i - starts[lane[i]]), caps)
                   for i, caps in self.monitor.observe_decisions(reading, forward)]
        self._recent.extend(bool(o == GOAL) for o in world.outcome)
        self.trial += n
        return Stretch(self.trial - n, world.outcome.copy(), world.time.copy(), len(forward), int((~forward).sum()),
                       np.bincount(lane, minlength=n), changes)


