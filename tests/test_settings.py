"""Run settings are written once (run.json) and loaded by every process of the run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from coevo.config import GAConfig
from coevo.errors import ConfigError, RunDirError
from coevo.rundir.settings import RunSettings
from coevo.tasks.fuel.settings import WorldConfig


def test_settings_round_trip_through_run_json_with_the_world_in_full(tmp_path: Path) -> None:
    s = RunSettings.make(run="r1", regime="mutual", seed=7, world={"target_speed": 3}, ga=GAConfig(population=8))
    assert s.world == WorldConfig(target_speed=3).model_dump(mode="json")
    s.save(tmp_path / "run.json")
    back = RunSettings.load(tmp_path / "run.json")
    assert back == s and back.world_config() == WorldConfig(target_speed=3)
    assert [back.worker_seed(b) for b in ("tracking", "docking", "executive")] == [7, 8, 9]


@pytest.mark.parametrize("values,needle", [
    ({"run": "..", "regime": "mutual"}, "'..'"),
    ({"run": "a", "regime": "sideways"}, "'sideways'"),
    ({"run": "a", "regime": "mutual", "task": "maze"}, "'maze'"),
    ({"run": "a", "regime": "mutual", "seed": -1}, "seed=-1"),
    ({"run": "a", "regime": "mutual", "max_lead": -2}, "max_lead=-2"),
    ({"run": "a", "regime": "mutual", "world": {"arena": "big"}}, "arena='big'"),
    ({"run": "a", "regime": "mutual", "world": {"no_such": 1}}, "no_such"),
])
def test_bad_settings_name_the_bad_value(values: dict, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle):
        RunSettings.make(**values)


def test_a_run_json_from_before_settings_were_versioned_still_loads(tmp_path: Path) -> None:
    old = {"run": "old", "regime": "independent", "seed": 0, "model": "best", "max_lead": 1, "endpoint": "tcp/127.0.0.1:1",
           "world": WorldConfig().model_dump(), "ga": GAConfig().model_dump(), "started": 1.0}
    (tmp_path / "run.json").write_text(json.dumps(old))
    s = RunSettings.load(tmp_path / "run.json")
    assert s.task == "fuel" and s.settings_version == 1


def test_a_run_json_from_before_docking_left_the_target_sensors_out_keeps_them(tmp_path: Path) -> None:
    """A run made before the setting resumes as it learned: its Docking conditioned on the Target's sensors."""
    ga = GAConfig().model_dump()
    del ga["docking_target_sensors"]
    (tmp_path / "old.json").write_text(json.dumps({"run": "old", "regime": "independent", "ga": ga}))
    RunSettings.make(run="new", regime="independent").save(tmp_path / "new.json")
    assert RunSettings.load(tmp_path / "old.json").ga.docking_target_sensors is True
    assert RunSettings.load(tmp_path / "new.json").ga.docking_target_sensors is False


@pytest.mark.parametrize("text", ["{not json", "[1, 2]", json.dumps({"run": "x"})])
def test_a_broken_run_json_is_a_run_dir_error_naming_the_file(tmp_path: Path, text: str) -> None:
    f = tmp_path / "run.json"
    f.write_text(text)
    with pytest.raises(RunDirError, match="run.json"):
        RunSettings.load(f)


def test_a_worker_given_settings_refuses_flags_that_would_contradict_them(tmp_path: Path) -> None:
    f = tmp_path / "run.json"
    RunSettings.make(run="r", regime="mutual").save(f)
    r = subprocess.run([sys.executable, "-m", "coevo", "worker", "--settings", str(f), "--behaviour", "tracking",
                        "--regime", "independent", "--generations", "3"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "drop --regime, --generations" in r.stderr and "Traceback" not in r.stderr
