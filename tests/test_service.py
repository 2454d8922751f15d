"""The service for real: broker and workers as processes, Zenoh sessions on loopback."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from procs import SMALL, coevo_main, coevo_proc, copy_of, poll, stop

from coevo.bus import keys
from coevo.bus.messages import PolicyUpdate, decode, encode
from coevo.bus.session import make_config, open_session
from coevo.bus.status import StatusBoard
from coevo.policy import random_ruleset
from coevo.runs.local import free_port

pytestmark = pytest.mark.service  # starts brokers, workers or whole runs as processes: run with --all


def test_broker_stores_answers_and_rejects(broker, tmp_path: Path) -> None:
    endpoint, data = broker
    rs = random_ruleset("tracking", 6, np.random.default_rng(0))
    msg = PolicyUpdate(run="r1", behaviour="tracking", worker="t", version=1, generation=1, fitness=0.5, episodes=10,
                       rules=rs.to_dict(), sent_at=time.time())
    with open_session(make_config(mode="client", connect=[endpoint])) as s:
        s.put(keys.policy("r1", "tracking"), b"garbage")
        s.put(keys.policy("r1", "docking"), encode(msg))  # a tracking policy on docking's key
        s.put(keys.policy("r1", "tracking"), encode(msg))
        s.put(keys.policy("r1", "tracking"), encode(msg))  # duplicate: stored once

        def latest():
            return [r.ok.payload.to_bytes() for r in s.get(keys.store_latest("r1", "tracking"), timeout=2.0) if r.ok]

        got = poll(latest, 10, "the stored policy")
        assert got == [encode(msg)]
    lines = (data / "r1" / "store" / "tracking.jsonl").read_text().splitlines()
    assert len(lines) == 1 and not (data / "r1" / "store" / "docking.jsonl").exists()
    log = (tmp_path / "broker.log").read_text()
    assert "not_msgpack" in log and "wrong_behaviour" in log


def test_late_worker_gets_partners_best_from_the_store_and_logs_adoption(broker, tmp_path: Path) -> None:
    endpoint, _ = broker
    with open_session(make_config(mode="client", connect=[endpoint])) as s:
        for beh, v in (("tracking", 3), ("docking", 2)):
            rs = random_ruleset(beh, 6, np.random.default_rng(v))
            s.put(keys.policy("late", beh), encode(PolicyUpdate(run="late", behaviour=beh, worker=f"{beh}-x", version=v,
                  generation=v, fitness=0.1 * v, episodes=10, rules=rs.to_dict(), sent_at=time.time())))
        poll(lambda: len([r for r in s.get(keys.store_latest("late"), timeout=2.0) if r.ok]) == 2, 10, "both stored")
    out = tmp_path / "exec"
    p = coevo_proc("worker", "--behaviour", "executive", "--regime", "independent", "--run", "late", "--connect", endpoint,
                   "--generations", "1", *SMALL, "--out", str(out), log=tmp_path / "w.log")
    assert p.wait(120) == 0, (tmp_path / "w.log").read_text()
    adopted = [json.loads(x) for x in (out / "adoptions.jsonl").read_text().splitlines()]
    assert {(a["partner"], a["version"], a["generation"]) for a in adopted} == {("tracking", 3, 0), ("docking", 2, 0)}


def test_status_sees_a_worker_die(broker, tmp_path: Path) -> None:
    endpoint, _ = broker
    p = coevo_proc("worker", "--behaviour", "tracking", "--regime", "independent", "--run", "die", "--connect", endpoint,
                   "--generations", "1000", *SMALL, "--out", str(tmp_path / "w"), log=tmp_path / "w.log")
    try:
        with open_session(make_config(mode="client", connect=[endpoint])) as s:
            board = StatusBoard(s, "die", stall=5.0)
            try:
                poll(lambda: [w for w in board.snapshot() if w["state"] == "alive" and w["generation"] >= 1], 60, "alive")
                os.kill(p.pid, signal.SIGKILL)
                t0 = time.monotonic()
                poll(lambda: [w for w in board.snapshot() if w["state"] == "dead"], 10, "dead")
                assert time.monotonic() - t0 < 5
            finally:
                board.close()
    finally:
        stop(p)


@pytest.mark.parametrize("regime", ["independent", "mutual"])
def test_coevo_run_end_to_end_and_replay_reproduces_it(request: pytest.FixtureRequest, regime: str) -> None:
    """A whole ``coevo run`` of each regime (the session's shared finished runs, tests/procs.py: the fixture asserts
    it ended 0) has every worker's logs and the run's measures, adopts only stored versions, and replays exactly."""
    run_dir = request.getfixturevalue(f"finished_{regime}")
    generations = {"mutual": 3, "independent": 4}[regime]  # FINISHED_MUTUAL's and FINISHED_INDEPENDENT's
    summary = json.loads((run_dir / "summary.json").read_text())
    assert set(summary["versions"]) == {"tracking", "docking", "executive"}
    assert "measures" in summary and (run_dir / "measures.json").exists()
    for beh in ("tracking", "docking", "executive"):
        w = run_dir / "workers" / beh
        assert len((w / "curve.jsonl").read_text().splitlines()) == generations
        assert (w / "best.rules").exists() and (w / "done.json").exists()
    adopters = {b for b in ("tracking", "docking", "executive") if (run_dir / "workers" / b / "adoptions.jsonl").read_text().strip()}
    # Which adoptions happen depends on scheduling (that is the point); what is adopted must be in the store.
    stored = {(json.loads(x)["behaviour"], json.loads(x)["version"]) for f in (run_dir / "store").glob("*.jsonl")
              for x in f.read_text().splitlines()}
    for b in adopters:
        for a in (run_dir / "workers" / b / "adoptions.jsonl").read_text().splitlines():
            a = json.loads(a)
            assert (a["partner"], a["version"]) in stored
    if regime == "independent":
        assert adopters <= {"executive"}  # Tracking and Docking learn with the trivial Executive
    rr = coevo_main("replay", str(run_dir))  # a reader of files: in this process
    assert rr.returncode == 0, rr.stdout + rr.stderr
    assert rr.stdout.count("reproduced exactly") == 3


def test_replay_detects_a_tampered_log(finished_mutual: Path, tmp_path: Path) -> None:
    run = copy_of(finished_mutual, tmp_path)  # the session's 3-generation Mutual run
    curve = run / "workers" / "tracking" / "curve.jsonl"
    rows = [json.loads(x) for x in curve.read_text().splitlines()]
    rows[1]["population_mean"] += 0.125
    curve.write_text("".join(json.dumps(x) + "\n" for x in rows))
    rr = coevo_main("replay", str(run))
    assert rr.returncode == 1 and "tracking: 3 generations DIFFERS at generation 2" in rr.stdout


def test_worker_with_no_broker_fails_clearly(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-m", "coevo", "worker", "--behaviour", "tracking", "--regime", "mutual", "--run", "x",
                        "--connect", f"tcp/127.0.0.1:{free_port()}", "--connect-timeout", "1", "--out", str(tmp_path / "w")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "ServiceError" in r.stderr and "broker" in r.stderr


@pytest.mark.slow
def test_executive_learns_from_a_recorded_history_at_a_rate(finished_independent: Path, tmp_path: Path) -> None:
    history = str(finished_independent)  # the session's 4-generation Independent run (read, not changed)
    outs = {}
    for rate in ("0.5", "2"):
        out = tmp_path / f"exec-{rate}"
        e = subprocess.run([sys.executable, "-m", "coevo", "learn", "--behaviour", "executive", "--history", history,
                            "--rate", rate, "--generations", "4", *SMALL, "--measure-epochs", "2", "--out", str(out), "--quiet"],
                           capture_output=True, text=True, timeout=300)
        assert e.returncode == 0, e.stderr
        outs[rate] = [json.loads(x) for x in (out / "adoptions.jsonl").read_text().splitlines()]
    for rate, rows in outs.items():
        for a in rows:  # never adopts a version from the partner's future at this rate
            assert a["partner_generation"] <= a["generation"] * float(rate)
    bad = subprocess.run([sys.executable, "-m", "coevo", "learn", "--behaviour", "executive", "--history", history,
                          "--rate", "0", "--out", str(tmp_path / "bad"), "--quiet"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "rate" in bad.stderr and not (tmp_path / "bad").exists()


def test_current_policy_model_end_to_end_replays_from_the_log(tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-m", "coevo", "run", "--regime", "mutual", "--model", "current", "--run", "cur",
                        "--root", str(tmp_path), "--generations", "4", *SMALL, "--measure-epochs", "2", "--quiet"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    run_dir = tmp_path / "cur"
    for b in ("tracking", "docking", "executive"):
        for line in (run_dir / "workers" / b / "adoptions.jsonl").read_text().splitlines():
            a = json.loads(line)
            assert 1 <= a["version"] <= 4 and "rules" in a  # versions of "current" are partner generations
    import shutil

    shutil.rmtree(run_dir / "store")  # the log alone must suffice
    (run_dir / "store").mkdir()
    rr = coevo_main("replay", str(run_dir))  # a reader of files: in this process
    assert rr.returncode == 0, rr.stdout + rr.stderr


def test_the_store_history_answers_every_version_not_only_the_latest(broker) -> None:
    """zenoh's default query consolidation keeps one reply per key; the store's history is many on one key."""
    from coevo.bus.session import query

    endpoint, _ = broker
    rs = random_ruleset("tracking", 6, np.random.default_rng(0)).to_dict()
    with open_session(make_config(mode="client", connect=[endpoint])) as s:
        for v in (1, 2, 3):
            s.put(keys.policy("h", "tracking"), encode(PolicyUpdate(run="h", behaviour="tracking", worker="t", version=v,
                                                                    generation=v, fitness=0.1 * v, episodes=1, rules=rs,
                                                                    sent_at=time.time())))
        got = poll(lambda: (r := query(s, keys.store_history("h", "tracking"), timeout=2.0, what="history")) and
                   len(r) == 3 and r, 10, "three versions in the history")
    assert [decode(p).version for _, p in got] == [1, 2, 3]
