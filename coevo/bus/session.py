"""The one module that owns Zenoh: configuration, sessions and the connection flags.

Flags follow the zenoh examples: ``--mode``, ``--connect``, ``--listen``,
``--config``, ``--no-multicast-scouting``.  Sessions are context managers: a
process that exits without closing a session that has callback subscribers hangs
(see docs/zenoh-notes.md), so every process closes its sessions in ``finally``.

Members only: :class:`Security` turns ``--tls-ca/--tls-cert/--tls-key`` (mutual
TLS on ``tls/`` endpoints) and ``--user/--password/--auth-file`` (Zenoh's
user/password authentication) into Zenoh transport settings, and checks the
merged configuration before any session opens, so that a missing certificate or
a ``tcp/`` endpoint beside TLS settings is a clear error rather than a timeout or
a run silently open to anyone.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any, cast

import zenoh

from coevo.bus.flags import DEFAULT_ENDPOINT, DEFAULT_LEASE_S, DEFAULT_TLS_ENDPOINT, PASSWORD_ENV, add_connection_args
from coevo.bus.messages import Message, PolicyUpdate
from coevo.bus.trust import OPEN, Gate
from coevo.bus.waiting import still_waiting
from coevo.errors import ConfigError, MessageError, ServiceError

__all__ = ["Session", "Sample", "Query", "Config", "Publisher", "LivelinessToken", "CallbackSubscriber", "ChannelSubscriber", "SessionGone", "fetch_latest", "DEFAULT_ENDPOINT", "DEFAULT_TLS_ENDPOINT", "PASSWORD_ENV", "Security", "add_connection_args", "config_from_args",
           "drain", "drain_messages", "is_put", "make_config", "open_session", "put_control", "query", "ring_subscriber", "sigterm_as_exit",
           "GatedSession", "Ring", "query_messages", "zenoh_text"]

log = logging.getLogger(__name__)



#: What zenoh raises when a declaration or a put meets a session that is closing (or closed): the one zenoh error
#: other modules handle (they log it and go on), named here so that nothing else imports zenoh.
SessionGone = zenoh.ZError


def _readable(what: str, path: str | Path) -> str:
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{what} {str(p)!r} does not exist or is not a file")
    try:
        with open(p, "rb") as f:
            f.read(1)
    except OSError as exc:
        raise ConfigError(f"{what} {str(p)!r} cannot be read: {exc.strerror}") from exc
    return str(p.resolve())


@dataclass(frozen=True, kw_only=True)
class Security:
    """Who may join a run: mutual TLS, user/password, or both (validated at construction).

    * ``tls_ca``: the CA that signed the members' certificates; a router accepts only
      clients whose certificate it signed (mutual TLS), a client accepts only a router
      whose certificate it signed.
    * ``tls_cert``/``tls_key``: this process's own certificate and key (a router's must
      name the host clients connect to).
    * ``user``/``password``: this process's credentials (a client's login, or a router's
      when it joins another router).
    * ``auth_file``: a router's dictionary of accepted ``user:password`` lines.
    """

    tls_ca: str | None = None
    tls_cert: str | None = None
    tls_key: str | None = None
    user: str | None = None
    password: str | None = None
    auth_file: str | None = None

    def __post_init__(self) -> None:
        if (self.tls_cert is None) != (self.tls_key is None):
            raise ConfigError("--tls-cert and --tls-key go together: give both (this process's certificate and its key)")
        if self.tls_cert is not None and self.tls_ca is None:
            raise ConfigError("--tls-cert needs --tls-ca (the CA that signed the other members' certificates)")
        for what, name in (("--tls-ca file", "tls_ca"), ("--tls-cert file", "tls_cert"), ("--tls-key file", "tls_key"),
                           ("--auth-file", "auth_file")):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _readable(what, getattr(self, name)))
        if (self.user is None) != (self.password is None):
            raise ConfigError(f"--user needs a password (--password or ${PASSWORD_ENV}) and a password needs --user")
        if self.user is not None and (not self.user or ":" in self.user):
            raise ConfigError(f"--user {self.user!r}: must be non-empty and contain no ':'")
        if self.auth_file is not None:
            try:
                lines = [x for x in Path(self.auth_file).read_text(encoding="utf-8").splitlines() if x.strip()]
            except UnicodeDecodeError as exc:
                raise ConfigError(f"--auth-file {self.auth_file!r} is not text (byte {exc.start} is not UTF-8): every "
                                  "line must be user:password") from None
            bad = [n for n, x in enumerate(lines, 1) if ":" not in x or not x.split(":", 1)[0] or not x.split(":", 1)[1]]
            if not lines or bad:
                raise ConfigError(f"--auth-file {self.auth_file!r}: every line must be user:password "
                                  f"({'empty file' if not lines else f'line {bad[0]} is not'})")

    @property
    def tls(self) -> bool:
        return self.tls_ca is not None

    @property
    def enabled(self) -> bool:
        return self.tls or self.user is not None or self.auth_file is not None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Security:
        password = getattr(args, "password", None)
        if password is None and getattr(args, "user", None) is not None:
            password = os.environ.get(PASSWORD_ENV)
        return cls(tls_ca=getattr(args, "tls_ca", None), tls_cert=getattr(args, "tls_cert", None),
                   tls_key=getattr(args, "tls_key", None), user=getattr(args, "user", None), password=password,
                   auth_file=getattr(args, "auth_file", None))

    def apply(self, conf: zenoh.Config, mode: str) -> None:
        """Write these settings into ``conf`` (a router both listens and, to join other routers, connects)."""
        sets: dict[str, Any] = {}
        if self.tls_ca is not None:
            sets["transport/link/tls/root_ca_certificate"] = self.tls_ca
            sets["transport/link/tls/enable_mtls"] = self.tls_cert is not None
        if self.tls_cert is not None:
            if mode == "router":
                sets["transport/link/tls/listen_certificate"] = self.tls_cert
                sets["transport/link/tls/listen_private_key"] = self.tls_key
            sets["transport/link/tls/connect_certificate"] = self.tls_cert
            sets["transport/link/tls/connect_private_key"] = self.tls_key
        if self.user is not None:
            sets["transport/auth/usrpwd/user"] = self.user
            sets["transport/auth/usrpwd/password"] = self.password
        if self.auth_file is not None:
            if mode != "router":
                raise ConfigError("--auth-file is a router's list of accepted users: give it to 'coevo broker' or 'coevo router'")
            sets["transport/auth/usrpwd/dictionary_file"] = self.auth_file
        for key, value in sets.items():
            conf.insert_json5(key, json.dumps(value))


def _endpoints(section: dict[str, Any] | None, mode: str) -> list[str]:
    """A config's ``listen``/``connect`` endpoints for ``mode``: a list, or a per-mode dict of lists."""
    eps = (section or {}).get("endpoints") or []
    if isinstance(eps, dict):
        return list(eps.get(mode) or [])
    return list(eps)


