"""``coevo replay RUN_DIR``: re-run a finished asynchronous run in one process, exactly.

Each worker's GA is deterministic given its seed and the partner policies it
evaluated against; the only non-repeatable thing in a run is *when* partner
versions arrived.  The adoption log records that (after how many of its own
generations a worker took which version), and the store holds every version, so
replaying feeds each GA the same partners at the same points and must reproduce
its learning curve bit for bit.  A CEL learner (:mod:`coevo.cel_service.learner`) is replayed
the same way from its ``changes.jsonl``: after how many generations it took which
capability list, and the cases it restarted from; a CEL run's execution module from
its ``policies.jsonl`` (which rule set from which trial): its world is its own seed's.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from coevo.agents.models import PartnerModels
from coevo.cel.casebase import Case
from coevo.config import GAConfig, build
from coevo.errors import RunDirError
from coevo.ga import GA
from coevo.policy.rules import RuleSet
from coevo.rundir.layout import RunPaths, WorkerPaths, read_json, read_jsonl, read_store
from coevo.tasks import DEFAULT_TASK, Task, get_task

__all__ = ["WorkerReplay", "replay"]

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


def replay_worker(wdir: Path, store: dict[tuple[str, str, int], RuleSet], *, until: int | None = None) -> WorkerReplay:
    w = WorkerPaths(Path(wdir))
    meta = w.meta()
    task = get_task(meta.get("task", DEFAULT_TASK))
    behaviour = task.check_behaviour(meta["behaviour"])
    world = build(task.world_settings, meta["world"])
    ga_cfg = build(GAConfig, meta["ga"])
    curve = read_jsonl(w.curve)
    n = len(curve) if until is None else min(until, len(curve))
    if "cel" in meta:
        rows = _cel_rows(w, meta, world, ga_cfg)
    else:
        rows = _rows(w, task, behaviour, meta, world, ga_cfg, store)
    for g in range(n):
        rep = next(rows)
        for k in sorted(set(rep) | set(curve[g])):
            if k not in _UNCOMPARED and rep.get(k) != curve[g].get(k):
                return WorkerReplay(behaviour, n, False, g + 1, f"{k}: recorded {curve[g].get(k)!r}, replayed {rep.get(k)!r}")
    return WorkerReplay(behaviour, n, True, None, "identical")


def _by_generation(rows: list[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    out: dict[int, list[dict[str, Any]]] = {}
    for a in rows:
        out.setdefault(int(a["generation"]), []).append(a)
    return out


def _rows(w: WorkerPaths, task: Task, behaviour: str, meta: dict[str, Any], world: BaseModel, ga_cfg: GAConfig,
          store: dict[tuple[str, str, int], RuleSet]) -> Iterator[dict[str, Any]]:
    """A co-evolution worker's curve, again: its GA fed the partner versions it adopted, when it adopted them."""
    models = PartnerModels(task, behaviour, meta["regime"], meta["seed"], kind=meta["model"], ga=ga_cfg)
    ga = GA(task, behaviour, world=world, ga=ga_cfg, seed=meta["seed"])
    by_gen = _by_generation(read_jsonl(w.adoptions))
    g = 0
    while True:
        for a in by_gen.get(g, []):
            key = (a["partner"], a["from_worker"], int(a["version"]))
            if "rules" in a:
                rules = RuleSet.from_dict(a["rules"])
            elif key in store:
                rules = store[key]
            else:
                raise RunDirError(f"{w.dir.name}: adopted {key} is neither in the log nor in the store; the run directory is incomplete")
            models.adopt(a["partner"], int(a["version"]), rules)
        yield ga.generation(models.partners()).as_dict()
        g += 1


class _LoggedCases:
    """A case base that answers a restart with the cases the live learner restarted from (its changes.jsonl)."""

    def __init__(self, cases: list[Case]) -> None:
        self.cases = cases

    def add(self, capabilities: Any, rules: RuleSet, *, fitness: float, generation: int) -> Case:
        return Case(tuple(capabilities), rules, fitness, generation, -1)

    def nearest(self, capabilities: Any, k: int = 1) -> list[Case]:
        return self.cases


