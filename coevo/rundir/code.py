"""Which code made a run or an experiment: ``code.json`` beside its ``run.json`` (or ``compare.json``, ...).

A version is coevo's package version and a digest of its source: the sha256 of every ``*.py`` and ``*.rules``
file of the installed ``coevo`` package, in the order of their paths, each as its path (relative to the
package, with ``/``) and its bytes.  Two checkouts of one commit give the same digest (nothing of the machine,
the time or the checkout's place goes in); any edit of a source file, committed or not, gives another.  Compiled
files, caches and the other installed packages (numpy, ...: recorded per worker start in ``machines.jsonl``) are
not in it.

A resume on code of another version is refused, naming both, unless told ``--force``: its curves would mix two
versions of the code.  What ran a directory is kept in ``code.json``: the version of its latest start, and each
earlier version it ran on (``earlier``).  A directory without ``code.json`` (made before it existed) resumes as
it always did, and is given one.
"""

from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.rundir.layout import read_json, write_json

__all__ = ["CODE_FILE", "code_version", "version_text", "code_difference", "refuse_other_code", "record_code"]

#: The file beside a run's (or an experiment's) settings that says which code ran it.
CODE_FILE = "code.json"


@cache
def code_version() -> dict[str, str]:
    """This process's code: ``{"package": "0.1.0", "source": "<16 hex digits>"}``."""
    import coevo

    root = Path(coevo.__file__).parent
    digest = hashlib.sha256()
    for f in sorted(p for ext in ("*.py", "*.rules") for p in root.rglob(ext) if "__pycache__" not in p.parts):
        rel = f.relative_to(root).as_posix().encode()
        data = f.read_bytes()
        digest.update(len(rel).to_bytes(4, "big") + rel + len(data).to_bytes(8, "big") + data)
    return {"package": coevo.__version__, "source": digest.hexdigest()[:16]}


def version_text(v: dict[str, Any]) -> str:
    return f"coevo {v.get('package', '?')} (source {v.get('source', '?')})"


def _recorded(directory: Path) -> dict[str, Any] | None:
    f = Path(directory) / CODE_FILE
    if not f.exists() and not f.is_symlink():
        return None
    data = read_json(f, what="record of the code that ran it")
    if not isinstance(data.get("package"), str) or not isinstance(data.get("source"), str):
        raise RunDirError(f"{str(f)!r} is damaged: it names no code version (package, source)")
    return data


def code_difference(directory: Path) -> str:
    """'' when ``directory`` last ran on this code or does not say; else what differs, in words.  A damaged
    ``code.json`` is a RunDirError naming it."""
    recorded = _recorded(directory)
    now = code_version()
    if recorded is None or all(recorded[k] == now[k] for k in now):
        return ""
    return f"it ran on {version_text(recorded)}, this is {version_text(now)}"


def refuse_other_code(directory: Path, *, force: bool, what: str) -> None:
    """A RunDirError, before anything changes, when ``directory`` ran on other code and ``force`` is not given."""
    differs = code_difference(directory)
    if differs and not force:
        raise RunDirError(f"cannot resume {directory}: {differs}; its {what} would mix two versions of the code "
                          "(add --force to continue it anyway, and code.json keeps both)")


def record_code(directory: Path) -> None:
    """Say in ``directory``'s ``code.json`` that this code runs it now (the earlier versions kept)."""
    recorded = _recorded(directory)
    now = code_version()
    earlier = list(recorded.get("earlier", [])) if recorded else []
    if recorded is not None and any(recorded[k] != now[k] for k in now):
        earlier.append({k: recorded[k] for k in now})
    write_json(Path(directory) / CODE_FILE, {**now, "earlier": earlier})
