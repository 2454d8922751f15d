"""A study's folder, its replicates on the runner, resuming it, marking it complete, and its progress as data.

The folder (``--out``)::

    study.json          the declaration (StudySpec) and its cells, written first; --resume checks it
    cells/CELL/         one ``coevo compare`` folder per cell (compare.json, settings/, runs/): every cell's
                        replicates are exactly the comparison's, so ``coevo compare --report-only --out
                        cells/CELL`` writes a cell's full comparison report; in a study of learning runs
                        (``learn``), the cell's settings (learn.json) and one ``coevo learn`` folder per seed
                        (runs/BEHAVIOUR-seedN, as ``coevo seeds`` lays them out)
    logs/CELL@RUN.log   each replicate's log (the runner's)
    report.md, results.json, effect-FACTOR.png, cells.png    the study's report (:mod:`.report`)
    complete.json       written last, atomically, when every run finished and the report is written

``complete.json`` names the declaration it completes (a digest of study.json's spec) and how many runs it holds; a
folder without it, or whose marker names another declaration, is a study in progress, whatever else it holds.
Any run of ``coevo study`` on a folder removes the marker before it starts anything.

All cells' replicates go to one :func:`~coevo.replicates.runner.run_replicates`, interleaved by replicate index
(run 0 of every cell, then run 1, ...), so ``--jobs`` and ``--cluster`` are shared by the whole study and a study
cut short is balanced across its cells.  A learning-run cell's replicates are ``coevo seeds``' own
(:func:`coevo.experiments.seeds.experiment.replicates`): ``coevo learn`` writes its folder under a temporary name and
renames it when done, so a run is finished only with its measures.json and timing.json there.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from coevo.errors import RunDirError
from coevo.experiments.compare.experiment import held_spec, is_finished, jobs_of, prepare, problems, replicates
from coevo.experiments.seeds.experiment import replicates as learn_replicates
from coevo.experiments.study.declaration import Cell, LearnCell, StudySpec, study_cells
from coevo.replicates.backends import Backend
from coevo.replicates.replicate import Replicate as Job
from coevo.replicates.runner import Progress, run_replicates
from coevo.rundir.code import code_difference
from coevo.rundir.layout import ensure_dir, write_json

__all__ = ["MARKER", "COMPLETE", "SEP", "prepare_study", "study_jobs", "run_study", "held_declaration", "mark_complete",
           "is_complete", "StudyProgress", "CellProgress", "study_progress", "cell_dir", "learn_jobs", "LEARN_MARKER"]

MARKER = "study.json"
COMPLETE = "complete.json"
#: Between a cell and a run in a replicate's name (``CELL@RUN``, its log ``logs/CELL@RUN.log``): a character no cell
#: id or run id holds, and no "/", since the name also prefixes a Dask worker's temporary folder.
SEP = "@"
#: A learning-run cell's settings, in its folder (as compare.json is a comparison cell's).
LEARN_MARKER = "learn.json"


def cell_dir(out: Path, cell: Cell | LearnCell) -> Path:
    return Path(out) / "cells" / cell.id


def learn_jobs(cell: LearnCell) -> list[Job]:
    """A learning-run cell's runs as ``coevo seeds`` makes them, one ``coevo learn`` per seed, relative to the cell's
    folder (``runs/BEHAVIOUR-seedN``)."""
    return learn_replicates([cell.spec.behaviour], cell.spec.seeds, list(cell.args))


def _prepare_learn_cell(folder: Path, cell: LearnCell) -> None:
    """Write the cell's learn.json, or check the one there is this cell's."""
    mine = {"spec": json.loads(cell.spec.model_dump_json()), "args": list(cell.args)}
    f = folder / LEARN_MARKER
    if f.exists():
        _held_learn(f, cell)
        return
    ensure_dir(folder, what="a cell's folder")
    write_json(f, {**mine, "created": time.time()})


def check_cells(out: Path, the_cells: Sequence[Cell | LearnCell], *, report_only: bool = False,
                force: bool = False) -> None:
    """Read every file of the study's cells that its resume (``report_only``: its report) reads, changing nothing:
    each comparison cell's compare.json and replicates (:func:`coevo.experiments.compare.experiment.problems`) and,
    for a resume not ``force``d, that this code ran it (its code.json), each learning cell's learn.json.  A problem
    is a RunDirError naming the first, and the folder is left as it was."""
    found: list[str] = []
    for c in the_cells:
        folder = cell_dir(out, c)
        if not (folder.exists() or folder.is_symlink()):
            continue
        if not folder.is_dir():
            found.append(f"{folder} is not a directory")
            continue
        try:
            if isinstance(c, LearnCell):
                if (folder / LEARN_MARKER).exists() or (folder / LEARN_MARKER).is_symlink():
                    _held_learn(folder / LEARN_MARKER, c)
                continue
            held = held_spec(folder)
        except RunDirError as exc:
            found.append(str(exc))
            continue
        if held is None:
            if any(folder.iterdir()):
                found.append(f"{folder / 'compare.json'} is missing, but {folder} holds files: not a cell of this study")
        elif held != c.spec:
            found.append(f"{folder / 'compare.json'} holds another cell's settings")
        else:
            found += problems(folder, c.spec, report_only=report_only)
            differs = "" if report_only or force else code_difference(folder)
            if differs:
                found.append(f"{folder}: {differs} (add --force to continue it anyway)")
    if found:
        more = f" ({len(found) - 1} more problems)" if len(found) > 1 else ""
        raise RunDirError(f"cannot {'report on' if report_only else 'resume'} the study in {out}: {found[0]}; nothing "
                          f"was started or changed{more}")


def _held_learn(f: Path, cell: LearnCell) -> None:
    """That the learn.json ``f`` is ``cell``'s; a RunDirError naming it if it cannot be read or is another's."""
    mine = {"spec": json.loads(cell.spec.model_dump_json()), "args": list(cell.args)}
    try:
        held = json.loads(f.read_text(encoding="utf-8"))
        same = {k: held[k] for k in mine} == mine
    except (OSError, ValueError, KeyError, TypeError, RecursionError) as exc:
        raise RunDirError(f"{f} cannot be read ({exc}); choose another --out") from None
    if not same:
        raise RunDirError(f"{f} holds another cell's settings; choose another --out")


def _digest(spec: StudySpec) -> str:
    return hashlib.sha256(json.dumps(spec.as_dict(), sort_keys=True).encode()).hexdigest()


def held_declaration(out: Path) -> StudySpec | None:
    """The declaration in ``out/study.json`` (None: there is none); a RunDirError naming ``--out`` if unreadable."""
    f = Path(out) / MARKER
    if not f.exists():
        return None
    try:
        return StudySpec.from_dict(json.loads(f.read_text(encoding="utf-8"))["spec"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError, RecursionError) as exc:
        raise RunDirError(f"--out {str(out)!r}: {MARKER} cannot be read ({exc}); choose another --out") from exc


def _differences(held: StudySpec, mine: StudySpec) -> list[str]:
    a, b = held.as_dict(), mine.as_dict()
    diff = [k for k in ("name", "seed", "description") if a[k] != b[k]]
    la, lb = dict(a["levels"]), dict(b["levels"])
    diff += [k for k in dict.fromkeys([*la, *lb]) if la.get(k) != lb.get(k)]
    if not diff and list(la) != list(lb):
        diff.append("the order of the factors")
    return diff


def prepare_study(out: Path, spec: StudySpec, *, resume: bool, force: bool = False) -> list[Cell] | list[LearnCell]:
    """Check ``out`` and set it up: a fresh study needs an empty or missing folder; ``resume`` needs this very study
    there, its cells run by this code unless ``force`` (else a RunDirError naming what differs).  Removes the completion marker, writes study.json (fresh) and
    every cell's compare.json (learn.json); returns the cells."""
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
    the_cells = study_cells(spec)
    if resume:
        check_cells(out, the_cells, force=force)  # before anything is changed
    ensure_dir(out, what="--out")
    (out / COMPLETE).unlink(missing_ok=True)  # from here on the folder is a study in progress
    if held is None:
        write_json(out / MARKER, {"spec": spec.as_dict(), "created": time.time(),
                                  "cells": [{"id": c.id, "levels": dict(c.levels), "seed": c.spec.seed}
                                            for c in the_cells]})
    for c in the_cells:
        if isinstance(c, LearnCell):
            _prepare_learn_cell(cell_dir(out, c), c)
        else:
            prepare(cell_dir(out, c), c.spec, resume=True, force=True)  # makes its compare.json, or checks the one
            # there (its code.json was checked above, with the rest)
    return the_cells


