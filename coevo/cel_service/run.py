"""``coevo cel``: one live Continuous and Embedded Learning run on this machine (report Appendix B).

A :class:`CelRun` is a :class:`~coevo.runs.local.LocalRun` of the door task with a
``cel`` block in its ``run.json``: it starts ``coevo broker``, the learning module
(``coevo worker --behaviour door``, a :class:`~coevo.cel_service.learner.CelLearner`) and the
execution module (``coevo execution``, :mod:`coevo.cel_service.robot`) as three processes,
shows the live table (the learner's generation and best simulated success, the
robot's external performance, capability list and last change) and at the end writes
what the run did: ``performance.csv`` (Figure 3's curve, one row per generation),
``cel.json`` (the changes the monitor detected and when, the detection delays, the
learner's restarts, how fast new rules reached the robot) and ``summary.json``.
``coevo cel --resume RUN_DIR`` continues a run from its processes' checkpoints;
``coevo replay RUN_DIR`` reproduces the learner and the robot.

``--cases-from EARLIER_RUN`` starts the run's case base with the cases an earlier run's
broker stored (``EARLIER_RUN/store/cases/door.jsonl``): they are written into the new
run's store before its broker starts, as the learner's own (renumbered, their run in
``origin``), so the learner finds them there like any case the store holds.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path
from typing import Any

from coevo.bus.messages import CaseUpdate
from coevo.errors import ConfigError, RunDirError
from coevo.rundir.layout import (ExecutionPaths, RunPaths, not_a_file, read_cases, read_json, read_jsonl, write_csv,
                                 write_json)
from coevo.runs.local import LocalRun
from coevo.tasks.door import DOOR

__all__ = ["CelRun", "EXECUTION", "cel_report", "cases_of_run", "import_cases"]

EXECUTION = "execution"  # the execution module's process name (beside the behaviours' workers)


class CelRun(LocalRun):
    """The broker, learner and execution module of one CEL run directory."""

    COMMAND = "coevo cel"

    def __init__(self, settings: Any, **kwargs: Any) -> None:
        if settings.block("cel") is None:
            raise ConfigError("a CEL run needs cel settings (coevo cel makes them)")
        super().__init__(settings, **kwargs)

    @property
    def execution_paths(self) -> ExecutionPaths:
        return self.paths.execution

    def log_name(self, b: str) -> str:
        return EXECUTION if b == EXECUTION else super().log_name(b)

    def worker_args(self, b: str) -> list[str]:
        if b != EXECUTION:
            return super().worker_args(b)
        return ["execution", "--settings", str(self.paths.run_json), "--connect", self.endpoint, "--connect-timeout", "-1",
                "--out", str(self.execution_paths.dir)]

    def progress_log(self, b: str) -> Path:
        # the execution module's line per generation is that generation's trials
        return self.execution_paths.performance if b == EXECUTION else super().progress_log(b)

    def processes(self) -> dict[str, Any]:
        from coevo.cel_service.robot import Execution

        return {**super().processes(), EXECUTION: Execution(self.settings, out_dir=self.execution_paths.dir,
                                                            conf=self.client_config(), resume=True, run_key=self.key)}

    def processes_names(self) -> list[str]:
        return [*super().processes_names(), EXECUTION]

    def problems(self) -> list[str]:
        # and where its end writes what the run did
        return not_a_file([self.paths.dir / "cel.json", self.paths.dir / "performance.csv"]) + super().problems()

    def start(self, *, resume: bool) -> None:
        super().start(resume=resume)
        self.start_worker(EXECUTION, resume=resume)

    def unfinished(self) -> dict[str, int]:
        out = super().unfinished()
        p = self.execution_paths
        done = read_json(p.done, what="execution directory (its done.json)") if p.done.exists() else {}
        if not done.get("finished"):
            out[EXECUTION] = len(read_jsonl(p.performance, missing_ok=True))  # generations whose trials it played
        return out

    def finish(self, latest: dict[str, Any], *, seconds: float, interrupted: bool, measure_epochs: int,
               extra: dict[str, Any] | None = None) -> dict[str, Any]:
        report = cel_report(self.paths)
        write_json(self.paths.dir / "cel.json", report)
        write_csv(self.paths.dir / "performance.csv", report.pop("rows"))
        return super().finish(latest, seconds=seconds, interrupted=interrupted, measure_epochs=measure_epochs,
                              extra={**(extra or {}), "cel": {k: v for k, v in report.items() if k != "changes"}})


def cases_of_run(source: Path) -> list[CaseUpdate]:
    """The case base an earlier run's broker stored (``SOURCE/store/cases/door.jsonl``); a ConfigError if there is none."""
    src = RunPaths(Path(source))
    f = src.case_file(DOOR)
    if not src.dir.is_dir():
        raise ConfigError(f"--cases-from {str(source)!r} is not a run directory")
    if not f.exists():
        raise ConfigError(f"--cases-from {str(source)!r}: its store holds no case base ({f} does not exist; a run with "
                          "--case-base stores one)")
    try:
        return read_cases(f)
    except RunDirError as exc:
        raise ConfigError(f"--cases-from {str(source)!r}: {exc}") from None


