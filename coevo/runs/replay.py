"""``coevo replay RUN_DIR``: re-run a finished asynchronous run in one process, exactly.

Each worker's GA is deterministic given its seed and the partner policies it
evaluated against; the only non-repeatable thing in a run is *when* partner
versions arrived.  The adoption log records that (after how many of its own
generations a worker took which version), and the store holds every version, so
replaying feeds each GA the same partners at the same points and must reproduce
its learning curve bit for bit.  A kind of learner with its own curve or its own modules
says how to play them again (:mod:`coevo.runs.kinds`): a CEL learner from its
``changes.jsonl`` (after how many generations it took which capability list, and the cases
it restarted from), a CEL run's execution module from its ``policies.jsonl`` (which rule set
from which trial; its world is its own seed's), in :mod:`coevo.cel_service.audit`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from coevo.agents.models import PartnerModels, hall_settings
from coevo.config import HALL_SAMPLE, HALL_SHARE, GAConfig, build
from coevo.errors import RunDirError
from coevo.ga import GA
from coevo.policy.rules import RuleSet
from coevo.rundir.layout import RunPaths, WorkerPaths, by_generation, read_jsonl, read_store
from coevo.rundir.machine import differences
from coevo.rundir.records import AdoptionLine, CurveLine
from coevo.runs.kinds import kind_of_worker, run_kinds
from coevo.tasks import DEFAULT_TASK, Task, get_task
from coevo.tasks.base import check_behaviour

__all__ = ["WorkerReplay", "replay", "not_needed"]

_UNCOMPARED = ("seconds",)  # every other column of the learning curve must be identical


@dataclass(frozen=True)
class WorkerReplay:
    behaviour: str
    generations: int
    reproduced: bool
    first_mismatch: int | None  # 1-based generation (the execution module's: its generation, from 0)
    detail: str


def _store(run: RunPaths) -> dict[tuple[str, str, int], RuleSet]:
    return {(m.behaviour, m.worker, m.version): m.ruleset() for f in run.store_files() for m in read_store(f)}


#: Told each generation a replay reproduced: (behaviour, generations done, of how many).
Progress = Callable[[str, int, int], None]


def replay_worker(wdir: Path, store: dict[tuple[str, str, int], RuleSet], *, until: int | None = None,
                  progress: Progress | None = None) -> WorkerReplay:
    w = WorkerPaths(Path(wdir))
    meta = w.meta()
    task = get_task(meta.get("task", DEFAULT_TASK))
    behaviour = check_behaviour(task, meta["behaviour"])
    world = build(task.world_settings, meta["world"])
    ga_cfg = build(GAConfig, meta["ga"])
    curve = read_jsonl(w.curve, schema=CurveLine)
    n = len(curve) if until is None else min(until, len(curve))
    kind = kind_of_worker(meta)
    rows = (kind.curve(w, meta, world, ga_cfg) if kind.curve is not None
            else _rows(w, task, behaviour, meta, world, ga_cfg, store))
    for g in range(n):
        rep = next(rows)
        for k in sorted(set(rep) | set(curve[g])):
            if k not in _UNCOMPARED and rep.get(k) != curve[g].get(k):
                return WorkerReplay(behaviour, n, False, g + 1, f"{k}: recorded {curve[g].get(k)!r}, replayed {rep.get(k)!r}")
        if progress is not None:
            progress(behaviour, g + 1, n)
    return WorkerReplay(behaviour, n, True, None, "identical")


def _rows(w: WorkerPaths, task: Task, behaviour: str, meta: dict[str, Any], world: BaseModel, ga_cfg: GAConfig,
          store: dict[tuple[str, str, int], RuleSet]) -> Iterator[dict[str, Any]]:
    """A co-evolution worker's curve, again: its GA fed the partner versions it adopted, when it adopted them."""
    models = PartnerModels(task, behaviour, meta["regime"], meta["seed"], kind=meta["model"], ga=ga_cfg, world=world,
                           **hall_settings(meta["model"], meta.get("hall_sample", HALL_SAMPLE),
                                           meta.get("hall_share", HALL_SHARE)))
    ga = GA(task, behaviour, world=world, ga=ga_cfg, seed=meta["seed"])
    by_gen = by_generation(read_jsonl(w.adoptions, schema=AdoptionLine))
    g = 0
    while True:
        for a in by_gen.get(g, []):
            key = (a["partner"], a["from_worker"], a["version"])
            if a.get("rules") is not None:
                rules = RuleSet.from_dict(a["rules"])
            elif key in store:
                rules = store[key]
            else:
                raise RunDirError(f"{w.dir.name}: adopted {key} is neither in the log nor in the store; the run directory is incomplete")
            models.adopt(a["partner"], a["version"], rules)
        yield ga.generation(models.partners(), mixture=models.mixture(ga.cfg.episodes)).as_dict()
        g += 1


def _with_machine(r: WorkerReplay, w: WorkerPaths) -> WorkerReplay:
    """A replay that differs, with what differs between the machines the worker ran on and this one."""
    if r.reproduced:
        return r
    recorded = [m for m in read_jsonl(w.machines, missing_ok=True, problems=[]) if isinstance(m, dict)]
    diffs = sorted({d for m in recorded for d in differences(m)})
    note = ("; the run recorded no machine (it predates machines.jsonl)" if not recorded
            else "; recorded on a machine that differs from this one in: " + "; ".join(diffs) + " (none of which should "
            "change a number: docs/development.md, 'What is exact where')" if diffs
            else "; recorded on a machine like this one (the same versions, BLAS kernel, SIMD code and processor)")
    return replace(r, detail=r.detail + note)


def replay(run_dir: Path, *, progress: Progress | None = None) -> list[WorkerReplay]:
    """Each worker's curve replayed (``progress`` told each generation), then each kind's own replay."""
    run = RunPaths(Path(run_dir))
    workers = run.workers()
    store = _store(run)
    out = [_with_machine(replay_worker(w.dir, store, progress=progress), w) for w in workers]
    for kind in run_kinds(run):
        if kind.replay_run is None:
            continue
        what, n, first, detail = kind.replay_run(run)
        out.append(WorkerReplay(what, n, first is None, first, detail))
    return out


def not_needed(run_dir: Path) -> list[str]:
    """The run's files that :func:`replay` does not read (paths relative to the run, a worker's as
    ``workers/*/NAME``), of those that exist: a replay vouches for none of them (``coevo check`` reads them all)."""
    run = RunPaths(Path(run_dir))
    files = [run.run_json, run.summary, run.measures, run.curves_csv]
    out = [f.name for f in files if f.exists()]
    for name in ("published", "checkpoint", "done", "best_rules"):
        if any(getattr(w, name).exists() for w in run.workers()):
            out.append(f"workers/*/{getattr(run.workers()[0], name).name}")
    return out
