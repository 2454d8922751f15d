"""Appendix B's Figure 3 with the live service: ``coevo cel`` runs over seeds (once a script in benchmarks/).

Each replicate is one ``coevo cel`` (a broker, the learning module and the execution module as processes on
this host's loopback, its own run key) into ``OUT/runs/live-SEED``, run by :mod:`coevo.replicates` (``--jobs``
here, or ``--cluster``).  Its settings are written first, ``OUT/settings/live-SEED.json``, so the same options
give the same settings on any backend; a run interrupted after its ``run.json`` continues from its processes'
checkpoints (``coevo cel --resume``).  :func:`collect` reads what each finished run wrote: the external
performance per generation, the monitor's detections and the policy latency.
"""

from __future__ import annotations

import json
import shutil
import sys
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

from coevo.errors import ConfigError
from coevo.replicates.replicate import Replicate

if TYPE_CHECKING:
    from coevo.rundir.settings import RunSettings

__all__ = ["FIGURE3_FAILURE", "run_name", "write_settings", "replicates", "collect", "read_lockstep", "lockstep_equal"]

#: Figure 3's failure: the sonars the report's robot loses.
FIGURE3_FAILURE = ("front", "front_right", "right")


def run_name(seed: int) -> str:
    return f"live-{seed}"


def write_settings(out: Path, base: RunSettings, seeds: list[int]) -> None:
    """``OUT/settings/live-SEED.json``: ``base`` (a CEL run's RunSettings) for each seed, before anything runs."""
    d = out / "settings"
    d.mkdir(parents=True, exist_ok=True)
    for s in seeds:
        base.fresh(run_name(s)).model_copy(update={"seed": s}).save(d / f"{run_name(s)}.json")


def _argv(seed: int, root: Path) -> list[str]:
    """The ``coevo cel`` that runs this seed under ``root``, decided where it runs: one that got as far as its
    ``run.json`` continues from its processes' checkpoints, one that stopped before starts afresh."""
    root = Path(root)
    d = root / "runs" / run_name(seed)
    if (d / "run.json").exists():
        return [sys.executable, "-m", "coevo", "cel", "--quiet", "--resume", str(d)]
    if d.exists():
        shutil.rmtree(d)
    return [sys.executable, "-m", "coevo", "cel", "--quiet", "--settings",
            str(root / "settings" / f"{run_name(seed)}.json"), "--root", str(root / "runs")]


def _finished(seed: int, root: Path) -> bool:
    d = Path(root) / "runs" / run_name(seed)
    try:
        return (d / "cel.json").exists() and not json.loads((d / "summary.json").read_text())["interrupted"]
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _generations_done(seed: int, root: Path) -> int:
    f = Path(root) / "runs" / run_name(seed) / "execution" / "performance.jsonl"
    try:
        with open(f, "rb") as fh:
            return sum(1 for _ in fh)
    except OSError:
        return 0  # not started yet


def replicates(seeds: list[int], generations: int) -> list[Replicate]:
    """One ``coevo cel`` per seed (three processes; in lockstep about one core busy, as a live run: weight 2)."""
    return [Replicate(name=run_name(s), output=f"runs/{run_name(s)}", finished=partial(_finished, s),
                      command=partial(_argv, s), inputs=(f"settings/{run_name(s)}.json",), weight=2,
                      cost=generations + 1, progress=partial(_generations_done, s))
            for s in seeds]


def collect(out: Path, seeds: list[int]) -> list[dict[str, Any]]:
    """Per finished run: its seed, seconds, external performance per generation (0 = the default rules), the
    monitor's detections and each new best's latency from the learner to the robot (ms)."""
    from coevo.rundir.layout import read_jsonl

    runs = []
    for s in seeds:
        if not _finished(s, out):
            continue
        d = out / "runs" / run_name(s)
        perf = sorted(read_jsonl(d / "execution" / "performance.jsonl"), key=lambda r: r["generation"])
        runs.append({"seed": s, "seconds": json.loads((d / "summary.json").read_text())["seconds"],
                     "external": [float(p["external"]) for p in perf],
                     "detections": json.loads((d / "cel.json").read_text())["detections"],
                     "latency_ms": [float(p["latency_ms"]) for p in read_jsonl(d / "execution" / "policies.jsonl",
                                                                               missing_ok=True)]})
    return runs


def read_lockstep(path: Path, case_base: bool) -> dict[int, list[float]]:
    """Per-seed curves of the lockstep runs (``benchmarks/cel.py``'s JSON) of the same schedule; a ConfigError
    naming ``--lockstep`` when it cannot be read."""
    try:
        held = json.loads(Path(path).read_text())["runs"]
        if isinstance(held, dict):  # the cyclic file: restarts and case base apart
            held = held["case_base" if case_base else "restart"]
        return {int(r["seed"]): [float(x) for x in r["external"]] for r in held}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"--lockstep {str(path)!r}: not a file of lockstep runs ({type(exc).__name__}: {exc})") from None


def lockstep_equal(runs: list[dict[str, Any]], lockstep: dict[int, list[float]]) -> dict[str, Any]:
    """Which live runs equal the lockstep run of their seed exactly (the in-process reference)."""
    compared = [r["seed"] for r in runs if r["seed"] in lockstep]
    same = [r["seed"] for r in runs if r["seed"] in lockstep and lockstep[r["seed"]] == r["external"]]
    return {"compared": compared, "equal": same}

