"""Every Zenoh key expression coevo uses, built in one place (the wire protocol).

    coevo/<run>/policy/<behaviour>              PolicyUpdate, put by that behaviour's worker
    coevo/<run>/current/<behaviour>             PolicyUpdate of its current generation's best
                                                (version = generation), for the "current" model
    coevo/<run>/status/<behaviour>/<worker>     Status heartbeat, once per generation
    coevo/<run>/control                         Control (stop)
    coevo/<run>/alive/<behaviour>/<worker>      liveliness token of a worker
    coevo/<run>/store/latest/<behaviour>        broker queryable: the latest PolicyUpdate
    coevo/<run>/store/history/<behaviour>       broker queryable: every PolicyUpdate, in order
    coevo/<run>/store/versions/<behaviour>      broker queryable: the versions it holds, per worker
    coevo/<run>/broker                          BrokerStatus: what the broker stored and rejected
    coevo/<run>/case/<behaviour>                CaseUpdate: a strategy for the case base (CEL learner)
    coevo/<run>/store/cases/<behaviour>         broker queryable: every CaseUpdate, in order
    coevo/<run>/capabilities/<robot>            CapabilityUpdate: the robot's working sensors (its monitor)
    coevo/<run>/execution/<robot>               ExecutionStatus heartbeat of an execution module
    coevo/<run>/robot_alive/<robot>             liveliness token of an execution module
    coevo/_broker                               liveliness token of a broker with its store up
    coevo/_broker/degraded                      liveliness token of a broker whose store cannot write

Run ids, worker ids and robot ids are single key chunks: letters, digits, ``_``, ``-``, ``.``.
"""

from __future__ import annotations

import re

from coevo.errors import ConfigError
import coevo.tasks  # noqa: F401 - the tasks' registry: a behaviour named on a key has its task found and loaded
from coevo.policy.schema import known, registered

__all__ = ["ROOT", "BROKER", "BROKER_DEGRADED", "check_id", "valid_id", "policy", "current", "status", "control", "alive", "store_latest", "store_history",
           "store_versions", "broker_status", "case", "store_cases", "capabilities", "execution", "robot_alive", "parse"]

ROOT = "coevo"
BROKER = f"{ROOT}/_broker"
BROKER_DEGRADED = f"{BROKER}/degraded"
_ID = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


def check_id(kind: str, value: str) -> str:
    """``value`` if it is a valid single key chunk, else a ConfigError naming it."""
    if not valid_id(value):
        raise ConfigError(f"{kind} {value!r} is not valid: use 1-64 letters, digits, '_', '-' or '.'")
    return value


def valid_id(value: str) -> bool:
    return isinstance(value, str) and bool(_ID.match(value)) and value not in (".", "..")


def _b(behaviour: str) -> str:
    name = str(behaviour)
    if not known(name):
        raise ConfigError(f"unknown behaviour {name!r} (known: {', '.join(registered())})")
    return name


def _w(b: str | None) -> str:
    return "*" if b is None else _b(b)


def policy(run: str, behaviour: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/policy/{_w(behaviour)}"


def current(run: str, behaviour: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/current/{_w(behaviour)}"


def status(run: str, behaviour: str | None = None, worker: str | None = None) -> str:
    w = "*" if worker is None else check_id("worker id", worker)
    return f"{ROOT}/{check_id('run id', run)}/status/{_w(behaviour)}/{w}"


def control(run: str) -> str:
    return f"{ROOT}/{check_id('run id', run)}/control"


def alive(run: str, behaviour: str | None = None, worker: str | None = None) -> str:
    w = "*" if worker is None else check_id("worker id", worker)
    return f"{ROOT}/{check_id('run id', run)}/alive/{_w(behaviour)}/{w}"


def store_latest(run: str, behaviour: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/store/latest/{_w(behaviour)}"


def store_history(run: str, behaviour: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/store/history/{_w(behaviour)}"


def store_versions(run: str, behaviour: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/store/versions/{_w(behaviour)}"


def broker_status(run: str) -> str:
    return f"{ROOT}/{check_id('run id', run)}/broker"


def case(run: str, behaviour: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/case/{_w(behaviour)}"


def store_cases(run: str, behaviour: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/store/cases/{_w(behaviour)}"


def _r(robot: str | None) -> str:
    return "*" if robot is None else check_id("robot id", robot)


def capabilities(run: str, robot: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/capabilities/{_r(robot)}"


def execution(run: str, robot: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/execution/{_r(robot)}"


def robot_alive(run: str, robot: str | None = None) -> str:
    return f"{ROOT}/{check_id('run id', run)}/robot_alive/{_r(robot)}"


_ROBOT_TOPICS = ("capabilities", "execution", "robot_alive")


def parse(key: str) -> dict[str, str]:
    """Split a concrete key into its parts: ``{"run", "topic", "behaviour"?, "worker"?}`` (``"robot"`` instead of
    ``"behaviour"`` on an execution module's topics); {} if not coevo's."""
    parts = str(key).split("/")
    if len(parts) < 3 or parts[0] != ROOT:
        return {}
    out = {"run": parts[1], "topic": parts[2]}
    rest = parts[3:]
    if parts[2] == "store" and len(rest) == 2:
        out["topic"] = f"store/{rest[0]}"
        rest = rest[1:]
    if rest and parts[2] in _ROBOT_TOPICS:
        out["robot"] = rest[0]
        return out
    if rest:
        out["behaviour"] = rest[0]
    if len(rest) > 1:
        out["worker"] = rest[1]
    return out