_PORTED = ("tcp/", "udp/", "tls/", "quic/", "ws/")
#: The link protocols zenoh knows (its transport links); any other it takes its 30 s connect timeout to refuse.
PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream", "unixpipe", "serial", "vsock")


def check_endpoint(ep: str, *, listen: bool) -> None:
    """Refuse an endpoint that cannot exist (a port beyond 65535, none, or no host) before zenoh tries it: zenoh
    only warns, and a router would say it joined a port that cannot exist."""
    if not isinstance(ep, str) or not ep.strip():
        raise ConfigError(f"endpoint {ep!r} is empty: give one like tcp/127.0.0.1:7447")
    proto, slash, rest = ep.partition("/")
    if not slash or not proto or not rest or not proto.replace("-", "").isalnum():
        raise ConfigError(f"endpoint {ep!r} is not PROTOCOL/ADDRESS (e.g. tcp/127.0.0.1:7447)")
    if proto not in PROTOCOLS:
        raise ConfigError(f"endpoint {ep!r}: unknown protocol {proto!r} (zenoh knows {', '.join(PROTOCOLS)})")
    if not ep.startswith(_PORTED):
        return  # unixsock-stream/PATH, serial/..., and others zenoh knows: its own checks
    addr = ep.split("/", 1)[1].split("#", 1)[0].split("?", 1)[0]
    host, sep, port = addr.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise ConfigError(f"endpoint {ep!r} has no HOST:PORT (e.g. tcp/127.0.0.1:7447)")
    if not (0 if listen else 1) <= int(port) <= 65535:
        raise ConfigError(f"endpoint {ep!r}: port {port} cannot exist (ports are {0 if listen else 1}..65535)")


