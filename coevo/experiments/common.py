"""What the many-run commands share around :mod:`coevo.replicates`: their ``--out`` folder (fresh, or this very
experiment with ``--resume``) and the run of their replicates with a progress bar and the failures reported.

The runner owns the job loop; this only keeps the commands' own few lines alike (``coevo cel-experiment``,
``coevo seeds``, ``coevo td-baseline``).
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from coevo.errors import RunDirError
from coevo.replicates.replicate import Replicate

if TYPE_CHECKING:
    from coevo.replicates.backends import Backend
    from coevo.replicates.runner import Progress

__all__ = ["REPORT_SETTINGS", "below_report", "held_spec", "open_out", "plural", "prepare_out", "run_with_progress"]

#: The settings the report's findings rest on (Appendix A): per agent and generation, and runs per regime.
REPORT_SETTINGS = {"generations": 50, "population": 50, "episodes": 90, "runs a regime": 10}


def plural(n: int, noun: str) -> str:
    """``n`` and the noun in its number: "1 run", "2 runs" (for the nouns the reports count, all regular)."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def below_report(settings: dict[str, int]) -> str:
    """One line saying which ``settings`` (named as in :data:`REPORT_SETTINGS`) are below the report's and what that
    means for a verdict, or '' when none is."""
    low = [f"{k} {v} (the report's {REPORT_SETTINGS[k]})"
           for k, v in settings.items() if v < REPORT_SETTINGS[k]]
    if not low:
        return ""
    return ("These settings are below the report's: " + ", ".join(low) + ". This is a smoke test, not a "
            "reproduction: a finding 'not reproduced' or a target 'MISSED' here says nothing about the report's.")


def held_spec(out: Path, marker: str, mine: dict[str, Any], *, what: str = "experiment") -> dict[str, Any] | None:
    """The settings an earlier run of this command left in ``out/marker`` (None: none there); a RunDirError naming
    ``--out`` when they cannot be read or are not ``mine`` (another experiment, or other settings)."""
    f = out / marker
    if not f.exists():
        return None
    try:
        held = json.loads(f.read_text())["spec"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RunDirError(f"--out {str(out)!r}: {marker} cannot be read ({exc}); choose another --out") from exc
    if held != mine:
        diff = sorted(k for k in set(held) | set(mine) if held.get(k) != mine.get(k))
        raise RunDirError(f"--out {str(out)!r} holds a different {what} (differs in: {', '.join(diff)}); choose "
                          "another --out or repeat the original settings with --resume")
    return held


def prepare_out(out: Path, marker: str, spec: dict[str, Any], *, resume: bool) -> None:
    """A fresh experiment needs an empty or missing ``out``; ``resume`` needs this very experiment there (the
    settings in ``out/marker`` equal to ``spec``).  Writes the marker; raises RunDirError naming ``--out``."""
    from coevo.rundir.layout import ensure_dir, write_json

    f = out / marker
    mine = json.loads(json.dumps(spec))
    if out.exists() and not out.is_dir():
        raise RunDirError(f"--out {str(out)!r} is a file, not a directory")
    held = held_spec(out, marker, mine)
    if resume and held is None:
        raise RunDirError(f"--resume: {str(out)!r} holds no such experiment (no {marker})")
    if not resume and out.is_dir() and any(out.iterdir()):
        raise RunDirError(f"--out {str(out)!r} is not empty; add --resume to continue the runs there")
    ensure_dir(out, what="--out")
    if held is None:
        write_json(f, {"spec": mine, "created": time.time()})


def open_out(args: Any, out: Path, marker: str, spec: dict[str, Any], *, default_jobs: int) -> Any:
    """The backend the flags ask for, then ``out`` prepared (:func:`prepare_out`; the backend closed again if
    ``out`` is refused): nothing is written into ``out`` before the backend is open, so a scheduler that cannot
    be reached leaves ``out`` as it was."""
    from coevo.replicates.flags import backend_of

    backend = backend_of(args, default_jobs=default_jobs)
    try:
        prepare_out(out, marker, spec, resume=args.resume)
    except BaseException:
        backend.close()
        raise
    return backend


def run_with_progress(reps: Sequence[Replicate], out: Path, backend: Backend[Any], *, label: str, quiet: bool,
                      unit: str = "generations") -> Progress | None:
    """Run ``reps`` on ``backend`` with a progress bar in ``unit`` (what the replicates' costs count); print each
    failure with its log.  Returns the runner's Progress, or None when the Dask scheduler was lost (said on
    stderr, with how to continue)."""
    from coevo.console import ProgressBar
    from coevo.replicates.backends import ClusterLost
    from coevo.replicates.runner import run_replicates

    total = sum(r.cost for r in reps)
    with ProgressBar(label, total=total, unit=unit, quiet=quiet) as bar:
        try:
            prog = run_replicates(reps, out, backend, on_progress=lambda p: bar.update(p.done, p.total, p.info))
        except ClusterLost as exc:
            print(f"{exc}; finished runs are kept: continue with the same command and --resume --out {out}",
                  file=sys.stderr)
            return None
    for name, why in prog.failed.items():
        print(f"  {name} failed: {why} (log: {out / 'logs' / (name + '.log')})", file=sys.stderr)
    return prog
