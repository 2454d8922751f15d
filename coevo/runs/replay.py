"""``coevo replay RUN_DIR``: re-run a finished asynchronous run in one process, exactly.

Each worker's GA is deterministic given its seed and the partner policies it
evaluated against; the only non-repeatable thing in a run is *when* partner
versions arrived.  The adoption log records that (after how many of its own
generations a worker took which version), and the store holds every version, so
replaying feeds each GA the same partners at the same points and must reproduce
its learning curve bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from coevo.agents.models import PartnerModels
from coevo.config import GAConfig, build
from coevo.errors import RunDirError
from coevo.ga import GA
from coevo.policy.rules import RuleSet
from coevo.runs.layout import RunPaths, WorkerPaths, read_jsonl, read_store
from coevo.tasks import DEFAULT_TASK, get_task

__all__ = ["WorkerReplay", "replay"]

_UNCOMPARED = ("seconds",)  # every other column of the learning curve must be identical


@dataclass(frozen=True)
class WorkerReplay:
    behaviour: str
    generations: int
    reproduced: bool
    first_mismatch: int | None  # 1-based generation
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
    adoptions = read_jsonl(w.adoptions)
    n = len(curve) if until is None else min(until, len(curve))
    models = PartnerModels(task, behaviour, meta["regime"], meta["seed"], kind=meta["model"], ga=ga_cfg)
    ga = GA(task, behaviour, world=world, ga=ga_cfg, seed=meta["seed"])
    by_gen: dict[int, list[dict]] = {}
    for a in adoptions:
        by_gen.setdefault(int(a["generation"]), []).append(a)
    for g in range(n):
        for a in by_gen.get(g, []):
            key = (a["partner"], a["from_worker"], int(a["version"]))
            if "rules" in a:
                rules = RuleSet.from_dict(a["rules"])
            elif key in store:
                rules = store[key]
            else:
                raise RunDirError(f"{wdir.name}: adopted {key} is neither in the log nor in the store; the run directory is incomplete")
            models.adopt(a["partner"], int(a["version"]), rules)
        rep = ga.generation(models.partners()).as_dict()
        for k in sorted(set(rep) | set(curve[g])):
            if k not in _UNCOMPARED and rep.get(k) != curve[g].get(k):
                return WorkerReplay(behaviour, n, False, g + 1, f"{k}: recorded {curve[g].get(k)!r}, replayed {rep.get(k)!r}")
    return WorkerReplay(behaviour, n, True, None, "identical")


def replay(run_dir: Path) -> list[WorkerReplay]:
    run = RunPaths(Path(run_dir))
    workers = run.workers()
    store = _store(run)
    return [replay_worker(w.dir, store) for w in workers]
