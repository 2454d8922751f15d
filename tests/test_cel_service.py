"""The CEL architecture as a live service (issue 17): real broker, learner and execution processes on loopback.

* A live run with max-lead 0 is the lockstep run of the same seed, exactly (curve, external
  performance, rules versions, the change and when the learner took it), and replays.
* Either process killed with SIGKILL and restarted with ``--resume``: the run ends complete,
  every generation's trials played once, the learner's curve whole and replayable.
* The case base lives in the broker's store; a later run starts from it (``--cases-from``).
* The wire: malformed or foreign capability lists, cases and execution heartbeats are refused
  and named; bad command lines end in one line.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from procs import coevo_main, coevo_proc, poll, stop

from coevo.bus import keys
from coevo.bus.auth import RunKey
from coevo.bus.messages import CapabilityUpdate, CaseUpdate, ExecutionStatus, encode
from coevo.bus.session import open_session
from coevo.bus.status import StatusBoard
from coevo.cel.experiment import run_cel
from coevo.cel_service.run import CelRun
from coevo.errors import MessageError
from coevo.runs.check import check_run
from coevo.rundir.layout import read_cases, read_jsonl
from coevo.runs.local import free_port
from coevo.runs.replay import replay
from coevo.rundir.settings import RunSettings
from coevo.tasks.door import default_ruleset, door_ga

pytestmark = pytest.mark.service  # starts brokers, workers or whole runs as processes: run with --all

FAILED = ("front", "front_right", "right")
SMALL = ["--population", "16", "--episodes", "20", "--ga", "best_episodes=20"]


def _cel(tmp_path: Path, *args: str, timeout: float = 240) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", "cel", "--root", str(tmp_path), "--quiet", *args],
                          capture_output=True, text=True, timeout=timeout)


def test_a_live_run_is_the_lockstep_run_exactly_and_replays(tmp_path: Path) -> None:
    r = _cel(tmp_path, "--run", "live", "--generations", "6", "--fail", "3:front,front_right,right", *SMALL, "--seed", "2")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "detected after 1 trials" in r.stdout and "learner on the new model from generation 4" in r.stdout
    run = tmp_path / "live"
    lock = run_cel(2, generations=6, events=((3, FAILED),),
                   ga=door_ga(population=16, episodes=20, best_episodes=20, generations=6))
    perf = read_jsonl(run / "execution" / "performance.jsonl")
    assert [p["external"] for p in perf] == [row["external"] for row in lock["rows"]]
    assert [max(p["rules_versions"]) for p in perf] == [row["rules_version"] for row in lock["rows"]]
    curve = read_jsonl(run / "workers" / "door" / "curve.jsonl")
    assert [c["success"] for c in curve] == [row["simulated"] for row in lock["rows"][1:]]
    taken = read_jsonl(run / "workers" / "door" / "changes.jsonl")
    assert [(c["generation"] + 1, c["capabilities"]) for c in taken] == \
        [(c["learner_from"], c["capabilities"]) for c in lock["changes"]]
    report = json.loads((run / "cel.json").read_text())
    assert report["detections"][0]["detected"] and report["detections"][0]["generations"] == 0
    assert report["latency_ms"]["median"] > 0
    assert (run / "performance.csv").read_text().count("\n") == 8  # header + generations 0..6
    assert [(w.behaviour, w.reproduced) for w in replay(run)] == [("door", True), ("execution", True)]
    assert check_run(run, replay=False).ok  # the rest of coevo check: its replay is the one just above
    # The robot's log is its replay: take a rule set a generation later than it did, and replay says where it differs.
    taken = read_jsonl(run / "execution" / "policies.jsonl")
    taken[-1]["first_trial"] += 100
    (run / "execution" / "policies.jsonl").write_text("".join(json.dumps(p) + "\n" for p in taken))
    differs = next(w for w in replay(run) if w.behaviour == "execution")
    assert not differs.reproduced and differs.first_mismatch == taken[-1]["first_trial"] // 100 - 1, differs


@pytest.mark.slow
def test_either_process_killed_and_resumed_loses_nothing(tmp_path: Path) -> None:
    # 12 generations, the failure at 5: the robot killed before it (at its third), the learner after it (at 7), each
    # with generations left (24, the failure at 10 and population 24 checked the same at twice the CPU).
    ga = door_ga(generations=12, population=16, episodes=20, best_episodes=20)
    settings = RunSettings.make(run="kills", task="door", regime="independent", seed=1, max_lead=0, ga=ga,
                                cel={"schedule": [[5, list(FAILED)]]})
    lr = CelRun(settings, root=tmp_path, log_level="INFO")
    lr.create()
    lr.start(resume=False)
    perf = lr.paths.execution.performance
    curve = lr.paths.worker("door").curve
    n = lambda f: len(f.read_text().splitlines()) if f.exists() else 0  # noqa: E731
    try:
        with open_session(lr.client_config(), gate=lr.gate()) as s:
            board = StatusBoard(s, "kills")
            poll(lambda: n(perf) >= 3, 120, "the robot's third generation")
            os.kill(lr.workers["execution"].pid, signal.SIGKILL)
            poll(lambda: any(r["state"] == "dead" for r in board.robots_view()), 5, "the robot shown dead")
            lr.workers["execution"].wait()
            lr.start_worker("execution", resume=True)
            poll(lambda: n(curve) >= 7, 120, "the learner past the failure")
            os.kill(lr.workers["door"].pid, signal.SIGKILL)
            lr.workers["door"].wait()
            time.sleep(0.5)
            lr.start_worker("door", resume=True)
            poll(lambda: not lr.workers_running(), 300, "the run to finish")
            board.close()
    finally:
        lr.end_all()
    assert all(p.returncode == 0 for p in lr.workers.values()), {b: p.returncode for b, p in lr.workers.items()}
    assert "resumed at trial" in lr.paths.log("execution").read_text()
    assert "resumed after generation" in lr.paths.log("worker-door").read_text()
    assert [r["generation"] for r in read_jsonl(perf)] == list(range(13))  # every generation's trials, once
    assert [r["generation"] for r in read_jsonl(curve)] == list(range(1, 13))
    changes = read_jsonl(lr.paths.execution.changes)
    assert changes and changes[0]["matches_world"] and changes[0]["trial"] >= 500
    assert read_jsonl(lr.paths.worker("door").changes), "the learner took the change"
    assert [(w.behaviour, w.reproduced) for w in replay(lr.dir)] == [("door", True), ("execution", True)]
    check = check_run(lr.dir, replay=False)  # the rest of coevo check: its replay is the one just above
    assert check.ok, check.problems


@pytest.mark.slow
def test_the_case_base_is_in_the_store_and_a_later_run_starts_from_it(tmp_path: Path) -> None:
    r = _cel(tmp_path, "--run", "first", "--generations", "8", "--fail", "2:front,front_right,right", "--fail", "4:",
             "--fail", "6:front,front_right,right", "--case-base", *SMALL)
    assert r.returncode == 0, r.stdout + r.stderr
    first = tmp_path / "first"
    stored = read_cases(first / "store" / "cases" / "door.jsonl")
    own = read_cases(first / "workers" / "door" / "cases.jsonl")
    assert len(stored) == 3 and [c.version for c in stored] == [1, 2, 3]  # one per change: failure, repair, failure
    assert [c.rules for c in stored] == [c.rules for c in own]
    assert [c.capabilities for c in stored][1] == ["far_left", "left", "front_left", "far_right"]
    restarts = read_jsonl(first / "workers" / "door" / "changes.jsonl")
    assert restarts[-1]["restart_cases"][0]["capabilities"] == ["far_left", "left", "front_left", "far_right"]
    assert [(w.behaviour, w.reproduced) for w in replay(first)] == [("door", True), ("execution", True)]

    r = _cel(tmp_path, "--run", "second", "--generations", "3", "--fail", "1:front,front_right,right",
             "--cases-from", str(first), *SMALL)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "3 cases from" in r.stdout
    found = read_cases(tmp_path / "second" / "workers" / "door" / "cases.jsonl")
    assert [c.origin for c in found[:3]] == ["first"] * 3
    restart = read_jsonl(tmp_path / "second" / "workers" / "door" / "changes.jsonl")[0]
    assert restart["restart_cases"][0]["rules"] == stored[0].rules or \
        restart["restart_cases"][0]["capabilities"] == ["far_left", "left", "front_left", "far_right"]
    assert [(w.behaviour, w.reproduced) for w in replay(tmp_path / "second")] == [("door", True), ("execution", True)]


def test_the_wire_refuses_foreign_and_malformed_cel_messages(tmp_path: Path) -> None:
    settings = RunSettings.make(run="w", task="door", regime="independent", cel={}).with_roster()
    key = RunKey.create("w")
    gate = settings.gate(key)
    now = time.time()
    caps = CapabilityUpdate(run="w", robot="robot", change=1, trial=5, decision=2, capabilities=["front"], sent_at=now)
    k = keys.capabilities("w", "robot")
    assert gate.decode(k, gate.seal(caps, k)) == caps
    other = caps.model_copy(update={"robot": "robot-2"})
    k2 = keys.capabilities("w", "robot-2")
    with pytest.raises(MessageError, match="not_roster"):
        gate.decode(k2, gate.seal(other, k2))
    with pytest.raises(MessageError, match="wrong_behaviour"):  # a robot's message on another robot's key
        gate.decode(k2, gate.seal(caps, k2))
    with pytest.raises(MessageError, match="unauthenticated"):
        gate.decode(k, encode(caps))
    status = ExecutionStatus(run="w", robot="robot", trial=1, trials=10, generation=0, performance=50, rules_version=0,
                             capabilities=["front"], changes=0, sent_at=now)
    with pytest.raises(MessageError, match="wrong_key"):  # a heartbeat on the capabilities key
        gate.decode(k, gate.seal(status, k))
    rules = default_ruleset().to_dict()
    case = CaseUpdate(run="w", behaviour="door", worker="door-0", version=1, generation=3, fitness=0.5,
                      capabilities=["left"], rules=rules, sent_at=now)
    ck = keys.case("w", "door")
    assert gate.decode(ck, gate.seal(case, ck)) == case
    with pytest.raises(MessageError, match="not_roster"):
        forged = case.model_copy(update={"worker": "door-9"})
        gate.decode(ck, gate.seal(forged, ck))
    bad = {**case.model_dump(mode="json"), "rules": {**rules, "lo": [[0]]}}
    with pytest.raises(MessageError, match="bad_rules"):
        import msgpack

        from coevo.bus import auth

        gate.decode(ck, auth.seal(msgpack.packb(bad), ck, key.secret))
    with pytest.raises(ValueError):
        CapabilityUpdate(run="w", robot="robot", change=1, trial=5, decision=2, capabilities=["front", "front"], sent_at=now)


@pytest.mark.parametrize("argv, says", [
    (["--fail", "x"], "invalid failure 'x'"),
    (["--fail", "5:nose"], "unknown sonar 'nose'"),
    (["--fail", "200:front"], "after the run's 100 generations"),
    (["--fail", "5:front", "--fail", "3:"], "must increase"),
    (["--cases-from", "/nonexistent/run"], "not a run directory"),
    (["--resume", "/nonexistent/run", "--generations", "5"], "--generations"),
    (["--zero-run", "0"], "invalid number 0"),
])
def test_bad_cel_command_lines_end_in_one_line(tmp_path: Path, argv: list[str], says: str) -> None:
    r = coevo_main("cel", "--root", str(tmp_path), "--quiet", *argv)  # refused before anything starts: in process
    assert r.returncode == 2, r.stdout + r.stderr
    assert says in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "Traceback" not in r.stderr


def test_execution_refuses_a_run_that_is_not_a_cel_run(tmp_path: Path) -> None:
    RunSettings.make(run="plain", task="door", regime="independent").save(tmp_path / "run.json")
    r = coevo_main("execution", "--settings", str(tmp_path / "run.json"), "--connect-timeout", "0")
    assert r.returncode == 2 and "cel block" in r.stderr, r.stderr


@pytest.mark.slow
def test_a_killed_broker_loses_no_case_and_a_whole_run_killed_at_once_resumes(tmp_path: Path) -> None:
    """The broker dies after the learner stored a case, and its store comes back without it (a write lost): the
    learner puts its cases again when a broker appears.  Then the whole run dies at once, and coevo cel --resume
    finishes it."""
    # 10 generations, changes at 2, 4 and 6 (three cases, as the case-base test's run): killed whole at 7, three left
    # (14 with changes at 3, 6 and 9 checked the same).
    ga = door_ga(generations=10, population=16, episodes=20, best_episodes=20)
    settings = RunSettings.make(run="outage", task="door", regime="independent", seed=3, max_lead=0, ga=ga,
                                cel={"schedule": [[2, list(FAILED)], [4, []], [6, list(FAILED)]], "case_base": True})
    lr = CelRun(settings, root=tmp_path, log_level="INFO")
    lr.create()
    lr.start(resume=False)
    cases = lr.paths.worker("door").cases
    curve = lr.paths.worker("door").curve
    n = lambda f: len(f.read_text().splitlines()) if f.exists() else 0  # noqa: E731
    try:
        # In the broker's store, not only in the learner's own file: killed before it had written it, the broker left
        # no store file to take away (and the test failed on the unlink below, once, in a full run).
        poll(lambda: n(cases) >= 1 and n(lr.paths.case_file("door")) >= 1, 120, "the learner's first case, stored")
        lr.broker.send_signal(signal.SIGKILL)
        lr.broker.wait()
        lr.paths.case_file("door").unlink()  # the store lost the case
        time.sleep(1.0)
        lr.start_broker()
        poll(lambda: n(curve) >= 7, 120, "the learner past generation 7")
    finally:
        lr.end_all()  # the whole run at once (SIGTERM, as a machine shutting down would)
    r = _cel(tmp_path, "--resume", str(lr.dir))
    assert r.returncode == 0, r.stdout + r.stderr
    summary = json.loads((lr.dir / "summary.json").read_text())
    assert summary["resumed"] is True and not summary["interrupted"]
    stored = read_cases(lr.paths.case_file("door"))
    assert [c.version for c in stored] == sorted(c.version for c in stored) and len(stored) == 3, stored
    check = check_run(lr.dir)  # every case in the store, every generation's trials once, replay exact
    assert check.ok, check.problems


def test_prepare_then_three_processes_started_by_hand_make_a_complete_run(tmp_path: Path) -> None:
    """coevo cel --prepare, then the broker, the robot and the learner started as on three hosts (deploy/README.md):
    each process finds its key and its directory beside run.json."""
    r = _cel(tmp_path, "--run", "p1", "--prepare", "--generations", "4", "--fail", "2:front", *SMALL, timeout=60)
    assert r.returncode == 0, r.stderr
    run = tmp_path / "p1"
    settings = RunSettings.load(run / "run.json")
    assert settings.block("cel") is not None and settings.roster == {"door": "door-0"} and (run / "secret.key").exists()
    assert "coevo execution --settings" in r.stdout and "coevo worker --behaviour door --settings" in r.stdout
    assert not (run / "logs").exists()  # nothing started
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    broker = coevo_proc("broker", "--data-dir", str(tmp_path), "--listen", endpoint, log=tmp_path / "broker.log")
    try:
        robot = coevo_proc("execution", "--settings", str(run / "run.json"), "--connect", endpoint,
                           log=tmp_path / "robot.log")
        learner = coevo_proc("worker", "--behaviour", "door", "--settings", str(run / "run.json"), "--connect", endpoint,
                             log=tmp_path / "learner.log")
        assert learner.wait(timeout=120) == 0 and robot.wait(timeout=60) == 0, (tmp_path / "robot.log").read_text()
    finally:
        stop(broker)
    check = check_run(run)
    assert check.ok and check.facts["execution"]["generations"] == 5, check.problems


@pytest.mark.slow
def test_coevo_chaos_on_a_cel_run_kills_either_module_and_the_run_comes_out_complete(tmp_path: Path) -> None:
    # 10 generations (16 before): the faults come 0.3-1 s apart from the start, so two of them need only seconds of a
    # run that lasts tens; fewer generations cut the run and coevo check's replay of it.
    r = subprocess.run([sys.executable, "-m", "coevo", "chaos", "--learner", "cel", "--run", "cc", "--root", str(tmp_path), "--seed",
                        "5", "--generations", "10", *SMALL, "--faults", "4", "--kinds", "kill-worker", "kill-broker",
                        "--gap", "0.3", "1.0", "--down", "0.3", "1.0", "--measure-epochs", "1"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads((tmp_path / "cc" / "chaos.json").read_text())
    assert report["complete"] and sum(report["faults"].values()) >= 2, report
    assert report["facts"]["execution"]["generations"] == 11 and report["facts"]["door"]["generations"] == 10


@pytest.mark.slow
def test_a_robot_resumed_after_its_learner_finished_plays_out_its_trials(tmp_path: Path) -> None:
    """Found by coevo chaos --learner cel: the robot waited for ever for a learner that had finished while it was down."""
    # 7 generations, the failure at 4, the robot killed at its third: the learner finishes 4 without it (10 and 5
    # checked the same).
    ga = door_ga(generations=7, population=16, episodes=20, best_episodes=20)
    settings = RunSettings.make(run="late", task="door", regime="independent", seed=4, max_lead=0, ga=ga,
                                cel={"schedule": [[4, list(FAILED)]], "patience": 1.5})
    lr = CelRun(settings, root=tmp_path, log_level="INFO")
    lr.create()
    lr.start(resume=False)
    perf = lr.paths.execution.performance
    try:
        poll(lambda: perf.exists() and len(perf.read_text().splitlines()) >= 3, 120, "the robot's third generation")
        os.kill(lr.workers["execution"].pid, signal.SIGKILL)
        lr.workers["execution"].wait()
        assert lr.workers["door"].wait(timeout=120) == 0  # the learner waited 1.5 s for it, then learned on alone
        t0 = time.monotonic()
        lr.start_worker("execution", resume=True)
        assert lr.workers["execution"].wait(timeout=120) == 0
        assert time.monotonic() - t0 < 60
    finally:
        lr.end_all()
    assert [r["generation"] for r in read_jsonl(perf)] == list(range(8))
    check = check_run(lr.dir)
    assert check.ok, check.problems
