"""A worker's checkpoint: everything it needs to continue after a crash, in one file.

After every generation the worker writes ``checkpoint.msgpack`` in its directory:
the GA (population with learned strengths, control genes, best and current
policies, generator state), its models of the partners (policies, versions,
generator state), its publication counter, rejection counts, timings, and the
lengths of its append-only logs (``curve.jsonl``, ``adoptions.jsonl``,
``published.jsonl``) at that moment.  On ``--resume`` the logs are cut back to
those lengths, so whatever a crash left after the checkpoint (a curve line, an
adoption, a publication of a generation that is now done again) disappears and
the logs agree with the restored state: a replay reproduces the whole run.

The file is written atomically (:func:`coevo.runs.layout.write_bytes`) and carries a
CRC-32 of its body, so a crash mid-write leaves the previous checkpoint intact and
a damaged file is refused with its name rather than half-read.
"""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

import msgpack

from coevo.errors import RunDirError
from coevo.runs.layout import write_bytes

__all__ = ["FORMAT", "save_checkpoint", "load_checkpoint", "truncate_log"]

FORMAT = "coevo-checkpoint/1"


def save_checkpoint(path: Path, ident: dict[str, Any], state: dict[str, Any]) -> None:
    """Write ``state`` for the worker ``ident`` (run, behaviour, worker, seed) atomically."""
    body = msgpack.packb(state, use_bin_type=True)
    write_bytes(Path(path), msgpack.packb({"format": FORMAT, "ident": ident, "crc32": zlib.crc32(body), "body": body},
                                          use_bin_type=True))


def load_checkpoint(path: Path, ident: dict[str, Any]) -> dict[str, Any] | None:
    """The state saved at ``path`` (None if there is none); refuses a damaged or foreign file."""
    path = Path(path)
    if not path.exists():
        return None
    try:
        outer = msgpack.unpackb(path.read_bytes(), raw=False)
        body = outer["body"]
        fmt, saved, crc = outer["format"], outer["ident"], outer["crc32"]
    except (OSError, msgpack.UnpackException, ValueError, TypeError, KeyError) as exc:
        raise RunDirError(f"checkpoint {str(path)!r} cannot be read ({type(exc).__name__}: {exc}); "
                          "move it away to start this worker afresh") from None
    if fmt != FORMAT:
        raise RunDirError(f"checkpoint {str(path)!r} has format {fmt!r}; this coevo reads {FORMAT!r}")
    if zlib.crc32(body) != crc:
        raise RunDirError(f"checkpoint {str(path)!r} is damaged (CRC mismatch); move it away to start this worker afresh")
    if saved != ident:
        diff = ", ".join(f"{k} {saved.get(k)!r} (asked: {ident.get(k)!r})" for k in sorted(set(saved) | set(ident))
                         if saved.get(k) != ident.get(k))
        raise RunDirError(f"checkpoint {str(path)!r} belongs to another worker: {diff}")
    state: dict[str, Any] = msgpack.unpackb(body, raw=False, strict_map_key=False)
    return state


def truncate_log(path: Path, size: int) -> None:
    """Cut an append-only log back to ``size`` bytes (what it held at the checkpoint)."""
    path = Path(path)
    have = path.stat().st_size if path.exists() else 0
    if have < size:
        raise RunDirError(f"{str(path)!r} holds {have} bytes but the checkpoint saw {size}: the worker directory was "
                          "changed behind the worker's back; it cannot be resumed")
    if have > size:
        with open(path, "r+b") as f:
            f.truncate(size)
