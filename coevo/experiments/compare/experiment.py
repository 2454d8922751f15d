"""A regime comparison: N real asynchronous runs per regime, resumable.

Every replicate is a whole ``coevo run`` (its own broker and three worker
processes on a free port, its own run id and directory under ``OUT/runs/``), so
what is compared is exactly what a user gets.  Replicate ``i`` of every regime
uses the same seed (a paired design: the regimes differ in their agents'
interactions, not in their random initial populations).

The report's second protocol of Regime Independent is the pseudo-regime
``independent-offline``: "because the tasks were independent of each other and
subordinate to the Executive Task, they could be first learned offline which
would allow us to simulate various rates of asynchrony during the learning of the
Executive Task".  Tracking and Docking learn exactly as in live Independent (with
the trivial Executive, the Executive's choices never reach them), so replicate
``i`` reuses the Tracking and Docking histories stored by the live
``independent-i`` run and, for each rate in ``rates``, an Executive learns on
them with ``coevo learn --history RUN --rate R`` (rate = partner generations per
Executive generation), with the live Executive's seed: the rate is the only
difference between them.

Resuming: ``OUT/compare.json`` holds the comparison's settings; a finished run
has ``summary.json`` with its measures.  ``--resume`` keeps the finished runs,
continues the half-done ones from their workers' checkpoints (``coevo run
--resume``: each worker goes on from its last finished generation, the store
reloads from disk), starts afresh any that did not get as far as its
``run.json``, and runs the rest.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, SerializeAsAny, ValidationInfo, field_validator, model_validator

from coevo.config import DEFAULT_MAX_LEAD, MODELS, GAConfig, build
from coevo.errors import CoevoError, ConfigError, RunDirError
from coevo.replicates.backends import Backend
from coevo.replicates.replicate import Replicate as Job
from coevo.replicates.runner import Progress, run_replicates
from coevo.rundir.code import record_code, refuse_other_code
from coevo.rundir.layout import LearnPaths, RunPaths, ensure_dir, read_json, read_jsonl, write_json
from coevo.rundir.settings import RunSettings
from coevo.tasks import DEFAULT_TASK, get_task, saved_settings, split_settings
from coevo.tasks.base import Task, check_ga

__all__ = ["CompareSpec", "offline_learner", "Replicate", "held_spec", "prepare", "problems", "replicates", "groups", "run_all", "jobs_of", "default_jobs", "OFFLINE",
           "DEFAULT_RATES"]

log = logging.getLogger(__name__)

SEED_STRIDE = 1000  # replicate i runs with seed + i * SEED_STRIDE (workers take seed, seed+1, seed+2)
OFFLINE = "independent-offline"  # the Executive learning on recorded Tracking/Docking histories, per rate
DEFAULT_RATES = (0.25, 0.5, 1.0, 2.0, 4.0)  # (ours) partner generations per Executive generation: 16x apart


def _settings_now(spec: Any) -> Any:
    """A comparison's settings (compare.json's spec, or values given) with GA values that are now world settings
    moved to the world (:func:`coevo.tasks.split_settings`: GA settings of comparisons saved before a task moved
    them), and the world read as its task's settings (checked there, once, naming a bad value: ``world settings of
    the fuel task: arena='big': ...``)."""
    if not isinstance(spec, dict) or not isinstance(spec.get("task", DEFAULT_TASK), str):
        return spec
    task = get_task(spec.get("task", DEFAULT_TASK))
    world, ga = spec.get("world", {}), spec.get("ga", {})
    if isinstance(world, BaseModel):
        world = world.model_dump(mode="json")
    if isinstance(world, dict) and isinstance(ga, dict):
        world, ga = split_settings(task, world, ga)
        spec = {**spec, "ga": ga}
    if isinstance(world, dict):
        world = build(task.world_settings, world, what=f"world settings of the {task.name} task")
    return {**spec, "world": world}


def offline_learner(task: Task[Any]) -> str | None:
    """The behaviour of ``task`` that learns offline on an independent run's recorded partner histories (``coevo
    learn --history``, the pseudo-regime :data:`OFFLINE`), or None: the task has none."""
    return task.offline_learner


class CompareSpec(BaseModel):
    """Everything that makes two comparisons the same comparison."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    task: str = DEFAULT_TASK
    regimes: tuple[str, ...] = ("mutual", "independent")
    rates: tuple[float, ...] = Field(DEFAULT_RATES, description="rates of asynchrony for independent-offline")
    runs: int = Field(10, ge=1, le=1000, description="replicates per regime")
    seed: int = 0
    model: str = "best"
    max_lead: int | None = DEFAULT_MAX_LEAD
    measure_epochs: int = Field(100, ge=1, le=100_000)
    world: SerializeAsAny[BaseModel] = Field(default=None, validate_default=False)  # type: ignore[assignment]
    ga: GAConfig = GAConfig()

    @field_validator("task")
    @classmethod
    def _task(cls, v: str) -> str:
        try:
            return get_task(v).name
        except ConfigError as exc:
            raise ValueError(str(exc)) from None

    @field_validator("regimes")
    @classmethod
    def _regimes(cls, v: tuple[str, ...], info: ValidationInfo) -> tuple[str, ...]:
        if "task" not in info.data:
            return v  # the task itself is refused
        task = get_task(info.data["task"])
        # an offline learner's report is its task's own reading (the generic one reads the live regimes)
        known = (*task.regimes, OFFLINE) if offline_learner(task) and task.comparison else task.regimes
        if not v:
            raise ValueError("name at least one regime")
        for r in v:
            if r not in known:
                raise ValueError(f"unknown regime {r!r} of the {task.name} task (use {', '.join(known)})")
        if len(set(v)) != len(v):
            raise ValueError(f"regimes repeat: {list(v)}")
        if OFFLINE in v and "independent" not in v:
            raise ValueError(f"{OFFLINE} learns on the partner histories of the independent runs: "
                             "add independent to the regimes")
        return v

    @model_validator(mode="before")
    @classmethod
    def _moved(cls, data: Any) -> Any:
        """The world read as the task's settings; a comparison saved before a task moved GA settings to its world
        reads as it ran."""
        return _settings_now(data)

    @field_validator("ga")
    @classmethod
    def _ga(cls, v: GAConfig, info: ValidationInfo) -> GAConfig:
        if "task" not in info.data:
            return v
        try:
            return check_ga(get_task(info.data["task"]), v)  # before OUT is written to
        except ConfigError as exc:
            raise ValueError(str(exc)) from None

    @property
    def the_task(self) -> Task[Any]:
        return get_task(self.task)

    @field_validator("rates")
    @classmethod
    def _rates(cls, v: tuple[float, ...]) -> tuple[float, ...]:
        if not v:
            raise ValueError("name at least one rate of asynchrony")
        for r in v:
            if not (r > 0 and r < 1e6):  # also refuses NaN
                raise ValueError(f"a rate of asynchrony must be positive and finite, got {r}")
        if len(set(v)) != len(v):
            raise ValueError(f"rates repeat: {list(v)}")
        return tuple(sorted(v))

    @field_validator("model")
    @classmethod
    def _model(cls, v: str) -> str:
        if v not in MODELS:
            raise ValueError(f"unknown partner model {v!r} (use {', '.join(MODELS)})")
        return v

    @field_validator("max_lead")
    @classmethod
    def _lead(cls, v: int | None) -> int | None:
        if v is not None and v < 0:
            raise ValueError(f"max_lead must be 0 or more (or None for unpaced), got {v}")
        return v

    @classmethod
    def make(cls, **values: Any) -> CompareSpec:
        return build(cls, values, what="comparison settings")

    @classmethod
    def saved(cls, data: Any) -> CompareSpec:
        """A comparison's settings as its compare.json saved them, read as it ran: every setting added since filled
        in with its value from before (:func:`coevo.tasks.saved_settings`), the rest with its default.  Raises
        ConfigError, in one line naming the bad value, for what is not a comparison's settings."""
        if not isinstance(data, dict):
            raise ConfigError(f"saved comparison settings: a JSON object expected, got {type(data).__name__}")
        return build(cls, saved_settings(data), what="saved comparison settings")


