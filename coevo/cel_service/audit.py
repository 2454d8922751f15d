"""What ``coevo check`` and ``coevo replay`` read in a CEL run beyond a worker's own logs.

A CEL run (``coevo cel``) holds a learner, which is a worker with a learning module
instead of a bare GA, and an execution module, which is no worker at all.  These are
the CEL kind's hooks (registered in :mod:`coevo.runs.kinds`):

* :func:`learner_curve`: the learner's learning curve again, from its ``changes.jsonl``
  (after how many generations it took which capability list, and the cases it restarted
  from);
* :func:`check_execution`: the execution module played every generation's trials once,
  used only rule sets the learner published under those versions, numbered its
  monitor's changes 1..n; every case the learner stored is in the broker's store;
* :func:`replay_execution`: the execution module again, from its seed, its schedule
  and the rule sets it took at the trials it took them (``policies.jsonl``).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

from pydantic import BaseModel

from coevo.agents.inbox import rules_digest
from coevo.cel.casebase import Case
from coevo.cel.settings import CelSettings
from coevo.config import GAConfig, build
from coevo.errors import RunDirError
from coevo.policy.rules import RuleSet
from coevo.rundir.layout import RunPaths, WorkerPaths, by_generation, read_cases, read_json, read_jsonl, span_text

__all__ = ["learner_curve", "check_execution", "replay_execution"]


class _LoggedCases:
    """A case base that answers a restart with the cases the live learner restarted from (its changes.jsonl)."""

    def __init__(self, cases: list[Case]) -> None:
        self.cases = cases

    def add(self, capabilities: Sequence[str], rules: RuleSet, *, fitness: float, generation: int) -> Case:
        return Case(tuple(capabilities), rules, fitness, generation, -1)

    def nearest(self, capabilities: Sequence[str], k: int = 1) -> list[Case]:
        return self.cases


def learner_curve(w: WorkerPaths, meta: dict[str, Any], world: BaseModel, ga_cfg: GAConfig) -> Iterator[dict[str, Any]]:
    """A CEL learner's curve, again: its learning module given the capability lists it took, when it took them."""
    from coevo.cel.learning import LearningModule

    cel = build(CelSettings, meta["cel"])
    module = LearningModule(world, ga_cfg, seed=meta["seed"], case_base=None, keep=cel.keep,  # type: ignore[arg-type]
                            cases=cel.cases)
    by_gen = by_generation(read_jsonl(w.changes, missing_ok=True))
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


def check_execution(run: RunPaths, published: dict[tuple[str, int], tuple[str, str]]) -> tuple[list[str], dict[str, Any]]:
    """Problems and facts of a CEL run's execution module and case base; ``published`` maps (behaviour, version)
    to (worker id, digest of its rules), from the workers' own publication logs."""
    problems: list[str] = []
    ex = run.execution
    meta = read_json(ex.meta_json, what="execution directory (its execution.json)")
    gens = int(meta.get("generations", 0))
    points = [int(r["generation"]) for r in read_jsonl(ex.performance, problems=problems)]
    if points != list(range(gens + 1)):
        problems.append(f"execution: performance.jsonl has generations {span_text(points)}, expected 0..{gens}")
    done = read_json(ex.done, what="execution directory (its done.json)") if ex.done.exists() else {}
    if not done.get("finished"):
        problems.append("execution: done.json missing or not finished")
    used = read_jsonl(ex.policies, problems=problems)
    for u in used:
        pub = published.get(("door", int(u["version"])))
        if pub is None or pub[1] != rules_digest(u["rules"]):
            problems.append(f"execution: used door v{u['version']}, which the learner did not publish so")
    changes = [int(c["change"]) for c in read_jsonl(ex.changes, problems=problems)]
    if changes != list(range(1, len(changes) + 1)):
        problems.append(f"execution: changes.jsonl numbers {changes}, not 1..n")
    learner = run.worker("door")
    if learner.cases.exists():
        store = run.case_file("door")
        held = {(c.worker, c.version): c for c in read_cases(store, problems=problems)} if store.exists() else {}
        own = [c for c in read_cases(learner.cases, problems=problems) if c.worker == learner.meta()["worker"]]
        lost = [c.version for c in own if (c.worker, c.version) not in held or held[(c.worker, c.version)].rules != c.rules]
        if lost:
            problems.append(f"door: cases {lost} are not in the store as the learner stored them")
    return problems, {"execution": {"generations": len(points), "policies_used": len(used), "changes": len(changes)}}


def replay_execution(run: RunPaths) -> tuple[str, int, int | None, str]:
    """A CEL run's execution module, again: its seed, its schedule, and the rule sets it took at the trials it
    took them (``policies.jsonl``), in the same stretches; every generation's outcomes and every change the
    monitor reported must come out the same.  Returns (what, generations, first mismatch or None, detail)."""
    from coevo.cel.execution import ExecutionModule
    from coevo.cel.monitor import Monitor
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
    K = cel.trials_per_generation
    found: list[dict[str, Any]] = []
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
                return "execution", len(rows), g, f"{k}: recorded {row.get(k)!r}, replayed {v!r}"
    want: list[dict[str, Any]] = [{k: c[k] for k in ("trial", "decision", "capabilities")} for c in logged]
    if found != want:
        first = next((i for i, (a, b) in enumerate(zip(found, want)) if a != b), min(len(found), len(want)))
        trial = (want[first] if first < len(want) else found[first])["trial"]
        return ("execution", len(rows), trial // K,
                f"monitor change {first + 1}: recorded {want[first] if first < len(want) else None}, "
                f"replayed {found[first] if first < len(found) else None}")
    return "execution", len(rows), None, "identical"
