"""The one module that owns Zenoh: configuration, sessions and the connection flags.

Flags follow the zenoh examples: ``--mode``, ``--connect``, ``--listen``,
``--config``, ``--no-multicast-scouting``.  Sessions are context managers: a
process that exits without closing a session that has callback subscribers hangs
(see ZENOH-NOTES), so every process closes its sessions in ``finally``.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import zenoh

from coevo.errors import ConfigError

__all__ = ["DEFAULT_ENDPOINT", "add_connection_args", "make_config", "open_session", "sigterm_as_exit"]

log = logging.getLogger(__name__)

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


def add_connection_args(p: argparse.ArgumentParser, *, default_mode: str = "client") -> None:
    p.add_argument("--mode", choices=["client", "peer", "router"], default=default_mode, help=f"zenoh mode (default {default_mode})")
    p.add_argument("--connect", "-e", action="append", metavar="ENDPOINT", help=f"endpoint to connect to (default {DEFAULT_ENDPOINT} for clients)")
    p.add_argument("--listen", "-l", action="append", metavar="ENDPOINT", help="endpoint to listen on")
    p.add_argument("--config", "-c", metavar="FILE", help="a zenoh JSON5 config file (flags override it)")
    p.add_argument("--no-multicast-scouting", action="store_true", default=True, help="(default) do not scout by multicast")
    p.add_argument("--connect-timeout", type=float, default=30.0, metavar="SECONDS",
                   help="how long a client waits for its router before giving up (default 30; -1: for ever)")


def make_config(
    *,
    mode: str = "client",
    connect: list[str] | None = None,
    listen: list[str] | None = None,
    config_file: str | None = None,
    connect_timeout: float = 30.0,
    lease_ms: int | None = 3000,
) -> zenoh.Config:
    try:
        conf = zenoh.Config.from_file(config_file) if config_file else zenoh.Config()
    except Exception as exc:  # zenoh raises ZError with the parser's message
        raise ConfigError(f"zenoh config {config_file!r}: {exc}") from exc
    if mode not in ("client", "peer", "router"):
        raise ConfigError(f"zenoh mode {mode!r} is not client, peer or router")
    if mode == "client" and not connect and not config_file:
        connect = [DEFAULT_ENDPOINT]
    try:
        conf.insert_json5("mode", json.dumps(mode))
        conf.insert_json5("scouting/multicast/enabled", "false")
        if connect:
            conf.insert_json5("connect/endpoints", json.dumps(connect))
        if listen:
            conf.insert_json5("listen/endpoints", json.dumps(listen))
        if mode != "router":
            ms = -1 if connect_timeout < 0 else int(connect_timeout * 1000)
            conf.insert_json5("connect/timeout_ms", json.dumps(ms))
        if lease_ms is not None:
            conf.insert_json5("transport/link/tx/lease", json.dumps(lease_ms))
    except Exception as exc:
        raise ConfigError(f"bad zenoh setting: {exc}") from exc
    return conf


def config_from_args(args: argparse.Namespace) -> zenoh.Config:
    return make_config(mode=args.mode, connect=args.connect, listen=args.listen, config_file=args.config,
                       connect_timeout=args.connect_timeout)


@contextmanager
def open_session(conf: zenoh.Config, *, what: str = "session") -> Iterator[Any]:
    """A zenoh session closed on exit; a router that cannot be reached becomes a ConfigError."""
    try:
        session = zenoh.open(conf)
    except Exception as exc:
        raise ConfigError(f"cannot open the zenoh {what}: {exc} (is 'coevo broker' running and reachable?)") from exc
    try:
        yield session
    finally:
        session.close()


def sigterm_as_exit() -> Any:
    """Turn SIGTERM into KeyboardInterrupt: one stop path, and ``finally`` blocks close sessions.

    Returns the previous handler, for callers that restore it.
    """

    def _raise(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    return signal.signal(signal.SIGTERM, _raise)
