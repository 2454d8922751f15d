"""Bus messages: frozen pydantic models carried as msgpack maps with a schema version.

Every message is a msgpack map with ``kind`` and ``schema_version`` first-class
fields.  :func:`encode` and :func:`decode` are the only way in and out; a bad
payload becomes a :class:`MessageError` whose ``reason`` (a counter name, see
:data:`REASONS`) says what was wrong — never a crash.  In a run with a key the
message travels in an envelope with its authenticator (:mod:`coevo.bus.auth`):
``encode(..., key=..., secret=...)`` seals it, and ``decode`` given the secret
checks the envelope before it parses anything inside.
"""

from __future__ import annotations

import hmac
import math
from typing import Annotated, Any, Final, Literal, Union, cast

import msgpack
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    TypeAdapter,
    ValidationError,
)

from coevo.bus import auth, keys
from coevo.errors import MessageError, RuleSetError
from coevo.policy.rules import RuleSet
import coevo.tasks  # noqa: F401 - the tasks' registry: a behaviour named on a key has its task found and loaded
from coevo.policy.schema import known

__all__ = ["SCHEMA_VERSION", "MAX_BYTES", "REASONS", "PolicyUpdate", "Status", "BrokerStatus", "Control", "CaseUpdate",
           "CapabilityUpdate", "ExecutionStatus", "Message", "encode", "decode", "decode_fresh", "unseal", "unseal_fresh"]

SCHEMA_VERSION: Final = 1
MAX_BYTES = 1 << 20  # a 64-rule policy is ~5 KB; anything near a megabyte is not ours

#: Why a message is rejected: the keys of every ``rejected`` counter (status, broker stats, logs).
REASONS = {
    "oversize": f"payload over {MAX_BYTES} bytes (not even decoded)",
    "not_msgpack": "bytes that are not msgpack",
    "truncated": "msgpack cut short",
    "invalid": "msgpack, but not a message: wrong or missing fields, wrong types",
    "non_finite": "a NaN or infinite fitness",
    "bad_rules": "a rule set that cannot be (impossible intervals, unknown actions, wrong shapes)",
    "schema_version": f"a schema version other than {SCHEMA_VERSION}, or in a run with a key an envelope of format 1 "
                      "(no freshness: sent by an older coevo)",
    "wrong_run": "a message naming another run than its key",
    "wrong_behaviour": "a message naming another behaviour (or worker) than its key",
    "wrong_key": "a message of a kind that does not belong on its key",
    "flood": "dropped unread: more arrived than a receiver keeps between two reads",
    "unauthenticated": "in a run with a key: no envelope, a wrong authenticator (forged, altered, or replayed onto "
                       "another key), or a run the broker holds no key for",
    "not_roster": "a policy, case or status from a worker id that is not the behaviour's publisher in the run's roster, "
                  "or a capability list or execution status from a robot id that is not the run's robot",
    "bad_version": "a policy version its publisher cannot have reached: above its generation, past the run's "
                   "generations, or more versions than generations since the one held",
    "quota": "the broker's store is full for that run (policies, bytes) or for new runs",
    "replayed": "in a run with a key: a genuine message this receiver has already taken (its sender's sequence "
                "number on that key seen before): captured and put again",
    "stale": "in a run with a key: a genuine message of an earlier incarnation of the run (before a resume), of an "
             "older incarnation of its sender, or sealed more than 10 minutes ago",
}


def _known_behaviour(name: str) -> str:
    if not known(name):
        raise ValueError(f"unknown behaviour {name!r}")
    return name


def _plain_id(value: str) -> str:
    if not keys.valid_id(value):  # the pattern lets "." and ".." through: not a directory name
        raise ValueError(f"{value!r} is not a plain name")
    return value


_Id = Annotated[str, Field(pattern=r"^[A-Za-z0-9_.-]{1,64}$"), AfterValidator(_plain_id)]
#: A learning behaviour's name, of any task (messages name no task: behaviour names are unique).
BehaviourName = Annotated[str, Field(pattern=r"^[a-z0-9_]{1,32}$"), AfterValidator(_known_behaviour)]


