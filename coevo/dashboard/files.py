"""The dashboard's readers of files that grow while it watches them: a log's new lines, a file's last change.

Every page's model reads through these (a run's, a comparison's, a study's, the robot's), so they sit apart from
any of them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["Tail", "mtime"]


class Tail:
    """The new complete lines of a JSON-lines log since the last call (a log cut back, by a resumed worker, is
    read again from its start: ``reset`` is then True once)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._offset = 0
        self._partial = b""
        self.reset = False
        self.bad = 0  # lines that were not JSON objects (skipped, and said on the page)
        self.mtime = 0.0

    def read(self) -> list[dict[str, Any]]:
        self.reset = False
        try:
            st = self.path.stat()
        except OSError:
            return []
        self.mtime = st.st_mtime
        if st.st_size < self._offset:
            self._offset, self._partial, self.reset = 0, b"", True
        if st.st_size == self._offset:
            return []
        try:
            with open(self.path, "rb") as f:
                f.seek(self._offset)
                data = f.read()
        except OSError:
            return []
        from coevo.rundir.layout import json_object

        self._offset += len(data)
        lines = (self._partial + data).split(b"\n")
        self._partial = lines.pop()  # an incomplete last line waits for its end
        out = []
        for line in lines:
            if not line.strip():
                continue
            try:
                out.append(json_object(line))
            except ValueError:
                self.bad += 1
        return out


def mtime(p: Path) -> float:
    """When ``p`` last changed (0 when it cannot be read)."""
    try:
        return Path(p).stat().st_mtime
    except OSError:
        return 0.0
