"""The exceptions coevo raises, one tree rooted at :class:`CoevoError`.

Branches are chosen by how a caller reacts::

    CoevoError                  anything coevo raises on purpose
    ├── ConfigError             bad parameters or settings: fix the input and retry
    ├── RuleSetError            a rule set that is malformed (bad interval, unknown sensor, ...)
    │   └── RuleParseError      rule-set text that does not parse (carries the line number)
    ├── RunDirError             a run directory that is missing, foreign or incomplete
    ├── ServiceError            the bus or a service on it is unreachable, refused us, or did not answer in time
    │                           (a router that cannot be reached, a store query that failed, a wait that timed out)
    └── MessageError            a bus message rejected on receipt (logged and counted, never fatal)

Errors of the libraries underneath are translated at the boundary, with ``raise ... from``:
zenoh's in :mod:`coevo.bus.session` (and nowhere else: it names the one zenoh error others log and pass,
``SessionGone``, a session closing under a declaration or a put), files' in :mod:`coevo.rundir.layout`.

Every message names the bad value and, where there is one, the fix.
"""

from __future__ import annotations

__all__ = [
    "CoevoError",
    "ConfigError",
    "RuleSetError",
    "RuleParseError",
    "RunDirError",
    "ServiceError",
    "MessageError",
]


class CoevoError(Exception):
    """Base of every error coevo raises deliberately."""


class ConfigError(CoevoError):
    """A parameter or setting is invalid."""


class RuleSetError(CoevoError):
    """A rule set is malformed."""


class RuleParseError(RuleSetError):
    """Rule-set text does not parse."""

    def __init__(self, message: str, *, line: int | None = None) -> None:
        self.line = line
        super().__init__(f"line {line}: {message}" if line is not None else message)


class RunDirError(CoevoError):
    """A run directory is missing, belongs to another run, or is incomplete."""


class ServiceError(CoevoError):
    """The bus or a service on it cannot be reached, refused this process, or did not answer in time."""


class MessageError(CoevoError):
    """A message from the bus was rejected; ``reason`` is a short counter key."""

    def __init__(self, reason: str, detail: str) -> None:
        self.reason = reason
        self.detail = detail
        super().__init__(f"{reason}: {detail}")