@dataclass(frozen=True)
class Replicate:
    regime: str
    index: int
    seed: int
    rate: float | None = None  # independent-offline only

    @property
    def offline(self) -> bool:
        return self.regime == OFFLINE

    @property
    def group(self) -> str:
        """What the report compares: the regime, or for independent-offline the regime at its rate."""
        return f"{OFFLINE} rate {self.rate:g}" if self.offline else self.regime

    @property
    def run_id(self) -> str:
        if self.offline:
            return f"offline-rate{self.rate:g}-{self.index:02d}"
        return f"{self.regime}-{self.index:02d}"

    @property
    def depends_on(self) -> Replicate | None:
        """The live run whose stored Tracking/Docking histories this one learns on."""
        return Replicate("independent", self.index, self.seed) if self.offline else None


def replicates(spec: CompareSpec) -> list[Replicate]:
    """Interleaved (mutual-00, independent-00, mutual-01, ...) so a partial comparison is balanced;
    each independent-offline replicate comes after the live run it learns on."""
    out = []
    for i in range(spec.runs):
        seed = spec.seed + i * SEED_STRIDE
        out += [Replicate(r, i, seed) for r in spec.regimes if r != OFFLINE]
        if OFFLINE in spec.regimes:
            out += [Replicate(OFFLINE, i, seed, rate) for rate in spec.rates]
    return out