def _in_cell(cell: str, fn: Callable[[Path], Any], root: Path) -> Any:
    """A comparison's replicate function, called on its cell's folder under the study's ``root``."""
    return fn(Path(root) / "cells" / cell)


def _in_study(cell: str, job: Job) -> Job:
    """A cell's replicate (relative to the cell's folder) as the study's: named ``CELL@RUN``, pointed at
    ``cells/CELL``."""
    pre = f"cells/{cell}/"
    return Job(name=f"{cell}{SEP}{job.name}", output=pre + job.output, finished=partial(_in_cell, cell, job.finished),
               command=None if job.command is None else partial(_in_cell, cell, job.command),
               function=job.function, kwargs=job.kwargs, inputs=tuple(pre + i for i in job.inputs),
               after=tuple(f"{cell}{SEP}{a}" for a in job.after), weight=job.weight, cost=job.cost,
               progress=None if job.progress is None else partial(_in_cell, cell, job.progress))


def study_jobs(out: Path, the_cells: Sequence[Cell | LearnCell]) -> list[Job]:
    """Every cell's replicates, renamed ``CELL@RUN`` and pointed at ``cells/CELL``, interleaved by replicate index:
    a comparison cell's (:func:`~coevo.experiments.compare.experiment.jobs_of`), a learning-run cell's
    (:func:`learn_jobs`, run *i* of the cell's seeds at index *i*)."""
    keyed: list[tuple[int, int, int, Job]] = []
    for ci, c in enumerate(the_cells):
        if isinstance(c, LearnCell):
            for i, job in enumerate(learn_jobs(c)):
                keyed.append((i, ci, 0, _in_study(c.id, job)))
            continue
        for k, (rep, job) in enumerate(zip(replicates(c.spec), jobs_of(cell_dir(out, c), c.spec), strict=True)):
            keyed.append((rep.index, ci, k, _in_study(c.id, job)))
    return [j for *_, j in sorted(keyed, key=lambda t: t[:3])]


def run_study(out: Path, the_cells: Sequence[Cell | LearnCell], *, backend: Backend,
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
    for c in study_cells(spec):
        if isinstance(c, LearnCell):
            jobs = learn_jobs(c)
            done = sum(1 for j in jobs if j.finished(cell_dir(out, c)))
            per_cell.append(CellProgress(c.id, dict(c.levels), done, len(jobs)))
            continue
        reps = replicates(c.spec)
        done = sum(1 for r in reps if is_finished(cell_dir(out, c), r))
        per_cell.append(CellProgress(c.id, dict(c.levels), done, len(reps)))
    return StudyProgress(name=spec.name, cells_total=len(per_cell), cells_done=sum(c.done for c in per_cell),
                         runs_total=sum(c.runs_total for c in per_cell), runs_done=sum(c.runs_done for c in per_cell),
                         complete=is_complete(out, spec), cells=per_cell)
