"""A study's folder, its replicates on the runner, resuming it, marking it complete, and its progress as data.

The folder (``--out``)::

    study.json          the declaration (StudySpec) and its cells, written first; --resume checks it
    cells/CELL/         one ``coevo compare`` folder per cell (compare.json, settings/, runs/): every cell's
                        replicates are exactly the comparison's, so ``coevo compare --report-only --out
                        cells/CELL`` writes a cell's full comparison report
    logs/CELL@RUN.log   each replicate's log (the runner's)
    report.md, results.json, effect-FACTOR.png, cells.png    the study's report (:mod:`.report`)
    complete.json       written last, atomically, when every run finished and the report is written

``complete.json`` names the declaration it completes (a digest of study.json's spec) and how many runs it holds; a
folder without it, or whose marker names another declaration, is a study in progress, whatever else it holds.
Any run of ``coevo study`` on a folder removes the marker before it starts anything.

All cells' replicates go to one :func:`~coevo.replicates.runner.run_replicates`, interleaved by replicate index
(run 0 of every cell, then run 1, ...), so ``--jobs`` and ``--cluster`` are shared by the whole study and a study
cut short is balanced across its cells.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.experiments.compare.experiment import is_finished, jobs_of, prepare, replicates
from coevo.experiments.study.declaration import Cell, StudySpec, cells
from coevo.replicates.backends import Backend
from coevo.replicates.replicate import Replicate as Job
from coevo.replicates.runner import Progress, run_replicates
from coevo.rundir.layout import ensure_dir, write_json

__all__ = ["MARKER", "COMPLETE", "SEP", "prepare_study", "study_jobs", "run_study", "held_declaration", "mark_complete",
           "is_complete", "StudyProgress", "CellProgress", "study_progress", "cell_dir"]

MARKER = "study.json"
COMPLETE = "complete.json"
#: Between a cell and a run in a replicate's name (``CELL@RUN``, its log ``logs/CELL@RUN.log``): a character no cell
#: id or run id holds, and no "/", since the name also prefixes a Dask worker's temporary folder.
SEP = "@"


def cell_dir(out: Path, cell: Cell) -> Path:
    return Path(out) / "cells" / cell.id


def _digest(spec: StudySpec) -> str:
    return hashlib.sha256(json.dumps(spec.as_dict(), sort_keys=True).encode()).hexdigest()


def held_declaration(out: Path) -> StudySpec | None:
    """The declaration in ``out/study.json`` (None: there is none); a RunDirError naming ``--out`` if unreadable."""
    f = Path(out) / MARKER
    if not f.exists():
        return None
    try:
        return StudySpec.from_dict(json.loads(f.read_text())["spec"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise RunDirError(f"--out {str(out)!r}: {MARKER} cannot be read ({exc}); choose another --out") from exc


def _differences(held: StudySpec, mine: StudySpec) -> list[str]:
    a, b = held.as_dict(), mine.as_dict()
    diff = [k for k in ("name", "seed", "description") if a[k] != b[k]]
    la, lb = dict(a["levels"]), dict(b["levels"])
    diff += [k for k in dict.fromkeys([*la, *lb]) if la.get(k) != lb.get(k)]
    if not diff and list(la) != list(lb):
        diff.append("the order of the factors")
    return diff


def prepare_study(out: Path, spec: StudySpec, *, resume: bool) -> list[Cell]:
    """Check ``out`` and set it up: a fresh study needs an empty or missing folder; ``resume`` needs this very study
    there (else a RunDirError naming what differs).  Removes the completion marker, writes study.json (fresh) and
    every cell's compare.json; returns the cells."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RunDirError(f"--out {str(out)!r} is a file, not a directory")
    held = held_declaration(out)
    if held is not None and held != spec:
        raise RunDirError(f"--out {str(out)!r} holds a different study (differs in: {', '.join(_differences(held, spec))}); "
                          "choose another --out or repeat the original declaration with --resume")
    if resume and held is None:
        raise RunDirError(f"--resume: {str(out)!r} holds no study (no {MARKER})")
    if not resume and out.is_dir() and any(out.iterdir()):
        more = "add --resume to continue it" if held is not None else "choose another --out"
        raise RunDirError(f"--out {str(out)!r} is not empty; {more}")
    the_cells = cells(spec)
    ensure_dir(out, what="--out")
    (out / COMPLETE).unlink(missing_ok=True)  # from here on the folder is a study in progress
    if held is None:
        write_json(out / MARKER, {"spec": spec.as_dict(), "created": time.time(),
                                  "cells": [{"id": c.id, "levels": dict(c.levels), "seed": c.spec.seed}
                                            for c in the_cells]})
    for c in the_cells:
        prepare(cell_dir(out, c), c.spec, resume=True)  # makes the cell's compare.json, or checks the one there
    return the_cells


