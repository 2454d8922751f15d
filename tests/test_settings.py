"""Run settings are written once (run.json) and loaded by every process of the run."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from coevo.config import GAConfig
from coevo.errors import ConfigError, RunDirError
from coevo.rundir.settings import RunSettings
from coevo.tasks import get_task
from coevo.tasks.base import check_ga
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
    """The GA settings as runs saved them before symmetric rules and docking_target_sensors existed (Docking's other
    settings among them: they were GA settings until issue 41)."""
    ga = GAConfig(max_rules=48).model_dump(mode="json")
    del ga["symmetric_rules"]
    return {**ga, "docking_fresh_starts": True, "docking_sensors": "both"}


def test_a_run_saved_before_a_ga_setting_existed_resumes_and_replays_as_it_learned(tmp_path: Path) -> None:
    """run.json, worker.json and a resumed worker's check all read saved settings as the run learned: Docking's rules
    plain and on the Target's sensors; a run saved today keeps today's settings."""
    from coevo.agents.checkpoint import prepare_dir
    from coevo.agents.worker import _saved_meta
    from coevo.rundir.layout import WorkerPaths

    old = _saved_before_rounds_6_and_7()
    (tmp_path / "old.json").write_text(json.dumps({"run": "old", "regime": "independent", "ga": old}))
    RunSettings.make(run="new", regime="independent").save(tmp_path / "new.json")
    then, now = RunSettings.load(tmp_path / "old.json"), RunSettings.load(tmp_path / "new.json")
    assert (then.ga.symmetric_rules, then.world_config().docking_target_sensors, then.ga.max_rules) == (False, True, 48)
    assert (now.ga.symmetric_rules, now.world_config().docking_target_sensors) == (None, False)  # None: the task's
    check_ga(get_task("fuel"), then.ga)  # plain 48-rule Docking, as it learned: no symmetric-rule refusal

    w = WorkerPaths(tmp_path / "worker")
    w.dir.mkdir()
    world = {k: v for k, v in WorldConfig().model_dump(mode="json").items() if not k.startswith("docking_")}
    meta = {"run": "old", "behaviour": "docking", "worker": "docking-1", "seed": 1, "task": "fuel",
            "regime": "independent", "model": "best", "max_lead": 1, "world": world, "ga": old}
    (w.worker_json).write_text(json.dumps(meta))
    assert w.meta()["ga"] == then.ga.model_dump(mode="json")  # what coevo replay builds its GA from
    assert WorldConfig(**w.meta()["world"]) == then.world_config()  # and its world
    resumed = {**meta, "ga": then.ga.model_dump(mode="json"), "world": then.world}
    prepare_dir(w.dir, what="worker", meta_file=w.worker_json, meta=resumed, logs=[], checkpoint=w.checkpoint,
                resume=True, saved=_saved_meta)
    with pytest.raises(ConfigError, match="ga was"):  # resumed under today's defaults: refused, as any other change
        prepare_dir(w.dir, what="worker", meta_file=w.worker_json, meta={**resumed, "ga": now.ga.model_dump(mode="json")},
                    logs=[], checkpoint=w.checkpoint, resume=True, saved=_saved_meta)


def _saved_before_issue_41(tmp_path: Path) -> tuple[dict, dict]:
    """run.json and worker.json as runs saved them while Docking's settings were GA settings (issue 41 moved them
    to the fuel task's world), with every one of them away from today's default."""
    ga = {**GAConfig().model_dump(mode="json"),
          "docking_fresh_starts": False, "docking_sensors": "polar", "docking_target_sensors": True}
    world = {k: v for k, v in WorldConfig().model_dump(mode="json").items() if not k.startswith("docking_")}
    run = {"settings_version": 1, "run": "old41", "task": "fuel", "regime": "independent", "seed": 0, "model": "best",
           "max_lead": 1, "world": world, "ga": ga}
    worker = {"coevo": "0", "task": "fuel", "behaviour": "docking", "regime": "independent", "run": "old41",
              "worker": "docking-1", "seed": 1, "model": "best", "max_lead": 1, "world": world, "ga": ga}
    return run, worker


def test_a_run_saved_while_dockings_settings_were_ga_settings_reads_them_as_world_settings(tmp_path: Path) -> None:
    """Docking's settings moved from the GA's to the fuel world's (issue 41): a run saved before loads with them in
    its world, its workers resume against their worker.json, and its comparison's compare.json still matches."""
    from coevo.agents.checkpoint import prepare_dir
    from coevo.agents.worker import _saved_meta
    from coevo.experiments.compare.experiment import CompareSpec, prepare
    from coevo.rundir.layout import WorkerPaths

    run, worker = _saved_before_issue_41(tmp_path)
    (tmp_path / "run.json").write_text(json.dumps(run))
    s = RunSettings.load(tmp_path / "run.json")
    w = s.world_config()
    assert (w.docking_fresh_starts, w.docking_sensors, w.docking_target_sensors) == (False, "polar", True)
    assert s.ga == GAConfig()  # nothing else changed
    wp = WorkerPaths(tmp_path / "docking")
    wp.dir.mkdir()
    wp.worker_json.write_text(json.dumps(worker))
    assert wp.meta()["world"] == s.world and wp.meta()["ga"] == s.ga.model_dump(mode="json")
    now = {**worker, "world": s.world, "ga": s.ga.model_dump(mode="json")}  # what the resumed worker writes today
    prepare_dir(wp.dir, what="worker", meta_file=wp.worker_json, meta=now, logs=[], checkpoint=wp.checkpoint,
                resume=True, saved=_saved_meta)
    # a comparison made then: its compare.json is the same comparison as the one asked for today
    spec = CompareSpec.make(runs=1, world=s.world, ga=s.ga)
    held = json.loads(spec.model_dump_json())
    held["world"], held["ga"] = run["world"], {**held["ga"], **{k: v for k, v in run["ga"].items() if "docking" in k}}
    (tmp_path / "cmp").mkdir()
    (tmp_path / "cmp" / "compare.json").write_text(json.dumps({"spec": held, "created": 0.0}))
    (tmp_path / "cmp" / "runs").mkdir()
    assert prepare(tmp_path / "cmp", spec, resume=True)
    assert CompareSpec.model_validate(held) == spec  # as the dashboard reads it


