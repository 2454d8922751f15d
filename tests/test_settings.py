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
from coevo.tasks import get_task
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


def _saved_before_rounds_6_and_7() -> dict:
    """A GAConfig as runs saved it before symmetric rules and docking_target_sensors existed."""
    ga = GAConfig(max_rules=48).model_dump(mode="json")
    del ga["symmetric_rules"], ga["docking_target_sensors"]
    return ga


def test_a_run_saved_before_a_ga_setting_existed_resumes_and_replays_as_it_learned(tmp_path: Path) -> None:
    """run.json, worker.json and a resumed worker's check all read a saved GA as the run learned: Docking's rules
    plain and on the Target's sensors; a run saved today keeps today's settings."""
    from coevo.agents.checkpoint import prepare_dir
    from coevo.config import SAVED_GA_BEFORE
    from coevo.rundir.layout import WorkerPaths

    old = _saved_before_rounds_6_and_7()
    (tmp_path / "old.json").write_text(json.dumps({"run": "old", "regime": "independent", "ga": old}))
    RunSettings.make(run="new", regime="independent").save(tmp_path / "new.json")
    then, now = RunSettings.load(tmp_path / "old.json").ga, RunSettings.load(tmp_path / "new.json").ga
    assert (then.symmetric_rules, then.docking_target_sensors, then.max_rules) == (False, True, 48)
    assert (now.symmetric_rules, now.docking_target_sensors) == (None, False)  # None: the task's choice
    get_task("fuel").check_ga(then)  # plain 48-rule Docking, as it learned: no symmetric-rule refusal

    w = WorkerPaths(tmp_path / "worker")
    w.dir.mkdir()
    meta = {"run": "old", "behaviour": "docking", "worker": "docking-1", "seed": 1, "task": "fuel",
            "regime": "independent", "model": "best", "max_lead": 1, "world": {}, "ga": old}
    (w.worker_json).write_text(json.dumps(meta))
    assert w.meta()["ga"] == then.model_dump(mode="json")  # what coevo replay builds its GA from
    resumed = {**meta, "ga": then.model_dump(mode="json")}
    prepare_dir(w.dir, what="worker", meta_file=w.worker_json, meta=resumed, logs=[], checkpoint=w.checkpoint,
                resume=True, saved_defaults={"ga": SAVED_GA_BEFORE})
    with pytest.raises(ConfigError, match="ga was"):  # resumed under today's defaults: refused, as any other change
        prepare_dir(w.dir, what="worker", meta_file=w.worker_json, meta={**meta, "ga": now.model_dump(mode="json")},
                    logs=[], checkpoint=w.checkpoint, resume=True, saved_defaults={"ga": SAVED_GA_BEFORE})


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
