"""Message authentication: a per-run secret key and an HMAC-SHA256 over every message and its key.

A run's processes share one secret of 32 random bytes (:class:`RunKey`).  Whatever
they put on the bus goes inside an *envelope* (format 2), a msgpack map::

    {"v": 2, "fresh": FRESH, "msg": MSG,
     "mac": HMAC-SHA256(secret, "coevo-mac-2\\0" + KEY_EXPRESSION + "\\0" + len(FRESH) as 4 bytes big-endian
                                + FRESH + MSG)}

where ``MSG`` is the message's own msgpack bytes (:func:`coevo.bus.messages.encode`),
``FRESH`` its freshness header (:mod:`coevo.bus.freshness`: run incarnation, sender
incarnation, sequence number, time sealed) and ``KEY_EXPRESSION`` the key it is put on
(a reply: the key it answers on).  Format 1 (``{"mac", "msg"}``, ``coevo-mac-1``, no
freshness: a captured message could be put again) is refused in a run with a key
(``schema_version``, saying so).  The
MAC covers the exact bytes and the key, so a message cannot be altered, and a valid
message copied onto another key (another behaviour, another run, the control key)
fails.  A receiver that holds the key checks the MAC before it parses the message
and rejects anything else as ``unauthenticated``; one without a key (an *open* run)
accepts envelopes and bare messages alike, unverified.

Why HMAC-SHA256 from the standard library: the key is symmetric and shared by the
run's members (nobody else needs to verify), ``hmac.compare_digest`` compares in
constant time, and it costs ~2 µs per policy message (``benchmarks/mac.py``); a
signature scheme would need a dependency and would only add value if members had
to be told apart cryptographically, which the roster (:mod:`coevo.bus.trust`)
bounds instead.

The key file is JSON, ``{"format": "coevo-run-key-1", "run": RUN, "key": HEX}``,
created with mode 0600 and refused when group or others may read it.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path

import msgpack

from coevo.errors import ConfigError

__all__ = ["KEY_ENV", "KEY_BYTES", "ENVELOPE", "RunKey", "mac", "mac2", "seal"]

#: The environment variable a worker reads its key file's path from (systemd units, spawners).
KEY_ENV = "COEVO_RUN_KEY_FILE"
KEY_BYTES = 32
_FORMAT = "coevo-run-key-1"
_DOMAIN = b"coevo-mac-1\x00"  # envelope format 1 (no freshness): refused, see the module docstring
_DOMAIN2 = b"coevo-mac-2\x00"
ENVELOPE = 2


def mac(secret: bytes, key_expr: str, body: bytes) -> bytes:
    """The authenticator of ``body`` put on ``key_expr``."""
    h = hmac.new(secret, _DOMAIN, hashlib.sha256)
    h.update(key_expr.encode("utf-8"))
    h.update(b"\x00")
    h.update(body)
    return h.digest()


def mac2(secret: bytes, key_expr: str, fresh: bytes, body: bytes) -> bytes:
    """The authenticator (format 2) of ``body`` with its freshness header ``fresh``, put on ``key_expr``."""
    h = hmac.new(secret, _DOMAIN2, hashlib.sha256)
    h.update(key_expr.encode("utf-8"))
    h.update(b"\x00")
    h.update(len(fresh).to_bytes(4, "big"))
    h.update(fresh)
    h.update(body)
    return h.digest()


def seal(body: bytes, key_expr: str, secret: bytes, fresh: bytes | None = None) -> bytes:
    """``body`` in a format-2 envelope with its freshness header (default: this process's next) and its
    authenticator for ``key_expr``."""
    if fresh is None:
        from coevo.bus.freshness import header

        fresh = header(0)
    sealed: bytes = msgpack.packb({"v": ENVELOPE, "fresh": fresh, "mac": mac2(secret, key_expr, fresh, body),
                                   "msg": body}, use_bin_type=True)
    return sealed


@dataclass(frozen=True)
class RunKey:
    """A run's secret key (never printed: its repr shows the run only)."""

    run: str
    secret: bytes

    def __repr__(self) -> str:
        return f"RunKey(run={self.run!r}, secret=<{len(self.secret)} bytes>)"

    @classmethod
    def create(cls, run: str) -> RunKey:
        return cls(run, secrets.token_bytes(KEY_BYTES))

    def save(self, path: Path) -> None:
        """Write the key file: created with mode 0600, never over an existing file, fsynced."""
        path = Path(path)
        data = json.dumps({"format": _FORMAT, "run": self.run, "key": self.secret.hex()}).encode() + b"\n"
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:
            raise ConfigError(f"key file {str(path)!r} already exists; a run key is never overwritten") from None
        except OSError as exc:
            raise ConfigError(f"cannot create the key file {str(path)!r}: {exc.strerror or exc}") from None
        try:
            os.fchmod(fd, 0o600)  # whatever the umask
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)

    @classmethod
    def load(cls, path: Path | str, *, run: str | None = None) -> RunKey:
        """The key in ``path``; a missing, unreadable, readable-by-others, malformed or foreign one is a ConfigError."""
        path = Path(path)
        try:
            st = path.stat()
            raw = path.read_bytes()
        except FileNotFoundError:
            raise ConfigError(f"key file {str(path)!r} does not exist") from None
        except OSError as exc:
            raise ConfigError(f"key file {str(path)!r} cannot be read: {exc.strerror or exc}") from None
        if not stat.S_ISREG(st.st_mode):
            raise ConfigError(f"key file {str(path)!r} is not a file")
        if st.st_mode & 0o077:
            raise ConfigError(f"key file {str(path)!r} is readable by others (mode {stat.S_IMODE(st.st_mode):04o}): "
                              f"chmod 600 {path}")
        try:
            data = json.loads(raw)
            key = bytes.fromhex(data["key"])
            owner = data["run"]
            ok = data.get("format") == _FORMAT and isinstance(owner, str) and len(key) == KEY_BYTES
        except (ValueError, TypeError, KeyError):
            ok = False
        if not ok:
            raise ConfigError(f"key file {str(path)!r} is not a coevo run key ({_FORMAT}: run and {KEY_BYTES} bytes of key)")
        if run is not None and owner != run:
            raise ConfigError(f"key file {str(path)!r} is the key of run {owner!r}, not of run {run!r}")
        return cls(owner, key)