def groups(spec: CompareSpec) -> list[str]:
    """The report's rows, in order: the live regimes, then independent-offline at each rate."""
    out = [r for r in spec.regimes if r != OFFLINE]
    if OFFLINE in spec.regimes:
        out += [Replicate(OFFLINE, 0, 0, rate).group for rate in spec.rates]
    return out


def run_dir(out: Path, rep: Replicate) -> Path:
    return Path(out) / "runs" / rep.run_id


def is_finished(out: Path, rep: Replicate) -> bool:
    if rep.offline:  # coevo learn writes its directory under a temporary name and renames it when complete
        return LearnPaths(run_dir(out, rep)).measures.exists()
    f = RunPaths(run_dir(out, rep)).summary
    if not f.exists():
        return False
    try:  # a run stopped early (Ctrl-C, SIGTERM) has its measures too, and is not finished: resumed
        summary = json.loads(f.read_text(encoding="utf-8"))
        return "measures" in summary and not summary.get("interrupted", False)
    except (OSError, ValueError, TypeError, AttributeError):  # unreadable, not UTF-8, not JSON, not an object
        return False


def _spec_json(spec: CompareSpec) -> dict[str, Any]:
    return json.loads(spec.model_dump_json())


def held_spec(out: Path) -> CompareSpec | None:
    """The settings of the comparison in ``out`` (its compare.json; None: it holds none), read as it ran; a
    RunDirError naming compare.json when it cannot be read (not UTF-8, not JSON, a directory, not a comparison's)."""
    marker = Path(out) / "compare.json"
    if not (marker.exists() or marker.is_symlink()):
        return None
    try:
        return CompareSpec.saved(read_json(marker, what="comparison (its compare.json)")["spec"])
    except (KeyError, ConfigError) as exc:
        why = "it names no spec" if isinstance(exc, KeyError) else str(exc)
        raise RunDirError(f"{str(marker)!r} cannot be read: {why}; choose another --out") from None
    except RunDirError as exc:
        raise RunDirError(f"{exc}; choose another --out") from None


def prepare(out: Path, spec: CompareSpec, *, resume: bool, report_only: bool = False,
            force: bool = False) -> list[Replicate]:
    """Check OUT before anything starts; returns the replicates still to run.

    A fresh comparison needs an empty or missing OUT.  ``resume`` needs OUT to
    hold this very comparison (same settings) and, unless ``force``, made by this code (``code.json``); anything
    else is refused with a message naming what differs.  Every file of OUT that the comparison (``report_only``:
    its report) will read is read first (:func:`problems`): a problem is a RunDirError naming it, and OUT is left
    as it was.
    """
    out = Path(out)
    marker = out / "compare.json"
    if out.exists() and not out.is_dir():
        raise RunDirError(f"--out {str(out)!r} is a file, not a directory")
    if out.exists() and any(out.iterdir()):
        held_spec_ = held_spec(out)
        if held_spec_ is None:
            raise RunDirError(f"--out {str(out)!r} is not empty and holds no comparison (no compare.json); choose another --out")
        held, mine = _spec_json(held_spec_), _spec_json(spec)
        if held != mine:
            diff = sorted(k for k in set(held) | set(mine) if held.get(k) != mine.get(k))
            raise RunDirError(
                f"--out {str(out)!r} holds a different comparison (differs in: {', '.join(diff)}); "
                "choose another --out, or leave its settings out: --resume and --report-only take its own")
        if not resume:
            raise RunDirError(f"--out {str(out)!r} already holds this comparison; add --resume to continue it")
        found = problems(out, spec, report_only=report_only)
        if found:
            more = f" ({len(found) - 1} more problems)" if len(found) > 1 else ""
            raise RunDirError(f"cannot {'report on' if report_only else 'resume'} the comparison in {out}: {found[0]}; "
                              f"nothing was started or changed{more}")
        if not report_only:
            refuse_other_code(out, force=force, what="runs")
    else:
        ensure_dir(out, what="--out")
        write_json(marker, {"spec": _spec_json(spec), "created": time.time()})
    if not report_only:
        record_code(out)
    todo = []
    for rep in replicates(spec):
        if is_finished(out, rep):
            continue
        d = run_dir(out, rep)
        if not report_only and not rep.offline and d.exists() and not RunPaths(d).run_json.exists():
            log.info("removing the run %s, which stopped before it began, to run it again", d)
            shutil.rmtree(d)
        todo.append(rep)
    return todo