def _cel_rows(w: WorkerPaths, meta: dict[str, Any], world: BaseModel, ga_cfg: GAConfig) -> Iterator[dict[str, Any]]:
    """A CEL learner's curve, again: its learning module given the capability lists it took, when it took them."""
    from coevo.cel.learning import LearningModule
    from coevo.cel.settings import CelSettings

    cel = build(CelSettings, meta["cel"])
    module = LearningModule(world, ga_cfg, seed=meta["seed"], case_base=None, keep=cel.keep,  # type: ignore[arg-type]
                            cases=cel.cases)
    by_gen = _by_generation(read_jsonl(w.changes, missing_ok=True))
    g = 0
    while True:
        for c in by_gen.get(g, []):
            if cel.case_base:
                module.case_base = _LoggedCases([Case.from_dict(d) for d in c["restart_cases"]])  # type: ignore[assignment]
            if not module.set_capabilities(c["capabilities"]):
                raise RunDirError(f"{w.dir.name}: changes.jsonl takes {c['capabilities']} after generation {g}, the list "
                                  "already in force")
        yield module.generation().report.as_dict()
        g += 1


def replay(run_dir: Path) -> list[WorkerReplay]:
    run = RunPaths(Path(run_dir))
    workers = run.workers()
    store = _store(run)
    out = [replay_worker(w.dir, store) for w in workers]
    if run.execution.meta_json.exists():
        out.append(replay_execution(run))
    return out


def replay_execution(run: RunPaths) -> WorkerReplay:
    """A CEL run's execution module, again: its seed, its schedule, and the rule sets it took at the trials it
    took them (``policies.jsonl``), in the same stretches; every generation's outcomes and every change the
    monitor reported must come out the same."""
    from coevo.cel.execution import ExecutionModule
    from coevo.cel.monitor import Monitor
    from coevo.cel.settings import CelSettings
    from coevo.tasks.door import default_ruleset
    from coevo.tasks.door.settings import DoorConfig

    ex = run.execution
    meta = read_json(ex.meta_json, what="execution directory (its execution.json)")
    cel, world = build(CelSettings, meta["cel"]), build(DoorConfig, meta["world"])
    module = ExecutionModule(world, default_ruleset(), seed=int(meta["seed"]), schedule=cel.failure_schedule(),
                             monitor=Monitor(zero_run=cel.zero_run, repair_run=cel.repair_run, capabilities=world.capabilities),
                             window=cel.window)
    taken = {int(p["first_trial"]): p for p in read_jsonl(ex.policies)}
    rows, logged = read_jsonl(ex.performance), read_jsonl(ex.changes)
    K, found = cel.trials_per_generation, []
    for g, row in enumerate(rows):
        while module.trial < K * (g + 1):
            p = taken.get(module.trial)
            if p is not None:
                module.receive(RuleSet.from_dict(p["rules"]))
                module.version = int(p["version"])
            st = module.run(min(cel.chunk, K * (g + 1) - module.trial))
            found += [{"trial": c.trial, "decision": c.decision, "capabilities": list(c.capabilities)} for c in st.changes]
        again = {"external": module.performance, "capabilities": list(module.capabilities)}
        for k, v in again.items():
            if row.get(k) != v:
                return WorkerReplay("execution", len(rows), False, g, f"{k}: recorded {row.get(k)!r}, replayed {v!r}")
    want = [{k: c[k] for k in ("trial", "decision", "capabilities")} for c in logged]
    if found != want:
        first = next((i for i, (a, b) in enumerate(zip(found, want)) if a != b), min(len(found), len(want)))
        trial = (want[first] if first < len(want) else found[first])["trial"]
        return WorkerReplay("execution", len(rows), False, trial // K,
                            f"monitor change {first + 1}: recorded {want[first] if first < len(want) else None}, "
                            f"replayed {found[first] if first < len(found) else None}")
    return WorkerReplay("execution", len(rows), True, None, "identical")