def check_config(conf: zenoh.Config, *, source: str = "flags") -> None:
    """Refuse a merged configuration that would fail late or leave a protected run open."""
    try:
        d = json.loads(str(conf))
    except ValueError:  # a zenoh that prints its config differently: nothing to check
        return
    tls = ((d.get("transport") or {}).get("link") or {}).get("tls") or {}
    for key in ("root_ca_certificate", "listen_certificate", "listen_private_key", "connect_certificate", "connect_private_key"):
        if tls.get(key):
            _readable(f"transport/link/tls/{key} ({source})", tls[key])
    dictionary = (((d.get("transport") or {}).get("auth") or {}).get("usrpwd") or {}).get("dictionary_file")
    if dictionary:
        _readable(f"transport/auth/usrpwd/dictionary_file ({source})", dictionary)
    mode = d.get("mode") or "peer"
    listen, connect = _endpoints(d.get("listen"), mode), _endpoints(d.get("connect"), mode)
    has_tls = bool(tls.get("root_ca_certificate") or tls.get("listen_certificate"))
    for ep in listen:
        check_endpoint(ep, listen=True)
    for ep in connect:
        check_endpoint(ep, listen=False)
    for ep in listen + connect:
        if ep.startswith(("tls/", "quic/")) and not tls.get("root_ca_certificate"):
            raise ConfigError(f"endpoint {ep!r} is TLS but no CA is set: give --tls-ca (and --tls-cert/--tls-key for mutual TLS)")
    for ep in listen:
        if ep.startswith(("tls/", "quic/")) and not (tls.get("listen_certificate") and tls.get("listen_private_key")):
            raise ConfigError(f"listening on {ep!r} needs this router's certificate: give --tls-cert and --tls-key")
    if has_tls:
        plain = [ep for ep in (listen if mode == "router" else connect) if not ep.startswith(("tls/", "quic/"))]
        if plain:
            raise ConfigError(f"TLS is configured but endpoint {plain[0]!r} is not tls/: every "
                              f"{'listen' if mode == 'router' else 'connect'} endpoint must be tls/ or the run is open (or unreachable)")


_RUST_PLACE = re.compile(r"\s*\bat\s+\S+\.rs:\d+(?::\d+)?\.?")


def zenoh_text(exc: BaseException) -> str:
    """A zenoh error's words without the places in zenoh's Rust sources it names (``at /root/.cargo/.../x.rs:388``):
    a user's message says what went wrong, not where inside zenoh."""
    return _RUST_PLACE.sub("", str(exc)).strip().rstrip(".!").strip() or type(exc).__name__


def make_config(
    *,
    mode: str = "client",
    connect: list[str] | None = None,
    listen: list[str] | None = None,
    config_file: str | None = None,
    connect_timeout: float | None = 30.0,
    lease_ms: int | None = 3000,
    security: Security | None = None,
) -> zenoh.Config:
    if config_file:
        _readable("--zenoh-config file", config_file)
    try:
        conf = zenoh.Config.from_file(config_file) if config_file else zenoh.Config()
    except zenoh.ZError as exc:  # with the parser's message
        raise ConfigError(f"zenoh config {config_file!r}: {zenoh_text(exc)}") from exc
    if mode not in ("client", "peer", "router"):
        raise ConfigError(f"zenoh mode {mode!r} is not client, peer or router")
    if mode == "client" and not connect and not config_file:
        connect = [DEFAULT_TLS_ENDPOINT if security is not None and security.tls else DEFAULT_ENDPOINT]
    if lease_ms is not None and lease_ms < 500:
        raise ConfigError(f"lease {lease_ms} ms is too short: use at least 0.5 s (10 s across hosts)")
    try:
        conf.insert_json5("mode", json.dumps(mode))
        conf.insert_json5("scouting/multicast/enabled", "false")
        if connect:
            conf.insert_json5("connect/endpoints", json.dumps(connect))
        if listen:
            conf.insert_json5("listen/endpoints", json.dumps(listen))
        if mode != "router" and connect_timeout is not None:
            ms = -1 if connect_timeout < 0 else int(connect_timeout * 1000)
            conf.insert_json5("connect/timeout_ms", json.dumps(ms))
        if lease_ms is not None:
            conf.insert_json5("transport/link/tx/lease", json.dumps(lease_ms))
        if security is not None:
            security.apply(conf, mode)
    except (zenoh.ZError, ValueError, TypeError) as exc:
        raise ConfigError(f"bad zenoh setting: {zenoh_text(exc)}") from exc
    check_config(conf, source=f"--zenoh-config {config_file}" if config_file else "flags")
    return conf