#: What a live run writes before its run.json (:meth:`coevo.runs.local.LocalRun.create`): a folder holding only
#: these stopped before it began, and is started again.
_BEFORE_RUN_JSON = {RunPaths.KEY_FILE}


def problems(out: Path, spec: CompareSpec, *, report_only: bool = False) -> list[str]:
    """What would stop the comparison in ``out`` from going on (``report_only``: from being reported), one line a
    problem, found by reading every file of its replicates that it will read and changing nothing: a finished
    run's summary.json, curves and final Docking rules, a finished offline Executive's measures, curve and timing
    (the report's), and each half-done run's files as ``coevo run --resume`` reads them."""
    from coevo.runs.local import LocalRun

    found: list[str] = []
    for rep in replicates(spec):
        d = run_dir(Path(out), rep)
        if not (d.exists() or d.is_symlink()):
            continue
        if not d.is_dir():
            found.append(f"{d} is not a directory")
            continue
        if rep.offline:
            paths = LearnPaths(d)
            if paths.measures.exists() or paths.measures.is_symlink():
                found += _json_problems([paths.measures, paths.curve_json, paths.timing])
            continue
        run = RunPaths(d)
        if run.summary.exists() or run.summary.is_symlink():
            try:
                summary = read_json(run.summary, what="run directory (its summary.json)")
            except RunDirError as exc:
                found.append(str(exc))
                continue
            if "measures" in summary:  # finished: what the report reads of it
                found += _finished_problems(run, spec)
                continue
        if report_only:
            continue  # an unfinished run is not reported on
        if not (run.run_json.exists() or run.run_json.is_symlink()):
            extra = sorted(p.name for p in d.iterdir() if p.name not in _BEFORE_RUN_JSON)
            if extra:
                found.append(f"{str(run.run_json)!r} is missing, but {d} holds {', '.join(extra)}: not a run that "
                             "stopped before it began; move it aside to run it again")
            continue
        try:
            found += LocalRun.resumable(d).problems()
        except CoevoError as exc:
            found.append(str(exc))
    return found


def _finished_problems(run: RunPaths, spec: CompareSpec) -> list[str]:
    """What is wrong with the files the report reads of a finished live run: its curves and the final rules its
    task's reading reads (the fuel task's: Docking's)."""
    from coevo.experiments.compare.reading import reading_of
    from coevo.policy.text import read_rule_file
    from coevo.rundir.records import CurveLine

    found: list[str] = []
    for b in spec.the_task.behaviours:
        read_jsonl(run.worker(b).curve, schema=CurveLine, problems=found)
    for b in reading_of(spec.the_task).rules_read:
        try:  # a finished worker wrote its best after its first generation
            read_rule_file(run.worker(b).best_rules, b)
        except CoevoError as exc:
            found.append(str(exc))
    return found


def _json_problems(files: list[Path]) -> list[str]:
    """What is wrong with JSON files a report reads (missing, unreadable, not JSON)."""
    found = []
    for f in files:
        try:
            json.loads(f.read_text(encoding="utf-8"))
        except FileNotFoundError:
            found.append(f"{str(f)!r} is missing")
        except (OSError, ValueError, RecursionError) as exc:
            found.append(f"{str(f)!r} cannot be read: {exc}")
    return found