def import_cases(run: RunPaths, cases: list[CaseUpdate], *, worker: str) -> None:
    """Write ``cases`` (an earlier run's) into ``run``'s store as ``worker``'s, renumbered, their run in ``origin``."""
    out = run.case_file(DOOR)
    out.parent.mkdir(parents=True, exist_ok=True)
    now = time.time()
    lines = [CaseUpdate(**{**c.model_dump(), "run": run.name, "worker": worker, "version": i, "sent_at": now,
                           "origin": c.origin or c.run}).model_dump_json() + "\n" for i, c in enumerate(cases, 1)]
    out.write_text("".join(lines), encoding="utf-8")


def _detections(changes: list[dict[str, Any]], schedule: tuple[tuple[int, tuple[str, ...]], ...], K: int,
                learner_changes: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """For each schedule event: the first change at or after it that matches the world, its delays, and the
    learner generations run on the wrong model after it (0: the first generation after the event's generation
    already learned with the right list, as in lockstep)."""
    out = []
    for g, failed in schedule:
        start = g * K
        hit = next((c for c in changes if c["trial"] >= start and c.get("matches_world")), None)
        row: dict[str, Any] = {"generation": g, "trial": start, "failed": list(failed), "detected": hit is not None}
        if hit is not None:
            took = next((lc for lc in learner_changes if lc["change"] >= hit["change"]), None)
            row.update(trials=hit["delay_trials"], decisions=hit["delay_decisions"], detected_in_generation=hit["generation"])
            if took is not None:
                row.update(learner_from=took["generation"] + 1, generations=took["generation"] - g,
                           seconds_to_learner=round(took["received_at"] - hit["detected_at"], 4))
        out.append(row)
    return out


def cel_report(paths: RunPaths) -> dict[str, Any]:
    """What a CEL run did, from its directory: Figure 3's rows, the changes, the detection delays, the latency."""
    from coevo.rundir.settings import RunSettings

    settings = RunSettings.load(paths.run_json)
    if settings.block("cel") is None:
        raise RunDirError(f"{str(paths.dir)!r} is not a CEL run (its run.json has no cel block)")
    ex = paths.execution
    learner = paths.worker(DOOR)
    perf = read_jsonl(ex.performance, missing_ok=True)
    curve = {int(r["generation"]): r for r in read_jsonl(learner.curve, missing_ok=True)}
    rows = [{"generation": r["generation"], "external": r["external"],
             "simulated": (curve.get(r["generation"]) or {}).get("success"),
             "success": r["success"], "collision": r["collision"], "timeout": r["timeout"],
             "not_forward": r["not_forward"], "rules_versions": " ".join(map(str, r["rules_versions"])),
             "world_failed": " ".join(r["world_failed"]), "capabilities": " ".join(r["capabilities"])} for r in perf]
    changes = read_jsonl(ex.changes, missing_ok=True)
    learner_changes = read_jsonl(learner.changes, missing_ok=True)
    latency = [r["latency_ms"] for r in read_jsonl(ex.policies, missing_ok=True)]
    return {"rows": rows, "generations_played": len(perf), "external_end": perf[-1]["external"] if perf else None,
            "changes": changes, "learner_restarts": [{k: c[k] for k in ("generation", "change", "capabilities")}
                                                     for c in learner_changes],
            "detections": _detections(changes, settings.block("cel").schedule, settings.block("cel").trials_per_generation,
                                      learner_changes),
            "policies_received": len(latency),
            "latency_ms": {"median": statistics.median(latency), "max": max(latency)} if latency else None,
            "cases": len(read_cases(paths.case_file(DOOR))) if paths.case_file(DOOR).exists() else 0}
