"""``coevo broker`` (the Zenoh router workers meet at, plus the policy store) and ``coevo router`` (a plain router).

Gathered by :mod:`coevo.cli`; the work is :mod:`coevo.broker.server`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from coevo.console import count_arg, positive_float_arg
from coevo.errors import ConfigError

__all__ = ["configure_broker", "configure_router"]


def configure_broker(p: argparse.ArgumentParser) -> None:
    """``coevo broker``'s arguments."""
    from coevo.bus.flags import add_connection_args

    add_connection_args(p, default_mode="router")
    p.add_argument("--data-dir", default="runs", help="where the store keeps each run's policies (default runs/)")
    p.add_argument("--inbox-mb", type=positive_float_arg(maximum=65536), default=64.0,
                   help="policy messages waiting to be stored at most (default 64 MB); a flood beyond is dropped and counted")
    p.add_argument("--open", action="store_true",
                   help="also store runs it holds no key for (DATA_DIR/RUN/secret.key), unauthenticated; "
                        "default: refuse them and count 'unauthenticated'")
    p.add_argument("--quota-runs", type=count_arg(1, 1_000_000), default=32,
                   help="runs the store takes policies for since the broker started (default 32); beyond: refused, counted as quota")
    p.add_argument("--quota-policies", type=count_arg(1, 10**9), default=10_000,
                   help="policies stored per run at most (default 10000; the report's parameters publish at most 150)")
    p.add_argument("--quota-mb", type=positive_float_arg(maximum=1 << 20), default=64.0,
                   help="bytes on disk per run at most, in MB (default 64: 10000 of the largest policies)")
    p.set_defaults(func=cmd_broker)


def cmd_broker(args: argparse.Namespace) -> int:
    from coevo.broker.server import serve_broker
    from coevo.broker.store import Quota

    if not str(args.data_dir).strip():
        raise ConfigError(f"--data-dir {args.data_dir!r} is empty: give the directory the store keeps runs in (default runs)")
    return serve_broker(args, data_dir=Path(args.data_dir), inbox_bytes=int(args.inbox_mb * (1 << 20)), open_runs=args.open,
                        quota=Quota(runs=args.quota_runs, policies=args.quota_policies, bytes=int(args.quota_mb * (1 << 20))))


def configure_router(p: argparse.ArgumentParser) -> None:
    """``coevo router``'s arguments."""
    from coevo.bus.flags import add_connection_args

    add_connection_args(p, default_mode="router")
    p.set_defaults(func=cmd_router)


def cmd_router(args: argparse.Namespace) -> int:
    """A plain Zenoh router (no store): a second site's meeting point, joined to the broker with --connect."""
    from coevo.broker.server import serve_router

    return serve_router(args)
