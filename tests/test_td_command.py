"""coevo td-baseline through the replicate runner: the same results as run_task in one process (the seconds
apart), the report's files, --resume, and the same results on a pool of processes and on a local Dask cluster.

Tiny: the door task (and Tracking on the cluster), 2 seeds, 2 generations, population 4, 16 lanes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from coevo.cli import main
from coevo.experiments.earl.td.runs import run_task
from coevo.experiments.earl.td.spec import TDSpec

TINY = ["--seeds", "2", "--generations", "2", "--population", "4", "--episodes", "3", "--lanes", "16", "--trials", "10",
        "--quiet"]
FILES = {"results.json", "curves.csv", "report.md", "timing.json", "td-baseline.json"}


def _curves(res: dict) -> dict:
    """A task's results without what depends on the clock."""
    strip = lambda cs: [{k: v for k, v in c.items() if k != "seconds"} for c in cs]  # noqa: E731
    return {"checkpoint_steps": res["checkpoint_steps"], "ga": strip(res["ga"]), "td": strip(res["td"]),
            "variants": {v: strip(cs) for v, cs in res["variants"].items()}, "spec": res["spec"]}


def _results(out: Path, tasks: list[str]) -> dict:
    assert FILES | {f"fig-{t}.png" for t in tasks} <= {p.name for p in out.iterdir()}
    data = json.loads((out / "results.json").read_text())
    assert sorted(data["tasks"]) == sorted(tasks)
    for t, res in data["tasks"].items():
        assert len(res["ga"]) == len(res["td"]) == 2
        assert all(0 <= m <= 100 for c in res["ga"] + res["td"] for m in c["measure"])
    assert sorted(json.loads((out / "timing.json").read_text())["tasks"]) == sorted(tasks)
    return {t: _curves(res) for t, res in data["tasks"].items()}


def test_the_runner_gives_run_tasks_results_and_resumes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "td"
    assert main(["td-baseline", "--tasks", "door", *TINY, "--out", str(out)]) == 0
    assert "door: at " in capsys.readouterr().out
    got = _results(out, ["door"])["door"]
    spec = TDSpec(task="door", seeds=2, generations=2, population=4, episodes=3, lanes=16, trials=10)
    want = _curves(json.loads(json.dumps(run_task(spec, variants=("default-rules",)))))
    assert got == want
    assert main(["td-baseline", "--tasks", "door", *TINY, "--out", str(out)]) == 2  # not without --resume
    assert "--resume" in capsys.readouterr().err
    before = (out / "parts" / "door" / "td.json").stat().st_mtime_ns
    assert main(["td-baseline", "--tasks", "door", *TINY, "--out", str(out), "--resume"]) == 0
    assert (out / "parts" / "door" / "td.json").stat().st_mtime_ns == before  # finished: not run again
    assert main(["td-baseline", "--tasks", "door", *TINY, "--seed", "3", "--out", str(out), "--resume"]) == 2


@pytest.mark.service
@pytest.mark.slow
def test_a_pool_of_processes_and_a_local_dask_cluster_give_the_same_results(tmp_path: Path) -> None:
    got = []
    for where, flags in (("here", ["--jobs", "1"]), ("pool", ["--jobs", "2"]), ("dask", ["--cluster", "local:2"])):
        r = subprocess.run([sys.executable, "-m", "coevo", "td-baseline", "--tasks", "door", "tracking", *TINY,
                            "--out", str(tmp_path / where), *flags], capture_output=True, text=True, timeout=180,
                           check=False)
        assert r.returncode == 0, r.stdout + r.stderr
        got.append(_results(tmp_path / where, ["door", "tracking"]))
    assert got[0] == got[1] == got[2]