class _Msg(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    schema_version: Literal[1] = SCHEMA_VERSION
    run: _Id
    sent_at: float = Field(ge=0)


def _rules_ok(v: dict[str, Any]) -> dict[str, Any]:
    try:
        RuleSet.from_dict(v)
    except RuleSetError as exc:
        raise ValueError(f"bad rule set: {exc}") from None
    return v


def _finite_number(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError(f"fitness must be finite, got {v}")
    return v


def _distinct(v: list[str]) -> list[str]:
    if len(set(v)) != len(v):
        raise ValueError(f"a sensor named twice in {v}")
    return v


Fitness = Annotated[float, AfterValidator(_finite_number)]
Rules = Annotated[dict[str, Any], AfterValidator(_rules_ok)]


class PolicyUpdate(_Msg):
    """A worker's new best-so-far policy."""

    kind: Literal["policy"] = "policy"
    behaviour: BehaviourName
    worker: _Id
    version: int = Field(ge=1)
    generation: int = Field(ge=0)
    fitness: Fitness
    episodes: int = Field(ge=0)
    rules: Rules

    def ruleset(self) -> RuleSet:
        rs = RuleSet.from_dict(self.rules)
        if rs.behaviour != self.behaviour:
            raise RuleSetError(f"policy for {self.behaviour} carries {rs.behaviour} rules")
        return rs


class Status(_Msg):
    """A worker's heartbeat, once per generation."""

    kind: Literal["status"] = "status"
    behaviour: BehaviourName
    worker: _Id
    regime: _Id
    generation: int = Field(ge=0)
    generations: int = Field(ge=0)
    best_fitness: float
    partner_versions: dict[str, int] = Field(default_factory=dict)
    rejected: dict[str, int] = Field(default_factory=dict)
    buffered: int = Field(default=0, ge=0)  # published versions the broker's store has not confirmed yet
    done: bool = False
    # its last heartbeat: it was asked to stop (a Ctrl-C, SIGTERM or the run's stop) and stops in order short of its
    # last generation, so its token's going is a stop, not a death (what a board that was not told the run stops
    # reads: `coevo status` in another terminal)
    stopped: bool = False
    open: bool = False  # the worker runs without a key: it accepts unauthenticated messages
    # The latest generation's best on the behaviour's own measures, in % (its task's status_measures; the
    # fuel task's: Tracking quality_tracking, Docking docking_from_random, the Executive dock_choice and
    # docking_success_rate).
    measures: dict[str, Annotated[float, Field(ge=0, le=100)]] = Field(default_factory=dict, max_length=8)


class BrokerStatus(_Msg):
    """The broker's account of one run, every few seconds: what it stored and what it rejected."""

    kind: Literal["broker"] = "broker"
    open: bool = False  # the broker holds no key for this run and stores it unauthenticated (coevo broker --open)
    stored: dict[str, int] = Field(default_factory=dict)  # behaviour -> policies held
    rejected: dict[str, int] = Field(default_factory=dict)  # reason -> count, for messages on this run's keys
    dropped: int = Field(default=0, ge=0)  # of those, dropped unread because the broker's inbox was full
    degraded: str = Field(default="", max_length=500)  # why the store cannot write ("" while it can)


#: A capability list: the names of the sensors that work (which names exist is the task's to check).
Capabilities = Annotated[list[Annotated[str, Field(pattern=r"^[a-z0-9_]{1,32}$")]], Field(max_length=64),
                         AfterValidator(_distinct)]


class CaseUpdate(_Msg):
    """A CEL learner's strategy for the case base (report Appendix B §6): the best rules it found under a
    capability list, stored by the broker so that a restarted learner, or a later run, finds them."""

    kind: Literal["case"] = "case"
    behaviour: BehaviourName
    worker: _Id
    version: int = Field(ge=1)  # the worker's n-th case
    generation: int = Field(ge=0)  # the learner's generations when it stored the case
    origin: _Id | None = None  # the run it was learned in, when not this one (coevo cel --cases-from)
    fitness: Fitness
    capabilities: Capabilities
    rules: Rules

    def ruleset(self) -> RuleSet:
        return PolicyUpdate.ruleset(self)  # type: ignore[arg-type]


class CapabilityUpdate(_Msg):
    """An execution module's monitor: the robot's working sensors (report Appendix B §5).  ``change`` counts
    the monitor's verdicts (0: the list it started with); the newest wins.  Sent on each change and again
    with every heartbeat, so a learner that missed one, or started later, catches up."""

    kind: Literal["capabilities"] = "capabilities"
    robot: _Id
    change: int = Field(ge=0)
    trial: int = Field(ge=0)  # the trial during which the monitor decided (0 for the initial list)
    decision: int = Field(ge=0)  # its decision within that trial
    capabilities: Capabilities


class ExecutionStatus(_Msg):
    """An execution module's heartbeat: where the robot is and how well it does (report §8.1's external
    performance: successes out of its last ``window`` trials, in %)."""

    kind: Literal["execution"] = "execution"
    robot: _Id
    trial: int = Field(ge=0)  # trials played
    trials: int = Field(ge=0)  # trials the run plays in all
    generation: int = Field(ge=0)  # the learner generation whose trials the robot is playing (its clock)
    performance: float = Field(ge=0, le=100)
    rules_version: int = Field(ge=0)  # the learner's policy version in use (0: the initial rules)
    capabilities: Capabilities
    changes: int = Field(ge=0)  # capability changes the monitor reported
    last_change: int | None = Field(default=None, ge=0)  # the trial of the last one
    rejected: dict[str, int] = Field(default_factory=dict)
    done: bool = False
    open: bool = False


class Control(_Msg):
    """A command to every process of a run."""

    kind: Literal["control"] = "control"
    command: Literal["stop"]


Message = Annotated[Union[PolicyUpdate, Status, BrokerStatus, Control, CaseUpdate, CapabilityUpdate, ExecutionStatus],
                    Field(discriminator="kind")]
_ADAPTER: TypeAdapter[Any] = TypeAdapter(Message)


AnyMessage = Union[PolicyUpdate, Status, BrokerStatus, Control, CaseUpdate, CapabilityUpdate, ExecutionStatus]


def encode(msg: AnyMessage, *, key: str | None = None,
           secret: bytes | None = None, fresh: bytes | None = None) -> bytes:
    """Message -> bytes; with ``secret``, sealed in an envelope authenticated for the key expression ``key``
    with the freshness header ``fresh`` (default: this process's next, run incarnation 0)."""
    body: bytes = msgpack.packb(msg.model_dump(mode="json"), use_bin_type=True)
    if secret is None:
        return body
    if key is None:
        raise TypeError("sealing needs the key expression the message is put on")
    return auth.seal(body, key, secret, fresh)


def _unpack(payload: bytes) -> Any:
    try:
        return msgpack.unpackb(payload, raw=False, strict_map_key=True)
    except (msgpack.UnpackException, ValueError, TypeError, OverflowError, RecursionError) as exc:
        # msgpack's own errors, and ValueError/TypeError for bad UTF-8, unhashable or non-string map keys
        reason = "truncated" if "incomplete" in str(exc) else "not_msgpack"
        raise MessageError(reason, f"{type(exc).__name__}: {exc}") from None


def _envelope(data: Any, key: str | None, secret: bytes | None) -> tuple[bytes, bytes | None] | None:
    """(the message bytes, the freshness header) inside an envelope (checked when ``secret`` is given); None if
    ``data`` is no envelope.  Format 1 (no freshness) is opened only without a secret (an open run)."""
    if not (isinstance(data, dict) and "mac" in data):
        if secret is not None:
            raise MessageError("unauthenticated", f"no authenticator on {key!r} (this run's messages are sealed)")
        return None
    tag, body, fresh = data.get("mac"), data.get("msg"), data.get("fresh")
    v1 = set(data) == {"mac", "msg"}
    if v1 and secret is not None:
        raise MessageError("schema_version", f"an envelope of format 1 on {key!r} (no freshness: an older coevo); "
                                             f"this coevo speaks format {auth.ENVELOPE}: run the same coevo everywhere")
    if not v1 and (set(data) != {"v", "fresh", "mac", "msg"} or data.get("v") != auth.ENVELOPE
                   or not isinstance(fresh, bytes)):
        raise MessageError("unauthenticated" if secret is not None else "invalid",
                           f"a malformed envelope (format {data.get('v')!r}; this coevo speaks {auth.ENVELOPE})")
    if not isinstance(tag, bytes) or not isinstance(body, bytes):
        raise MessageError("unauthenticated" if secret is not None else "invalid", "a malformed envelope")
    if secret is not None:
        if key is None:
            raise TypeError("checking an authenticator needs the key expression the message arrived on")
        if not hmac.compare_digest(tag, auth.mac2(secret, key, cast(bytes, fresh), body)):  # format 2: bytes
            raise MessageError("unauthenticated", f"wrong authenticator for {key!r} (forged, altered or moved "
                                                  "onto another key)")
    return body, (None if v1 else fresh)


def unseal_fresh(payload: bytes, *, key: str, secret: bytes | None) -> tuple[bytes, bytes | None]:
    """(the bytes inside an envelope for ``key``, its freshness header); any payload that is not one, when
    ``secret`` is None, with no header."""
    if len(payload) > MAX_BYTES:
        raise MessageError("oversize", f"{len(payload)} bytes > {MAX_BYTES}")
    opened = _envelope(_unpack(payload), key, secret)
    return (payload, None) if opened is None else opened


def unseal(payload: bytes, *, key: str, secret: bytes | None) -> bytes:
    """The bytes inside an envelope for ``key`` (any payload that is not one, when ``secret`` is None)."""
    return unseal_fresh(payload, key=key, secret=secret)[0]


def decode(payload: bytes, *, key: str | None = None,
           secret: bytes | None = None) -> AnyMessage:
    """Bytes -> message, checking it against the key it arrived on (if given).

    With ``secret`` (a run with a key) the payload must be an envelope whose authenticator
    matches ``key``; without, an envelope is opened unverified (an open run).  Freshness
    (replays) is the receiver's :class:`~coevo.bus.trust.Gate`'s to check (:func:`decode_fresh`).
    """
    return decode_fresh(payload, key=key, secret=secret)[0]


def decode_fresh(payload: bytes, *, key: str | None = None,
                 secret: bytes | None = None) -> tuple[AnyMessage, bytes | None]:
    """Like :func:`decode`: (the message, its envelope's freshness header, None without one)."""
    if len(payload) > MAX_BYTES:
        raise MessageError("oversize", f"{len(payload)} bytes > {MAX_BYTES}")
    data = _unpack(payload)
    opened = _envelope(data, key, secret)
    fresh = None
    if opened is not None:
        body, fresh = opened
        data = _unpack(body)
    if not isinstance(data, dict):
        raise MessageError("invalid", f"expected a map, got {type(data).__name__}")
    version = data.get("schema_version")
    if version != SCHEMA_VERSION:
        raise MessageError("schema_version", f"schema_version {version!r}, this coevo speaks {SCHEMA_VERSION}")
    try:
        msg = _ADAPTER.validate_python(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        field = str(first["loc"][-1]) if first["loc"] else ""
        where = ".".join(str(p) for p in first["loc"])
        reason = "invalid"
        if field == "fitness" and first["type"] == "value_error":
            reason = "non_finite"
        elif field == "rules" and first["type"] == "value_error":
            reason = "bad_rules"
        raise MessageError(reason, f"{where}: {first['msg']}") from None
    if isinstance(msg, (PolicyUpdate, CaseUpdate)) and msg.rules.get("behaviour") != msg.behaviour:
        raise MessageError("bad_rules", f"a {msg.behaviour} policy carrying {msg.rules.get('behaviour')!r} rules")
    if key is not None:
        _check_key(msg, key)
    return msg, fresh


_TOPICS = {"policy": ("policy", "current", "store/latest", "store/history"), "status": ("status",), "broker": ("broker",),
           "control": ("control",), "case": ("case", "store/cases"), "capabilities": ("capabilities",),
           "execution": ("execution",)}


def _check_key(msg: AnyMessage, key: str) -> None:
    k = keys.parse(key)
    if not k:
        raise MessageError("wrong_key", f"{key!r} is not a coevo key")
    if k["run"] != msg.run:
        raise MessageError("wrong_run", f"message for run {msg.run!r} on {key!r}")
    if k["topic"] not in _TOPICS[msg.kind]:
        raise MessageError("wrong_key", f"{msg.kind} message on {key!r}")
    beh = getattr(msg, "behaviour", None)
    if beh is not None and k.get("behaviour") != beh:
        raise MessageError("wrong_behaviour", f"{beh} {msg.kind} on {key!r}")
    robot = getattr(msg, "robot", None)
    if robot is not None and k.get("robot") != robot:
        raise MessageError("wrong_behaviour", f"{msg.kind} of robot {robot!r} on {key!r}")
    worker = getattr(msg, "worker", None)
    if msg.kind == "status" and k.get("worker") != worker:
        raise MessageError("wrong_behaviour", f"status of worker {worker!r} on {key!r}")