def config_from_args(args: argparse.Namespace) -> zenoh.Config:
    lease = getattr(args, "lease", None)
    if lease is None and not args.config:
        lease = DEFAULT_LEASE_S  # with a config file, its lease (or zenoh's 10 s) stands unless --lease is given
    timeout = args.connect_timeout
    if timeout is None and not args.config:
        timeout = 30.0
    return make_config(mode=args.mode, connect=args.connect, listen=args.listen, config_file=args.config,
                       connect_timeout=timeout, lease_ms=None if lease is None else int(lease * 1000),
                       security=Security.from_args(args))


#: The wire's types, as zenoh's own stubs give them.  A :class:`GatedSession` stands for a session (it forwards
#: everything to one), so the rest of the code types both as ``Session``.
Session = zenoh.Session
Sample = zenoh.Sample
Query = zenoh.Query
Config = zenoh.Config
Publisher = zenoh.Publisher
LivelinessToken = zenoh.LivelinessToken
#: A subscriber whose samples go to a callback (its handler is None), and one whose samples wait in a channel.
CallbackSubscriber = zenoh.Subscriber[None]
ChannelSubscriber = zenoh.Subscriber[zenoh.handlers.Handler[zenoh.Sample]]


class GatedSession:
    """A zenoh session that knows its run's :class:`~coevo.bus.trust.Gate` (everything else is the session's)."""

    def __init__(self, session: Session, gate: Gate) -> None:
        self._session = session
        self.gate = gate

    def __getattr__(self, name: str) -> Any:
        return getattr(self._session, name)


def _reaching(conf: zenoh.Config) -> str:
    """`` (connecting to ENDPOINTS, giving up after N s: --connect-timeout)``, as far as ``conf`` says."""
    try:
        endpoints = json.loads(conf.get_json("connect/endpoints"))
        ms = json.loads(conf.get_json("connect/timeout_ms"))
    except (zenoh.ZError, ValueError, TypeError):
        return ""
    if not endpoints:
        return ""
    limit = "" if not isinstance(ms, (int, float)) else (", waiting for ever: --connect-timeout -1" if ms < 0 else
                                                         f", giving up after {ms / 1000:g} s: --connect-timeout")
    return f" (connecting to {', '.join(map(str, endpoints))}{limit})"


def _open(conf: zenoh.Config) -> Session:
    """``zenoh.open`` on a helper thread, waited for here in short steps: a SIGTERM or Ctrl-C while the router is
    still being reached (up to ``--connect-timeout``, 30 s) stops this process at once instead of after the wait,
    which zenoh does not cut short.  A session that opens after all belongs to a process that is ending."""
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["session"] = zenoh.open(conf)
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
            box["error"] = exc

    opener = threading.Thread(target=run, name="zenoh-open", daemon=True)
    opener.start()
    while opener.is_alive():
        opener.join(0.1)
    if "error" in box:
        raise box["error"]
    session: Session = box["session"]
    return session


@contextmanager
def open_session(conf: zenoh.Config, *, what: str = "session", gate: Gate | None = None) -> Iterator[Session]:
    """A zenoh session closed on exit; a router that cannot be reached (or refuses us) becomes a ServiceError.

    With ``gate``, the session's ring subscribers decode through it (see :func:`drain_messages`).
    """
    try:
        with still_waiting(f"opening the zenoh {what}{_reaching(conf)}"):
            session = _open(conf)
    except zenoh.ZError as exc:
        raise ServiceError(f"cannot open the zenoh {what}: {zenoh_text(exc)} (is 'coevo broker' running and reachable, "
                           "and does it accept this process's certificate or password?)") from exc
    try:
        yield session if gate is None else cast(Session, GatedSession(session, gate))
    finally:
        session.close()


def query(session: Session, key: str, *, timeout: float, what: str) -> list[tuple[str, bytes]]:
    """(reply key, payload) of the successful replies to a get on ``key`` (a store queryable), waiting up to ``timeout`` s;
    every reply, several on one key included, in the order they came.

    A session closing or a router going away meanwhile becomes a ServiceError naming ``what``;
    no reply at all within the timeout is an empty list (the caller knows whether that is news).
    """
    try:
        # No consolidation: a store's history and case base answer many replies on one key, and zenoh's default
        # keeps only the latest reply per key.
        return [(str(r.ok.key_expr), bytes(r.ok.payload.to_bytes()))
                for r in session.get(key, timeout=timeout, consolidation=zenoh.ConsolidationMode.NONE) if r.ok is not None]
    except zenoh.ZError as exc:
        raise ServiceError(f"query for {what} on {key!r} failed: {zenoh_text(exc)}") from exc