def _in_cell(cell: str, fn: Callable[[Path], Any], root: Path) -> Any:
    """A comparison's replicate function, called on its cell's folder under the study's ``root``."""
    return fn(Path(root) / "cells" / cell)


def study_jobs(out: Path, the_cells: list[Cell]) -> list[Job]:
    """Every cell's comparison replicates (:func:`~coevo.experiments.compare.experiment.jobs_of`), renamed
    ``CELL@RUN`` and pointed at ``cells/CELL``, interleaved by replicate index."""
    keyed: list[tuple[int, int, int, Job]] = []
    for ci, c in enumerate(the_cells):
        for k, (rep, job) in enumerate(zip(replicates(c.spec), jobs_of(cell_dir(out, c), c.spec), strict=True)):
            pre = f"cells/{c.id}/"
            keyed.append((rep.index, ci, k, Job(
                name=f"{c.id}{SEP}{job.name}", output=pre + job.output, finished=partial(_in_cell, c.id, job.finished),
                command=None if job.command is None else partial(_in_cell, c.id, job.command),
                function=job.function, kwargs=job.kwargs, inputs=tuple(pre + i for i in job.inputs),
                after=tuple(f"{c.id}{SEP}{a}" for a in job.after), weight=job.weight, cost=job.cost,
                progress=None if job.progress is None else partial(_in_cell, c.id, job.progress))))
    return [j for *_, j in sorted(keyed, key=lambda t: t[:3])]


def run_study(out: Path, the_cells: list[Cell], *, backend: Backend,
              on_progress: Callable[[Progress], None] | None = None, poll: float = 1.0) -> Progress:
    """Run every unfinished replicate of the study on ``backend`` (the runner skips the finished ones)."""
    return run_replicates(study_jobs(Path(out), the_cells), Path(out), backend, on_progress=on_progress, poll=poll)


def mark_complete(out: Path, spec: StudySpec, *, runs: int) -> None:
    """Write the completion marker, atomically, last of all."""
    write_json(Path(out) / COMPLETE, {"spec_sha256": _digest(spec), "runs": runs, "finished": time.time()})


def is_complete(out: Path, spec: StudySpec) -> bool:
    """Does ``out`` hold this study finished: a completion marker naming this very declaration?"""
    try:
        mark = json.loads((Path(out) / COMPLETE).read_text())
        return bool(mark["spec_sha256"] == _digest(spec))
    except (OSError, ValueError, KeyError, TypeError):
        return False


@dataclass(frozen=True)
class CellProgress:
    id: str
    levels: dict[str, Any]
    runs_done: int
    runs_total: int

    @property
    def done(self) -> bool:
        return self.runs_done == self.runs_total


@dataclass(frozen=True)
class StudyProgress:
    """How far a study folder is, as plain data (for a dashboard or a script): read from the files alone."""

    name: str
    cells_total: int
    cells_done: int
    runs_total: int
    runs_done: int
    complete: bool  # every run finished and the report written (the completion marker is there and names it)
    cells: list[CellProgress] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def study_progress(out: Path) -> StudyProgress:
    """Cells done of the total, runs done of the total, and whether ``out`` holds the study complete.  A RunDirError
    when ``out`` holds no study."""
    spec = held_declaration(Path(out))
    if spec is None:
        raise RunDirError(f"{str(out)!r} holds no study (no {MARKER})")
    per_cell = []
    for c in cells(spec):
        reps = replicates(c.spec)
        done = sum(1 for r in reps if is_finished(cell_dir(out, c), r))
        per_cell.append(CellProgress(c.id, dict(c.levels), done, len(reps)))
    return StudyProgress(name=spec.name, cells_total=len(per_cell), cells_done=sum(c.done for c in per_cell),
                         runs_total=sum(c.runs_total for c in per_cell), runs_done=sum(c.runs_done for c in per_cell),
                         complete=is_complete(out, spec), cells=per_cell)
