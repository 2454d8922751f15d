"""coevo cel-experiment: Figure 3 over live coevo cel runs, through the replicate runner, here and on Dask.

The live tests start real runs (a broker, a learner and a robot each) at a tiny size: 2 runs of 4 generations
of 10 trials, the failure at generation 2.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from procs import coevo_main

from coevo.cli import main
from coevo.experiments.cel.report import key_points
from coevo.rundir.settings import RunSettings

TINY = ["--runs", "2", "--generations", "4", "--population", "4", "--episodes", "2", "--trials-per-generation", "10",
        "--fail", "2:front,front_right,right", "--quiet"]
FILES = {"report.md", "summary.json", "curve.csv", "runs.csv", "figure3.png", "cel-experiment.json"}


def coevo(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=timeout,
                          check=False)


def test_the_table_is_figure3s_four_numbers_for_its_failure_and_none_for_another_schedule() -> None:
    rows = key_points([(50, ["front", "front_right", "right"])], 100)
    assert [(r["generation"], r["report"]) for r in rows] == [(0, 25.0), (49, 63.0), (50, 37.0), (100, 60.0)]
    cyclic = key_points([(25, ["front"]), (50, []), (75, ["front"])], 100)
    assert [r["generation"] for r in cyclic] == [0, 24, 25, 49, 50, 74, 75, 100]
    assert all(r["report"] is None for r in cyclic)
    assert [r["generation"] for r in key_points([(50, ["front"])], 4)] == [0, 4]  # an event after the end is left out


def test_coevo_cel_settings_takes_every_setting_from_the_file_and_only_a_cel_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cel = tmp_path / "cel.json"
    RunSettings.make(run="x", task="door", regime="independent", cel={}).save(cel)
    assert main(["cel", "--settings", str(cel), "--seed", "3", "--root", str(tmp_path / "runs"), "--quiet"]) == 2
    assert "--settings gives every run setting but the run id; drop --seed" in capsys.readouterr().err
    plain = tmp_path / "plain.json"
    RunSettings.make(run="y", regime="independent").save(plain)
    assert main(["cel", "--settings", str(plain), "--root", str(tmp_path / "runs"), "--quiet"]) == 2
    assert "not a CEL run's settings" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


def test_the_other_commands_tell_a_cel_run_by_the_kinds_table(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    """coevo run sends a CEL run's settings to coevo cel, and a CEL run is a door-task run (coevo.runs.kinds)."""
    from coevo.cel_service.kind import CEL
    from coevo.runs.kinds import COEVOLUTION, kind_of_settings, kind_of_worker

    cel = RunSettings.make(run="x", task="door", regime="independent", cel={})
    assert kind_of_settings(cel) is CEL and kind_of_settings(RunSettings.make(run="y", regime="mutual")) is COEVOLUTION
    assert kind_of_worker({"cel": {}, "behaviour": "door"}) is CEL and kind_of_worker({"behaviour": "door"}) is COEVOLUTION
    cel.save(tmp_path / "cel.json")
    assert main(["run", "--settings", str(tmp_path / "cel.json"), "--root", str(tmp_path / "runs"), "--quiet"]) == 2
    assert "holds the settings of a CEL run: start it with coevo cel" in capsys.readouterr().err
    assert main(["chaos", "--learner", "cel", "--task", "fuel", "--root", str(tmp_path / "runs"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "a CEL run (cel settings) is a door-task run, not a 'fuel' one" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "runs").exists()


def _check(out: Path, stdout: str) -> dict:
    assert FILES <= {p.name for p in out.iterdir()}, sorted(p.name for p in out.iterdir())
    data = json.loads((out / "summary.json").read_text())
    assert data["runs_finished"] == data["runs_expected"] == 2
    assert [r["generation"] for r in data["table"]] == [0, 1, 2, 4]
    assert [r["report"] for r in data["table"]] == [25.0, 63.0, 37.0, 60.0]
    for r in data["table"]:
        assert 0 <= r["mean"] <= 100 and r["sd"] >= 0 and len(r["ours"]) == 2
    assert len(data["external_mean"]) == 5 and all(0 <= x <= 100 for x in data["external_mean"])
    assert data["detections"]["events"] == 2 and data["detections"]["detected"] == 2  # the monitor sees every failure
    assert data["latency_ms"]["n"] >= 2 and 0 < data["latency_ms"]["median"] < 5000
    assert "| 2 | generation 2: front, front_right, right fail |" in (out / "report.md").read_text()
    assert len((out / "runs.csv").read_text().splitlines()) == 3
    assert "(report 63 %)" in stdout
    return data


@pytest.mark.service
def test_live_runs_write_the_report_and_resume_keeps_them(tmp_path: Path) -> None:
    out = tmp_path / "cel"
    r = coevo("cel-experiment", *TINY, "--out", str(out), "--jobs", "2")
    assert r.returncode == 0, r.stdout + r.stderr
    _check(out, r.stdout)
    settings = sorted(p.name for p in (out / "settings").iterdir())
    assert settings == ["live-0.json", "live-1.json"]
    # The two refusals come before anything starts: in process (coevo_main, as python -m coevo runs it).
    again = coevo_main("cel-experiment", *TINY, "--out", str(out))
    assert again.returncode == 2 and "--resume" in again.stderr and len(again.stderr.splitlines()) == 1
    other = coevo_main("cel-experiment", *TINY[:-1], "--generations", "5", "--quiet", "--out", str(out), "--resume")
    assert other.returncode == 2 and "differs in: generations" in other.stderr
    resumed = coevo("cel-experiment", *TINY, "--out", str(out), "--resume")  # both finished: nothing runs again
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert json.loads((out / "summary.json").read_text())["runs_finished"] == 2


@pytest.mark.service
def test_on_a_local_dask_cluster_the_report_has_the_same_form(tmp_path: Path) -> None:
    r = coevo("cel-experiment", *TINY, "--out", str(tmp_path / "dask"), "--cluster", "local:2")
    assert r.returncode == 0, r.stdout + r.stderr
    data = _check(tmp_path / "dask", r.stdout)
    assert {p.name for p in (tmp_path / "dask" / "runs").iterdir()} == {"live-0", "live-1"}
    assert sorted(data) == sorted(["spec", "runs_expected", "runs_finished", "wall_seconds", "table", "external_mean",
                                   "external_sd", "runs_over_60_at_end", "detections", "latency_ms", "run_seconds",
                                   "lockstep", "machine", "runs"])
