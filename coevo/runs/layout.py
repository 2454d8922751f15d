"""Run directories: written in a temporary sibling and renamed into place when complete.

A run that fails or is interrupted leaves no half-written directory under the name
the user asked for; files are written atomically (temp file, fsync, rename).
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError

__all__ = ["staged_dir", "read_jsonl", "write_bytes", "write_json", "write_text", "write_csv"]


@contextmanager
def staged_dir(final: Path) -> Iterator[Path]:
    """Yield a temporary directory that becomes ``final`` only if the block succeeds."""
    final = Path(final)
    if final.exists() and not final.is_dir():
        raise RunDirError(f"output directory {str(final)!r} is a file; choose another --out")
    if final.exists() and any(final.iterdir()):
        raise RunDirError(f"output directory {str(final)!r} already exists and is not empty; choose another --out")
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".partial", dir=final.parent))
    except OSError as exc:
        raise RunDirError(f"cannot create output directory {str(final)!r}: {exc.strerror or exc}") from exc
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if final.exists():
        final.rmdir()
    os.replace(tmp, final)


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``path`` atomically: a temporary sibling, fsynced, renamed over it, the directory fsynced.

    A crash at any moment leaves either the old file or the new one, never a torn one.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    dfd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)


def write_text(path: Path, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def write_json(path: Path, data: Any) -> None:
    write_text(path, json.dumps(data, indent=2, sort_keys=True) + "\n")


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    if not rows:
        write_text(path, "")
        return
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0].keys()), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    write_text(path, buf.getvalue())


def read_jsonl(path: Path, *, missing_ok: bool = False, problems: list[str] | None = None) -> list[dict[str, Any]]:
    """The rows of a JSON-lines log (blank lines skipped).

    A missing file is ``[]`` with ``missing_ok``, else a RunDirError; a line that is
    not JSON is a RunDirError naming the file and line, or, when ``problems`` is
    given, noted there and skipped (``coevo check`` lists every one).
    """
    path = Path(path)
    if not path.exists():
        if missing_ok:
            return []
        if problems is None:
            raise RunDirError(f"{path} is missing: not a complete run directory")
        problems.append(f"{path} is missing")
        return []
    rows = []
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError as exc:
            if problems is None:
                raise RunDirError(f"{path} line {n} is not JSON: {exc}") from None
            problems.append(f"{path} line {n} is not JSON")
    return rows