def test_a_comparison_saved_before_a_world_setting_existed_resumes_as_it_ran(tmp_path: Path) -> None:
    """compare.json holds the settings of its day: a world setting added since is read at its value from before
    (saved_before) or its default, so --resume takes the comparison back instead of calling it a different one
    (it compared the raw dicts, so any world setting added after a comparison was saved refused its resume)."""
    from coevo.experiments.compare.experiment import CompareSpec, prepare

    spec = CompareSpec.make(runs=1)
    held = json.loads(spec.model_dump_json())
    assert "target_speed" not in WorldConfig.saved_before and "docking_target_sensors" in WorldConfig.saved_before
    del held["world"]["target_speed"]  # a setting with no value from before: its default
    out = tmp_path / "cmp"
    (out / "runs").mkdir(parents=True)
    (out / "compare.json").write_text(json.dumps({"spec": held, "created": 0.0}))
    assert prepare(out, spec, resume=True)
    assert CompareSpec.saved(held) == spec  # as the dashboard reads it

    del held["world"]["docking_target_sensors"]  # saved before Round 7: it learned with the Target's sensors
    (out / "compare.json").write_text(json.dumps({"spec": held, "created": 0.0}))
    with pytest.raises(RunDirError, match="differs in: world"):
        prepare(out, spec, resume=True)
    assert prepare(out, CompareSpec.make(runs=1, world={"docking_target_sensors": True}), resume=True)

    # what is not a comparison's settings is refused in one line naming the bad value itself
    for spec_json, needle in (({**held, "world": {"arena": "big"}}, "world settings of the fuel task: arena='big'"), ([1, 2], "got list")):
        (out / "compare.json").write_text(json.dumps({"spec": spec_json, "created": 0.0}))
        with pytest.raises(RunDirError, match=re.escape(needle)) as said:
            prepare(out, spec, resume=True)
        assert "\n" not in str(said.value)


def test_dockings_settings_given_as_ga_settings_are_still_read_as_world_settings() -> None:
    from coevo.tasks import split_settings

    fuel = get_task("fuel")
    assert split_settings(fuel, {"arena": 200}, {"docking_sensors": "polar", "population": 8}) == (
        {"arena": 200, "docking_sensors": "polar"}, {"population": 8})
    with pytest.raises(ConfigError, match="--world docking_sensors"):
        split_settings(fuel, {"docking_sensors": "both"}, {"docking_sensors": "polar"})
    with pytest.raises(ConfigError, match="docking_sensors"):  # the door task has no such setting
        RunSettings.make(run="d", task="door", regime="independent", ga={"docking_sensors": "polar"})


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


def test_a_worker_resumed_before_its_first_start_made_anything_starts_with_empty_logs(tmp_path: Path) -> None:
    """Seen in a study: a worker died at import (exit 1, twice), then coevo run --resume found its directory with no
    worker.json and no logs, wrote worker.json and stopped at its first checkpoint, which measures every log."""
    from coevo.agents.checkpoint import prepare_dir
    from coevo.rundir.layout import WorkerPaths

    w = WorkerPaths(tmp_path / "w")
    logs = [w.dir / n for n in WorkerPaths.LOGS]
    for before in ("nothing", "its settings"):
        if before == "its settings":  # it got as far as worker.json, and one log, before it died
            for f in logs:
                f.unlink()
            logs[0].write_text("")
        prepare_dir(w.dir, what="worker", meta_file=w.worker_json, meta={"run": "r"}, logs=logs, checkpoint=w.checkpoint,
                    resume=True)
        assert all(f.exists() and f.stat().st_size == 0 for f in logs), before
        assert json.loads(w.worker_json.read_text()) == {"run": "r"}


def test_a_run_json_of_the_code_before_kinds_were_plugins_loads_as_it_ran(tmp_path: Path) -> None:
    """Before kinds were found by name, every run.json held a "cel" key, null for a co-evolution run: such a run
    loads as a co-evolution run (it was refused as a CEL run of the wrong task), and a CEL run's block still loads
    as the CEL kind's settings; saved again, neither gains nor loses a key but the null."""
    from coevo.cel_service.kind import CEL
    from coevo.rundir.settings import RunSettings
    from coevo.runs.kinds import COEVOLUTION, kind_of_settings

    fuel = RunSettings.make(run="old", regime="mutual").model_dump(mode="json") | {"cel": None}
    (tmp_path / "fuel.json").write_text(json.dumps(fuel))
    loaded = RunSettings.load(tmp_path / "fuel.json")
    assert kind_of_settings(loaded) is COEVOLUTION and loaded.blocks == {}
    assert set(loaded.model_dump(mode="json")) == set(fuel) - {"cel"}
    door = RunSettings.make(run="oldcel", task="door", regime="independent", cel={"schedule": [[2, ["front"]]]})
    saved = door.model_dump(mode="json")
    assert saved["cel"]["schedule"] == [[2, ["front"]]] and "blocks" not in saved
    (tmp_path / "door.json").write_text(json.dumps(saved))
    again = RunSettings.load(tmp_path / "door.json")
    assert kind_of_settings(again) is CEL and again.block("cel") == door.block("cel")
