"""The connection flags every process on the bus takes (``--connect``, ``--mode``, TLS, user/password, lease),
declared once; :func:`coevo.bus.session.config_from_args` turns them into a Zenoh config.

Kept apart from the session module so that a command's ``--help`` does not load Zenoh or the messages.
"""

from __future__ import annotations

import argparse

from coevo.config import Bounded

__all__ = ["DEFAULT_ENDPOINT", "DEFAULT_TLS_ENDPOINT", "PASSWORD_ENV", "DEFAULT_LEASE_S", "add_connection_args",
           "connection_given"]

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
DEFAULT_TLS_ENDPOINT = "tls/localhost:7447"  # TLS checks the router's name: use one its certificate carries
PASSWORD_ENV = "COEVO_ZENOH_PASSWORD"
DEFAULT_LEASE_S = 3.0


#: Seconds a client waits for its router: 0 to a day, or -1 for ever.
_timeout_arg = Bounded(0, 86400, whole=False, words=(("-1", -1.0),), what="timeout")
#: A link lease: 0.1 to 3600 seconds (zenoh counts it in whole milliseconds).
_lease_arg = Bounded(0.1, 3600, whole=False, what="lease")


def add_connection_args(p: argparse.ArgumentParser, *, default_mode: str = "client") -> None:
    p.add_argument("--mode", choices=["client", "peer", "router"], default=default_mode, help=f"zenoh mode (default {default_mode})")
    p.add_argument("--connect", "-e", action="append", metavar="ENDPOINT", help=f"endpoint to connect to (default {DEFAULT_ENDPOINT} for clients)")
    p.add_argument("--listen", "-l", action="append", metavar="ENDPOINT", help="endpoint to listen on")
    p.add_argument("--config", "--zenoh-config", "-c", dest="config", metavar="FILE",
                   help="a full zenoh JSON5 config file, e.g. from deploy/zenoh/ (flags override it)")
    p.add_argument("--no-multicast-scouting", action="store_true", default=True, help="(default) do not scout by multicast")
    p.add_argument("--connect-timeout", type=_timeout_arg, metavar="SECONDS",
                   help="how long a client waits for its router before giving up (default 30; -1: for ever)")
    p.add_argument("--lease", type=_lease_arg, metavar="SECONDS",
                   help=f"a link silent this long counts as dead and its session closes (default {DEFAULT_LEASE_S:g}; "
                        "across hosts use 10 or more: longer survives network cuts, shorter detects dead workers faster)")
    g = p.add_argument_group("members only (see deploy/README.md)")
    g.add_argument("--tls-ca", metavar="FILE", help="CA certificate (PEM) that signed the members' certificates: mutual TLS")
    g.add_argument("--tls-cert", metavar="FILE", help="this process's certificate (PEM), signed by --tls-ca")
    g.add_argument("--tls-key", metavar="FILE", help="the private key (PEM) of --tls-cert")
    g.add_argument("--user", help="user name for Zenoh user/password authentication")
    g.add_argument("--password", help=f"its password (better: set ${PASSWORD_ENV}; a flag shows in ps)")
    if default_mode == "router":
        g.add_argument("--auth-file", metavar="FILE", help="accepted users, one user:password per line (routers only)")


def connection_given(args: argparse.Namespace) -> bool:
    """Whether any connection flag was given (then a follower goes where they say; else ``coevo status`` and
    ``coevo dashboard`` find the runs under ``runs/`` and their brokers themselves)."""
    return args.mode != "client" or any(getattr(args, name, None) is not None for name in (
        "connect", "listen", "config", "connect_timeout", "lease", "tls_ca", "tls_cert", "tls_key", "user", "password"))
