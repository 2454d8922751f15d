"""``coevo check RUN_DIR``: is a finished run directory complete and consistent?

What it checks, per worker directory:

* ``curve.jsonl`` holds generations 1..G in order, G = the configured generations,
  and ``done.json`` says the worker finished;
* ``published.jsonl`` holds versions 1..n in order, and the broker's store
  (``store/BEHAVIOUR.jsonl``) holds every one of them, identical: nothing a worker
  published was lost, however often the broker or the worker died;
* the store's latest of each behaviour (its highest version from that worker, as the
  broker answers it: by version, never by arrival) is the worker's newest published
  version, and a finished run's ``summary.json`` measured that version;
* every adoption in ``adoptions.jsonl`` names a version its partner published, from
  the worker that published it (its worker id), with the rules it published under that
  version (sha256 of the rules' canonical JSON, the ``rules_digest`` the adoption
  recorded and the one of the rules it holds);
* with a roster in ``run.json``, each worker is its behaviour's roster member and the
  store holds no policy of any other worker id;
* a resume would start: ``run.json``, the key, each process's settings, checkpoint and logs up to what the
  checkpoint saw read as ``coevo run --resume`` reads them (:meth:`coevo.runs.local.LocalRun.problems`);
* ``coevo replay`` reproduces the learning curve exactly from the logs (skipped
  with ``replay=False``).

A kind of learner with modules of its own (a CEL run's execution module and case base) adds
its checks of them (:mod:`coevo.runs.kinds`; for CEL, :func:`coevo.cel_service.audit.check_execution`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from coevo.agents.inbox import rules_digest
from coevo.errors import CoevoError
from coevo.bus.messages import PolicyUpdate
from coevo.rundir.layout import RunPaths, read_json, read_jsonl, read_store, span_text
from coevo.rundir.records import AdoptionLine, CurveLine
from coevo.runs.kinds import kind_of_settings, run_kinds

__all__ = ["RunCheck", "check_run"]


@dataclass
class RunCheck:
    run_dir: Path
    problems: list[str] = field(default_factory=list)
    facts: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.problems


def check_run(run_dir: Path, *, replay: bool = True, progress: Callable[[str, int, int], None] | None = None) -> RunCheck:
    """What is wrong with a finished run directory (``progress``: told each generation its replay reproduced)."""
    run = RunPaths(Path(run_dir))
    check = RunCheck(run.dir)
    wdirs = run.workers()
    roster = _roster(run, check)
    stored: dict[tuple[str, str, int], PolicyUpdate] = {}
    for f in run.store_files():
        for m in read_store(f, problems=check.problems):
            stored[(m.behaviour, m.worker, m.version)] = m
    if roster is not None:
        foreign = sorted({(b, w) for b, w, _ in stored if roster.get(b) != w})
        for b, worker in foreign:
            check.problems.append(f"the store holds {b} policies from worker {worker!r}, not the roster's "
                                  f"{roster.get(b)!r}")
    # (behaviour, version) -> (worker id, digest of its rules), from the workers' own published.jsonl
    published_all: dict[tuple[str, int], tuple[str, str]] = {}
    adoptions: list[tuple[str, str, list[dict[str, Any]]]] = []  # (behaviour, partner model, adoptions)
    for w in wdirs:
        try:
            meta = w.meta()
        except CoevoError as exc:
            check.problems.append(str(exc))
            continue
        beh, worker, gens = meta["behaviour"], meta["worker"], int(meta["ga"].get("generations", 0))
        if roster is not None and roster.get(beh) != worker:
            check.problems.append(f"{beh}: worker {worker!r} is not the roster's {roster.get(beh)!r}")
        curve = read_jsonl(w.curve, schema=CurveLine, problems=check.problems)
        got = [r["generation"] for r in curve]
        if got != list(range(1, gens + 1)):
            check.problems.append(f"{beh}: curve.jsonl has generations {span_text(got)}, expected 1..{gens}")
        try:
            done = read_json(w.done, what="worker directory (its done.json)") if w.done.exists() else {}
        except CoevoError as exc:
            check.problems.append(str(exc))
            done = {}
        if not done.get("finished"):
            check.problems.append(f"{beh}: done.json missing or not finished")
        published = read_store(w.published, problems=check.problems)
        versions = [p.version for p in published]
        if versions != list(range(1, len(versions) + 1)):
            check.problems.append(f"{beh}: published.jsonl versions {versions} are not 1..n in order")
        lost = []
        for p in published:
            s = stored.get((beh, worker, p.version))
            if s is None:
                lost.append(p.version)
            elif s.rules != p.rules or s.fitness != p.fitness:
                check.problems.append(f"{beh}: the store's v{p.version} differs from what the worker published")
            published_all[(beh, p.version)] = (worker, rules_digest(p.rules))
        if lost:
            check.problems.append(f"{beh}: versions {lost} were published but are not in the store")
        _check_latest(check, run, beh, worker, versions, stored)
        adopted = read_jsonl(w.adoptions, schema=AdoptionLine, problems=check.problems)
        adoptions.append((beh, meta["model"], adopted))
        check.facts[beh] = {"generations": len(curve), "published": len(published),
                            "republished": done.get("republished", 0), "rejected": done.get("rejected", {}),
                            "adoptions": len(adopted)}
    for beh, model, adopted in adoptions:
        for a in adopted:
            _check_adoption(check, beh, model, a, published_all)
    check.problems += [p for p in _resume_problems(run) if p not in check.problems]
    for kind in run_kinds(run):
        if kind.check_run is None:
            continue
        problems, facts = kind.check_run(run, published_all)
        check.problems += problems
        check.facts.update(facts)
    if replay and not check.problems:
        from coevo.runs.replay import replay as replay_run

        for r in replay_run(run.dir, progress=progress):
            if not r.reproduced:
                check.problems.append(f"{r.behaviour}: replay differs at generation {r.first_mismatch}: {r.detail}")
        check.facts["replayed"] = True
    return check


def _resume_problems(run: RunPaths) -> list[str]:
    """What would stop ``coevo run --resume`` (or its kind's command) of the run: its run.json, key, each process's
    settings, checkpoint and logs up to what the checkpoint saw (:meth:`coevo.runs.local.LocalRun.problems`).  A
    directory without run.json, or whose run.json has no roster (workers started by hand, the first of which wrote
    it), is not resumed by a run command: nothing to say."""
    from coevo.rundir.settings import RunSettings

    if not (run.run_json.exists() or run.run_json.is_symlink()):
        return []
    try:
        settings = RunSettings.load(run.run_json)
        if settings.roster is None:  # workers started by hand (run.json written by the first): resumed by hand too
            return []
        return kind_of_settings(settings).run().resumable(run.dir).problems()
    except CoevoError as exc:
        return [str(exc)]


def _check_latest(check: RunCheck, run: RunPaths, beh: str, worker: str, versions: list[int],
                  stored: dict[tuple[str, str, int], PolicyUpdate]) -> None:
    """The store's latest (highest version of the worker) is its newest published; so is what the summary measured."""
    if not versions:
        return
    newest = max(versions)
    held = [v for b, w, v in stored if b == beh and w == worker]
    if held and max(held) != newest:
        check.problems.append(f"{beh}: the store's latest is v{max(held)}, but the worker's newest published is v{newest}")
    if run.summary.exists():
        try:
            summary = read_json(run.summary, what="run directory (its summary.json)")
        except CoevoError as exc:
            check.problems.append(str(exc))
            return
        measured = (summary.get("versions") or {}).get(beh)
        if not summary.get("interrupted") and measured is not None and measured != newest:
            check.problems.append(f"{beh}: summary.json measured v{measured}, but the newest published is v{newest}")


def _roster(run: RunPaths, check: RunCheck) -> dict[str, str] | None:
    """The roster in run.json (None for runs without one: by hand, or made before rosters)."""
    if not run.run_json.exists():
        return None
    try:
        roster = read_json(run.run_json, what="run directory (its run.json)").get("roster")
    except CoevoError as exc:
        check.problems.append(str(exc))
        return None
    return roster if isinstance(roster, dict) else None


def _check_adoption(check: RunCheck, beh: str, model: str, a: dict[str, Any],
                    published: dict[tuple[str, int], tuple[str, str]]) -> None:
    """An adopted version must be one its partner published: same worker, same rules (by digest)."""
    partner, version = a["partner"], a["version"]
    what = f"{beh}: adopted {partner} v{version}"
    digest = rules_digest(a["rules"]) if a.get("rules") is not None else None
    if a.get("rules_digest") is not None and a["rules_digest"] != digest:
        check.problems.append(f"{what}: its recorded rules_digest does not match the rules it recorded")
    if model in ("current", "hall"):
        return  # current policies (the hall's too) are not logged by their publisher: nothing to compare with
    pub = published.get((partner, version))
    if pub is None:
        check.problems.append(f"{what}, which no worker published")
        return
    worker, pub_digest = pub
    if a.get("from_worker") != worker:
        check.problems.append(f"{what} from worker {a.get('from_worker')!r}, but {worker!r} published it")
    if digest != pub_digest:
        check.problems.append(f"{what} with rules other than {worker!r} published under that version")

