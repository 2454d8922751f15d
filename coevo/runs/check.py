"""``coevo check RUN_DIR``: is a finished run directory complete and consistent?

What it checks, per worker directory:

* ``curve.jsonl`` holds generations 1..G in order, G = the configured generations,
  and ``done.json`` says the worker finished;
* ``published.jsonl`` holds versions 1..n in order, and the broker's store
  (``store/BEHAVIOUR.jsonl``) holds every one of them, identical: nothing a worker
  published was lost, however often the broker or the worker died;
* every adoption in ``adoptions.jsonl`` names a version its partner published;
* ``coevo replay`` reproduces the learning curve exactly from the logs (skipped
  with ``replay=False``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from coevo.runs.layout import RunPaths, read_json, read_jsonl, read_store

__all__ = ["RunCheck", "check_run"]


@dataclass
class RunCheck:
    run_dir: Path
    problems: list[str] = field(default_factory=list)
    facts: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.problems


def check_run(run_dir: Path, *, replay: bool = True) -> RunCheck:
    run = RunPaths(Path(run_dir))
    check = RunCheck(run.dir)
    wdirs = run.workers()
    stored: dict[tuple[str, str, int], dict[str, Any]] = {}
    for f in run.store_files():
        for m in read_store(f, problems=check.problems):
            stored[(m.behaviour, m.worker, m.version)] = m.model_dump(mode="json")
    published_all: set[tuple[str, int]] = set()
    adoptions: list[tuple[str, str, list[dict[str, Any]]]] = []  # (behaviour, partner model, adoptions)
    for w in wdirs:
        meta = w.meta()
        beh, worker, gens = meta["behaviour"], meta["worker"], int(meta["ga"].get("generations", 0))
        curve = read_jsonl(w.curve, problems=check.problems)
        got = [int(r["generation"]) for r in curve]
        if got != list(range(1, gens + 1)):
            check.problems.append(f"{beh}: curve.jsonl has generations {_span(got)}, expected 1..{gens}")
        done = read_json(w.done, what="worker directory (its done.json)") if w.done.exists() else {}
        if not done.get("finished"):
            check.problems.append(f"{beh}: done.json missing or not finished")
        published = read_jsonl(w.published, problems=check.problems)
        versions = [int(p["version"]) for p in published]
        if versions != list(range(1, len(versions) + 1)):
            check.problems.append(f"{beh}: published.jsonl versions {versions} are not 1..n in order")
        lost = []
        for p in published:
            s = stored.get((beh, worker, int(p["version"])))
            if s is None:
                lost.append(int(p["version"]))
            elif s["rules"] != p["rules"] or s["fitness"] != p["fitness"]:
                check.problems.append(f"{beh}: the store's v{p['version']} differs from what the worker published")
            published_all.add((beh, int(p["version"])))
        if lost:
            check.problems.append(f"{beh}: versions {lost} were published but are not in the store")
        adopted = read_jsonl(w.adoptions, problems=check.problems)
        adoptions.append((beh, meta["model"], adopted))
        check.facts[beh] = {"generations": len(curve), "published": len(published),
                            "republished": done.get("republished", 0), "rejected": done.get("rejected", {}),
                            "adoptions": len(adopted)}
    for beh, model, adopted in adoptions:
        for a in adopted:
            if model != "current" and (a["partner"], int(a["version"])) not in published_all:
                check.problems.append(f"{beh}: adopted {a['partner']} v{a['version']}, which no worker published")
    if replay and not check.problems:
        from coevo.runs.replay import replay as replay_run

        for r in replay_run(run.dir):
            if not r.reproduced:
                check.problems.append(f"{r.behaviour}: replay differs at generation {r.first_mismatch}: {r.detail}")
        check.facts["replayed"] = True
    return check


def _span(values: list[int]) -> str:
    if not values:
        return "none"
    return f"{values[0]}..{values[-1]} ({len(values)} lines)" if values == list(range(values[0], values[-1] + 1)) else str(values)
