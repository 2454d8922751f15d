"""The monitor (report Appendix B §5.1): it marks a sonar defective from the robot's own readings.

"If the robot is moving forward, and the value of the sonar reads zero repeatedly,
that particular sonar is marked as being defective."  The monitor sees only what
the robot senses and does: each decision's seven sonar readings (inches) and
whether the robot moved forward.  It never sees the world's failure settings; it
identifies symptoms, not causes.

Per sonar it counts readings at or below ``zero`` (the sonar's minimum, 0 in):

* a working sonar that reads zero on ``zero_run`` decisions in a row **while the
  robot moves forward** is marked defective *(ours: the number; chosen by
  measurement in docs/cel.md)*.  A non-zero reading resets the count; a decision
  not moving forward leaves it as it is (a robot standing still next to a wall may
  read near zero without anything being wrong, and says nothing either way);
* a defective sonar that reads non-zero on ``repair_run`` decisions in a row is
  working again *(ours: repair detection, which the report does not describe; a
  failed sonar reads a constant minimum, so any reading above it is a sign of life,
  and a short run guards against a single glitch)*.

The counts run on across trials: the readings are one stream from one robot.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from coevo.errors import ConfigError
from coevo.tasks.door.settings import SONARS, sonar_names

__all__ = ["Monitor", "ZERO_RUN", "REPAIR_RUN", "check_capabilities"]

#: (ours) forward decisions in a row with a zero reading before a sonar is marked defective; see docs/cel.md.
ZERO_RUN = 8
#: (ours) non-zero readings in a row before a defective sonar counts as working again.
REPAIR_RUN = 3


def check_capabilities(capabilities: Sequence[str]) -> tuple[str, ...]:
    """A capability list (the working sonars) in canonical left-to-right order; unknown names are refused."""
    try:
        return sonar_names(capabilities)
    except ValueError as exc:
        raise ConfigError(f"{exc} in the capability list") from None


class Monitor:
    """Watches a robot's sonar readings and motion; see the module docstring."""

    def __init__(self, *, zero_run: int = ZERO_RUN, repair_run: int = REPAIR_RUN, zero: float = 0.0,
                 capabilities: Sequence[str] = SONARS) -> None:
        if int(zero_run) < 1 or int(repair_run) < 1:
            raise ConfigError(f"zero_run and repair_run must be at least 1, got {zero_run} and {repair_run}")
        if not zero >= 0.0:
            raise ConfigError(f"zero must be a reading >= 0 inches, got {zero}")
        self.zero_run, self.repair_run, self.zero = int(zero_run), int(repair_run), float(zero)
        working = check_capabilities(capabilities)
        self.working = np.array([s in working for s in SONARS])
        self._zeros = np.zeros(len(SONARS), dtype=np.int64)  # zero readings in a row while moving forward
        self._alive = np.zeros(len(SONARS), dtype=np.int64)  # non-zero readings in a row of a defective sonar
        self.decisions = 0  # decisions observed so far

    @property
    def capabilities(self) -> tuple[str, ...]:
        """The capability list: the sonars the monitor believes work, left to right."""
        return tuple(s for s, w in zip(SONARS, self.working) if w)

    def state_dict(self) -> dict[str, Any]:
        """The counts and the verdicts, as plain data (a checkpoint); :meth:`load_state` restores them."""
        return {"working": self.working.tolist(), "zeros": self._zeros.tolist(), "alive": self._alive.tolist(),
                "decisions": self.decisions}

    def load_state(self, state: dict[str, Any]) -> None:
        try:
            working, zeros, alive = (np.asarray(state[k]) for k in ("working", "zeros", "alive"))
            decisions = int(state["decisions"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"not a monitor state: {exc!r}") from exc
        if not working.shape == zeros.shape == alive.shape == (len(SONARS),):
            raise ConfigError(f"a monitor state has {len(SONARS)} values per count, got {working.shape}")
        self.working, self._zeros, self._alive = working.astype(bool), zeros.astype(np.int64), alive.astype(np.int64)
        self.decisions = decisions

    def observe(self, readings: np.ndarray, forward: bool) -> tuple[str, ...] | None:
        """One decision: the seven readings (inches, far-left to far-right) and whether the robot moved
        forward.  Returns the new capability list when it changed with this decision, else None."""
        r = np.asarray(readings, dtype=np.float64)
        if r.shape != (len(SONARS),):
            raise ConfigError(f"a decision has {len(SONARS)} sonar readings, got shape {r.shape}")
        self.decisions += 1
        zero = r <= self.zero
        if forward:
            self._zeros = np.where(zero, self._zeros + 1, 0)
        else:
            self._zeros[~zero] = 0
        self._alive = np.where(zero, 0, self._alive + 1)
        failed = self.working & (self._zeros >= self.zero_run)
        repaired = ~self.working & (self._alive >= self.repair_run)
        if not (failed.any() or repaired.any()):
            return None
        self.working = (self.working & ~failed) | repaired
        self._zeros[repaired] = 0
        return self.capabilities

    def observe_decisions(self, readings: np.ndarray, forward: np.ndarray) -> list[tuple[int, tuple[str, ...]]]:
        """Decisions in time order, ``(m, 7)`` readings and ``(m,)`` forward flags; returns every change as
        (index of the decision, the new capability list)."""
        readings = np.asarray(readings, dtype=np.float64)
        forward = np.asarray(forward, dtype=bool)
        if readings.ndim != 2 or len(readings) != len(forward):
            raise ConfigError(f"readings {readings.shape} and forward {forward.shape} must be (m, 7) and (m,)")
        if readings.shape[1:] != (len(SONARS),):
            raise ConfigError(f"a decision has {len(SONARS)} sonar readings, got shape {readings.shape[1:]}")
        if self._quiet(readings, forward):
            return []
        changes = []
        for i in range(len(readings)):
            new = self.observe(readings[i], bool(forward[i]))
            if new is not None:
                changes.append((i, new))
        return changes

    def _quiet(self, readings: np.ndarray, forward: np.ndarray) -> bool:
        """The common case at once: no working sonar reads zero and no defective one reads anything else,
        so nothing can change; update the counts as the decisions one by one would.  False (nothing
        done) otherwise."""
        zero = readings <= self.zero
        none, every = ~zero.any(axis=0), zero.all(axis=0)
        if not (np.where(self.working, none, every).all()):
            return False
        m = len(readings)
        self.decisions += m
        self._zeros = np.where(none, 0, self._zeros + int(forward.sum()))
        self._alive = np.where(none, self._alive + m, 0)
        return True