def query_messages(session: Session, key: str, *, timeout: float, what: str, gate: Gate | None = None) -> list[Message]:
    """The replies to a get on ``key`` that pass ``gate`` (default: the session's), decoded; a reply that does not
    goes to the gate's ``reject`` (else the log).  Errors as :func:`query`."""
    gate = gate if gate is not None else getattr(session, "gate", OPEN)
    out = []
    for k, payload in query(session, key, timeout=timeout, what=what):
        try:
            out.append(gate.decode(k, payload))
        except MessageError as err:
            if gate.reject is not None:
                gate.reject(err, k)
            else:
                log.warning("reply on %s rejected: %s", k, err)
    return out


class Ring:
    """A ring subscriber, the gate its messages pass (the session's) and its own memory of what it took
    (:class:`~coevo.bus.freshness.Seen`: a replay is refused per receiver)."""

    def __init__(self, subscriber: ChannelSubscriber, gate: Gate) -> None:
        from coevo.bus.freshness import Seen

        self.subscriber, self.gate = subscriber, gate
        self.seen = Seen()

    def try_recv(self) -> Sample | None:
        return self.subscriber.try_recv()

    def undeclare(self) -> None:
        self.subscriber.undeclare()


def ring_subscriber(session: Session, key: str, capacity: int) -> Ring:
    """A subscriber whose samples wait in a ring of the newest ``capacity``, drained with :func:`drain`.

    Nothing runs in Python per arriving sample: a flood on the key costs the
    receiving process no GIL time and cannot stall its connection (a callback that
    falls behind does, see docs/zenoh-notes.md); beyond ``capacity`` the oldest are dropped.
    """
    return Ring(session.declare_subscriber(key, zenoh.handlers.RingChannel(capacity)), getattr(session, "gate", OPEN))


def drain(subscriber: Ring, limit: int) -> list[tuple[str, bytes]]:
    """Up to ``limit`` waiting samples of a ring subscriber as (key, payload), oldest first; never blocks."""
    out: list[tuple[str, bytes]] = []
    while len(out) < limit:
        sample = subscriber.try_recv()
        if sample is None:
            break
        out.append((str(sample.key_expr), bytes(sample.payload.to_bytes())))
    return out


def drain_messages(subscriber: Ring, limit: int,
                   reject: Callable[[MessageError, str], None] | None = None) -> list[tuple[str, Message]]:
    """Like :func:`drain`, decoded through the ring's gate (key, roster, versions); bad ones go to ``reject``,
    else to the gate's own ``reject`` (or are skipped)."""
    gate = getattr(subscriber, "gate", OPEN)
    reject = reject if reject is not None else gate.reject
    out: list[tuple[str, Message]] = []
    for key, payload in drain(subscriber, limit):
        try:
            out.append((key, gate.decode(key, payload, getattr(subscriber, "seen", None))))
        except MessageError as err:
            if reject is not None:
                reject(err, key)
    return out


def put_control(session: Session, key: str, payload: bytes) -> None:
    """Put a one-off control message (a stop): blocking congestion control and a high priority, so a congested link
    (a slow subscriber's, under load) delays it rather than drops it, as zenoh's default drops what a full queue
    cannot take (docs/zenoh-notes.md).  Policies and statuses keep the default: a policy is put again until the broker's store
    holds it, a status at the next beat; a stop is put once."""
    session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK, priority=zenoh.Priority.INTERACTIVE_HIGH)


def is_put(sample: Sample) -> bool:
    """A liveliness sample that says a token appeared (PUT), rather than went (DELETE)."""
    return bool(sample.kind == zenoh.SampleKind.PUT)


def sigterm_as_exit() -> signal._HANDLER:
    """Turn SIGTERM into KeyboardInterrupt: one stop path, and ``finally`` blocks close sessions.

    Returns the previous handler, for callers that restore it.
    """

    def _raise(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    return signal.signal(signal.SIGTERM, _raise)


def fetch_latest(session: Session, run: str, timeout: float = 5.0, gate: Gate | None = None) -> dict[str, PolicyUpdate]:
    """The store's latest policy of each behaviour of ``run`` that passes ``gate`` (default: the session's)."""
    from coevo.bus import keys

    msgs = query_messages(session, keys.store_latest(run), timeout=timeout, what="the store's latest policies", gate=gate)
    return {m.behaviour: m for m in msgs if isinstance(m, PolicyUpdate) and m.run == run}
