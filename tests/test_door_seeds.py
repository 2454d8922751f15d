"""coevo seeds --task door: the door traversal of Appendix B over seeds, through the replicate runner.

Tiny: 2 seeds of 2 + 2 generations, population 4.  With --jobs 1 the seeds run in this process (the fast set);
--jobs 2 (a pool of processes) and --cluster local:2 (Dask) give the very same numbers: each seed is one
process's deterministic computation.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from coevo.cli import main

TINY = ["seeds", "--task", "door", "--seeds", "2", "--generations", "2", "--ga", "population=4", "--ga", "episodes=4",
        "--quiet"]
FILES = {"report.md", "summary.json", "seeds.csv", "figure3.png", "figure4.png", "figure5.png", "door-seeds.json"}
KEYS = ("default", "all_sonars", "drop", "adapted")


def _numbers(out: Path) -> list[dict]:
    assert FILES <= {p.name for p in out.iterdir()}, sorted(p.name for p in out.iterdir())
    data = json.loads((out / "summary.json").read_text())
    s = data["summary"]
    assert s["runs_finished"] == s["runs_expected"] == 2
    assert all(0 <= s["mean_success_1000_trials"][k] <= 100 for k in KEYS)
    assert s["report"] == {"default": 25.0, "all_sonars": 63.0, "drop": 37.0, "adapted": 60.0}
    for r in data["runs"]:
        assert len(r["external_100"]) == 2 * 2 + 2 and all(0 <= x <= 100 for x in r["external_100"])
        assert all(t >= 0 for t in r["ga_seconds"])
    assert "| that best with front, front_right, right failed |" in (out / "report.md").read_text()
    assert len((out / "seeds.csv").read_text().splitlines()) == 3
    return [{k: r[k] for k in ("seed", *KEYS, "external_100", "best_adapted")} for r in data["runs"]]


def test_the_door_over_seeds_writes_its_report_here(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "door"
    assert main([*TINY, "--out", str(out)]) == 0
    assert "(report 63 %)" in capsys.readouterr().out
    _numbers(out)
    assert main([*TINY, "--out", str(out), "--resume"]) == 0  # every seed finished: nothing runs again
    assert main([*TINY[:-1], "--generations", "3", "--out", str(out), "--resume"]) == 2  # another experiment


@pytest.mark.parametrize("argv, needle", [
    (["--task", "door", "--behaviours", "docking"], "--behaviours: not a setting of --task door"),
    (["--learn-arg=--generations=2", "--task", "door"], "--learn-arg: not a setting of --task door"),
    (["--fail", "front"], "--fail: not a setting of --task fuel"),
    (["--task", "door", "--fail", "nose"], "nose"),
    (["--task", "door", "--fail", ","], "--fail ','"),
    (["--task", "door", "--fail", ""], "--fail ''"),
    (["--task", "door", "--world", "sonar_noise=nan"], "sonar_noise"),
    (["--ga", "specialise_fraction=2"], "specialise_fraction=2"),  # --task fuel checks them before anything runs
    (["--world", "arena=-5"], "arena=-5"),
])
def test_a_flag_of_the_other_task_or_a_bad_door_setting_is_one_line(argv: list[str], needle: str, tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    try:
        code = main(["seeds", *argv, "--quiet", "--out", str(tmp_path / "x")])
    except SystemExit as exc:  # refused by the parser (an empty value)
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ConfigError: ") and needle in err[0], err
    assert not (tmp_path / "x").exists()


@pytest.mark.service
@pytest.mark.slow
def test_a_pool_of_processes_and_a_local_dask_cluster_give_the_same_numbers(tmp_path: Path) -> None:
    got = []
    for where, flags in (("here", ["--jobs", "1"]), ("pool", ["--jobs", "2"]), ("dask", ["--cluster", "local:2"])):
        r = subprocess.run([sys.executable, "-m", "coevo", *TINY, "--out", str(tmp_path / where), *flags],
                           capture_output=True, text=True, timeout=120, check=False)
        assert r.returncode == 0, r.stdout + r.stderr
        got.append(_numbers(tmp_path / where))
    assert got[0] == got[1] == got[2]


def test_generations_world_and_ga_reach_every_coevo_learn_of_the_fuel_task(tmp_path: Path) -> None:
    out = tmp_path / "fuel"
    assert main(["seeds", "--seeds", "1", "--behaviours", "docking", "--generations", "2", "--ga", "population=4",
                 "--ga", "episodes=4", "--world", "target_speed=3", "--quiet", "--out", str(out)]) == 0
    cfg = json.loads((out / "runs" / "docking-seed0" / "config.json").read_text())
    assert (cfg["ga"]["generations"], cfg["ga"]["population"], cfg["ga"]["episodes"]) == (2, 4, 4)
    assert cfg["world"]["target_speed"] == 3
    # Settings this far below the report's are said to be, beside the verdicts; no "nan" for a measure not taken.
    summary = json.loads((out / "summary.json").read_text())
    assert summary["caveat"].startswith("These settings are below the report's: generations 2 (the report's 50), "
                                        "population 4 (the report's 50), episodes 4 (the report's 90)")
    report = (out / "report.md").read_text()
    assert summary["caveat"] in report and "nan" not in report


def test_a_resumed_coevo_seeds_runs_again_a_learning_run_left_torn(tmp_path: Path) -> None:
    # A run's folder that is there but not finished (a copy torn on its way back from a cluster's worker) is not a
    # run: coevo learn would refuse the folder, so the resume removes it and runs that seed again.
    out = tmp_path / "fuel"
    args = ["seeds", "--seeds", "2", "--behaviours", "docking", "--generations", "1", "--ga", "population=4",
            "--ga", "episodes=4", "--quiet", "--out", str(out)]
    assert main(args) == 0
    kept = (out / "runs" / "docking-seed0" / "measures.json").read_bytes()
    torn = out / "runs" / "docking-seed1"
    for f in torn.iterdir():
        if f.name != "config.json":
            f.unlink()
    assert main([*args, "--resume"]) == 0
    assert (out / "runs" / "docking-seed0" / "measures.json").read_bytes() == kept  # the finished run is not redone
    assert (torn / "measures.json").exists() and (torn / "best.rules").exists()
    assert json.loads((out / "summary.json").read_text())["runs_finished"] == 2
