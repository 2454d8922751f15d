"""Where the dashboard listens: a port checked before anything loads, and the one line a refused one says."""

from __future__ import annotations

from coevo.errors import ConfigError

__all__ = ["cannot_serve", "check_port"]


def cannot_serve(host: str, port: int, exc: OSError) -> ConfigError:
    """The one line a dashboard that cannot listen on ``host:port`` says."""
    return ConfigError(f"cannot serve on {host}:{port}: {exc.strerror or exc} (choose another --port or --host)")


def check_port(host: str, port: int) -> None:
    """A ConfigError when ``host:port`` cannot be listened on (taken, or not an address of this machine), found by
    binding it as the server will (SO_REUSEADDR) and letting it go: the server binds it again once the page is built."""
    import socket

    try:
        addresses = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        for family, kind, proto, _, address in addresses:
            with socket.socket(family, kind, proto) as s:
                s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                s.bind(address)
    except OSError as exc:  # socket.gaierror included: a host that is no address
        raise cannot_serve(host, port, exc) from None
    except UnicodeError:  # a host name no resolver takes (a label over 63 characters)
        raise ConfigError(f"cannot serve on {host}:{port}: not a host name (choose another --host)") from None
