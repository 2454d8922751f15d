"""What a receiver of one run accepts: its key, its roster and the version rules (a :class:`Gate`).

* **Key**: with the run's :class:`~coevo.bus.auth.RunKey` every message must carry a
  valid authenticator for the key it arrived on (``unauthenticated`` otherwise);
  without one the gate is *open* and says so.
* **Roster** (behaviour -> worker id, from the run's settings): a policy, case or
  status of a behaviour from any other worker id is ``not_roster``; so is a capability
  list or execution status from a robot other than the run's ``robot`` (a CEL run).
* **Versions**: a worker publishes at most one version per generation, numbered
  1, 2, ..., so a policy's version never exceeds its generation, its generation never
  exceeds the run's generations (when the gate knows them), and a ``current`` policy's
  version is its generation; anything else is ``bad_version``.  (The receiver adds the
  sequence rule against the version it holds, see :class:`~coevo.agents.inbox.Inbox`.)

* **Freshness** (:mod:`coevo.bus.freshness`, with a key only): a genuine message taken
  before is ``replayed``; one of an earlier incarnation of the run (``epoch``: run.json's
  ``incarnation``), of an older incarnation of its sender, or sealed too long ago is
  ``stale``.  Each ring keeps its own memory (:class:`~coevo.bus.session.Ring`); the
  gate's own serves everything else (the broker, queries).

The gate rides on the session (:func:`coevo.bus.session.open_session`), so every ring
subscriber of that session — partner policies, control, the pacer's status rings, the
status board — decodes through it, and rejections with no other home go to its
``reject``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from coevo.bus import keys
from coevo.bus.auth import RunKey
from coevo.bus.freshness import Freshness, Seen
from coevo.bus.messages import (
    CapabilityUpdate,
    CaseUpdate,
    ExecutionStatus,
    Message,
    PolicyUpdate,
    Status,
    decode_fresh,
    encode,
    unseal_fresh,
)
from coevo.errors import MessageError

__all__ = ["Gate", "OPEN"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Gate:
    """A run's acceptance rules; ``Gate()`` accepts any well-formed message (an open run, no roster)."""

    key: RunKey | None = None
    roster: Mapping[str, str] | None = None
    generations: int | None = None
    reject: Callable[[MessageError, str], None] | None = None
    robot: str | None = None  # a CEL run's execution module (None: any robot id)
    epoch: int = 0  # the run's incarnation (run.json's): older messages are stale
    fresh: Freshness = field(default=None, compare=False, repr=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.fresh is None:
            object.__setattr__(self, "fresh", Freshness(self.epoch))

    @property
    def open(self) -> bool:
        return self.key is None

    @property
    def secret(self) -> bytes | None:
        return None if self.key is None else self.key.secret

    def seal(self, msg: Message, key_expr: str) -> bytes:
        """``msg`` encoded for ``key_expr`` (in an authenticated envelope, fresh, when the run has a key).
        Seal when putting: a sealed payload put twice is a replay to its receivers."""
        if self.key is None:
            return encode(msg)
        return encode(msg, key=key_expr, secret=self.key.secret, fresh=self.fresh.seal_header())

    def seal_bytes(self, body: bytes, key_expr: str) -> bytes:
        """Raw bytes (a store's versions reply) sealed like a message; unchanged in an open run."""
        from coevo.bus.auth import seal

        return body if self.key is None else seal(body, key_expr, self.key.secret, self.fresh.seal_header())

    def unseal(self, payload: bytes, key_expr: str, seen: Seen | None = None) -> bytes:
        body, fresh = unseal_fresh(payload, key=key_expr, secret=self.secret)
        if self.key is not None and fresh is not None:
            self.fresh.admit(key_expr, fresh, seen)
        return body

    def decode(self, key_expr: str, payload: bytes, seen: Seen | None = None) -> Message:
        """Bytes that arrived on ``key_expr`` -> a message this run accepts, or a MessageError.  ``seen``: the
        receiver's memory of what it took (default: the gate's)."""
        msg, fresh = decode_fresh(payload, key=key_expr, secret=self.secret)
        self.check(msg, key_expr)
        if self.key is not None and fresh is not None:  # with a key, decode_fresh refuses an envelope without
            self.fresh.admit(key_expr, fresh, seen)
        return msg

    def check(self, msg: Message, key_expr: str) -> None:
        beh, worker = getattr(msg, "behaviour", ""), getattr(msg, "worker", None)
        if self.robot is not None and isinstance(msg, (CapabilityUpdate, ExecutionStatus)) and msg.robot != self.robot:
            raise MessageError("not_roster", f"{msg.kind} of robot {msg.robot!r}; the run's robot is {self.robot!r}")
        if self.roster is not None and isinstance(msg, (PolicyUpdate, Status, CaseUpdate)):
            if self.roster.get(beh) != worker:
                raise MessageError("not_roster", f"{msg.kind} of {beh} from worker {worker!r}; the roster's publisher is "
                                                 f"{self.roster.get(beh)!r}")
        if isinstance(msg, PolicyUpdate):
            current = keys.parse(key_expr).get("topic") == "current"
            if current and msg.version != msg.generation:
                raise MessageError("bad_version", f"current policy v{msg.version} at generation {msg.generation}")
            if msg.version > msg.generation:
                raise MessageError("bad_version", f"v{msg.version} at generation {msg.generation}: at most one version "
                                                  "per generation")
            if self.generations is not None and msg.generation > self.generations:
                raise MessageError("bad_version", f"generation {msg.generation} in a run of {self.generations}")


OPEN = Gate()