def default_jobs() -> int:
    """Runs at once: a run keeps about two cores busy (three workers, paced), so one per two cores."""
    return max(1, (os.cpu_count() or 1) // 2)


def weight(rep: Replicate) -> int:
    """Half-jobs a replicate takes: a live run keeps about two cores busy, an offline Executive one, so one
    ``--jobs`` slot holds one live run or two offline Executives."""
    return 1 if rep.offline else 2


def _settings_file(out: Path, spec: CompareSpec, rep: Replicate) -> Path:
    """The replicate's settings, written once for the process that runs it (its run.json-to-be)."""
    regime = "independent" if rep.offline else rep.regime
    settings = RunSettings.make(task=spec.task, run=rep.run_id, regime=regime, seed=rep.seed, model=spec.model,
                                max_lead=spec.max_lead, world=spec.world.model_dump(mode="json"), ga=spec.ga)
    f = Path(out) / "settings" / f"{rep.run_id}.json"
    f.parent.mkdir(parents=True, exist_ok=True)
    settings.save(f)
    return f


def _run_command(spec_json: dict[str, Any], rep: Replicate, root: Path) -> list[str]:
    """The command that runs ``rep`` under ``root`` (the comparison's folder where the replicate runs: here, a
    shared directory or a Dask worker's temporary copy), decided there: a live run that got as far as its
    ``run.json`` continues from its workers' checkpoints (``coevo run --resume``), one that stopped before is
    started afresh."""
    root = Path(root)
    d = run_dir(root, rep)
    settings = root / "settings" / f"{rep.run_id}.json"
    epochs = str(spec_json["measure_epochs"])
    if rep.offline:  # the Executive learns with the seed it has in a live run (seed + its index)
        if rep.depends_on is None:
            raise TypeError(f"offline replicate {rep.run_id} names no live run to learn on the history of")
        return [sys.executable, "-m", "coevo", "learn", "--quiet", "--behaviour", str(spec_json["offline_learner"]),
                "--settings", str(settings), "--history", str(run_dir(root, rep.depends_on)),
                "--rate", repr(rep.rate), "--out", str(d), "--measure-epochs", epochs]
    if RunPaths(d).run_json.exists():  # interrupted: continue it from the workers' checkpoints
        return [sys.executable, "-m", "coevo", "run", "--quiet", "--resume", str(d), "--measure-epochs", epochs,
                "--force"]  # the comparison's own code.json was checked (prepare)
    if d.exists():
        shutil.rmtree(d)  # stopped before it began: run it again
    return [sys.executable, "-m", "coevo", "run", "--quiet", "--settings", str(settings), "--root", str(root / "runs"),
            "--measure-epochs", epochs]


def generations_of(spec: CompareSpec, rep: Replicate) -> int:
    """Worker generations a replicate runs: three workers, or one Executive learning offline."""
    return spec.ga.generations * (1 if rep.offline else len(spec.the_task.behaviours))


def generations_done(out: Path, rep: Replicate, behaviours: tuple[str, ...]) -> int:
    """Worker generations finished so far in a replicate (for progress), read from the curve logs
    (an offline Executive shows its generations only when it is done)."""
    if rep.offline:
        return 0
    n = 0
    for b in behaviours:
        f = RunPaths(run_dir(out, rep)).worker(b).curve
        try:
            with open(f, "rb") as fh:
                n += sum(1 for _ in fh)
        except OSError:
            continue  # that worker has not started its curve yet: no generations done
    return n


def _finished_under(rep: Replicate, root: Path) -> bool:
    return is_finished(Path(root), rep)


def _done_under(rep: Replicate, behaviours: tuple[str, ...], root: Path) -> int:
    return generations_done(Path(root), rep, behaviours)


def jobs_of(out: Path, spec: CompareSpec) -> list[Job]:
    """The comparison as replicates for :mod:`coevo.replicates`: each a ``coevo run`` (or, for
    independent-offline, a ``coevo learn`` after the live run it learns on), its settings written here first
    so that they are the same whichever backend runs it."""
    spec_json = {**_spec_json(spec), "offline_learner": offline_learner(spec.the_task)}
    jobs = []
    for rep in replicates(spec):
        settings = f"settings/{rep.run_id}.json"
        if not is_finished(out, rep):
            _settings_file(out, spec, rep)
        dep = rep.depends_on
        jobs.append(Job(
            name=rep.run_id, output=f"runs/{rep.run_id}", finished=partial(_finished_under, rep),
            command=partial(_run_command, spec_json, rep), progress=partial(_done_under, rep, spec.the_task.behaviours),
            inputs=(settings,) + ((f"runs/{dep.run_id}",) if dep is not None else ()),
            after=(dep.run_id,) if dep is not None else (), weight=weight(rep), cost=generations_of(spec, rep)))
    return jobs


def run_all(
    out: Path,
    spec: CompareSpec,
    todo: list[Replicate],
    *,
    backend: Backend,
    on_progress: Callable[[Progress], None] | None = None,
    poll: float = 1.0,
) -> Progress:
    """Run the comparison's unfinished replicates (``todo``, from :func:`prepare`) on ``backend``; the returned
    :class:`~coevo.replicates.runner.Progress` says which failed and why (their logs are in ``OUT/logs``)."""
    wanted = {r.run_id for r in todo}
    jobs = [j for j in jobs_of(Path(out), spec)]
    unknown = wanted - {j.name for j in jobs}
    if unknown:
        raise ConfigError(f"not replicates of this comparison: {sorted(unknown)}")
    return run_replicates(jobs, Path(out), backend, on_progress=on_progress, poll=poll)
