"""Faults for real: processes killed, hung and restarted, brokers lost, bad and flooding messages.

Every test here runs real processes with real signals over real Zenoh sessions on
loopback, bounded in time; one runs ``coevo chaos``.  Kills and bad
messages tried (the README's fault table counts these): worker SIGKILL 2 (one
directly, one as part of a whole ``coevo run`` group), worker SIGKILL inside
``coevo run`` 8 (one restarted, in the run whose broker is killed twice; one whose
checkpoint was zeroed first; six in a row for the restart bound), a Ctrl-C and a SIGTERM to a whole ``coevo run``
group, a SIGTERM to one worker of a run (restarted), broker SIGKILL 2 (one
directly, one with the group), a hung worker 1, and one message of each of 12
malformed kinds plus a flood of 3,000 on the worker's keys and a 40 MB flood on
a broker with a 1 MB inbox.
"""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import msgpack
import numpy as np
import pytest
import zenoh
from procs import SMALL, coevo_main, coevo_proc, copy_of, ctrl_c_heard, poll, stop

from coevo.agents.checkpoint import load_checkpoint, save_checkpoint
from coevo.agents.models import PartnerModels
from coevo.bus.auth import RunKey
from coevo.bus import keys
from coevo.bus.messages import MAX_BYTES, PolicyUpdate, Status, encode
from coevo.bus.session import make_config, open_session
from coevo.bus.status import StatusBoard
from coevo.bus.trust import Gate
from coevo.config import GAConfig
from coevo.errors import RunDirError
from coevo.ga import GA
from coevo.policy import random_ruleset
from coevo.rundir.layout import RunPaths, WorkerPaths
from coevo.rundir.settings import RunSettings
from coevo.runs.check import check_run
from coevo.runs.local import LocalRun, free_port
from coevo.tasks import get_task
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.settings import WorldConfig

CHECKPOINT = WorkerPaths(Path(".")).checkpoint.name
FUEL = get_task("fuel")

pytestmark = pytest.mark.service  # starts brokers, workers or whole runs as processes: run with --all

T, D, E = Behaviour.TRACKING, Behaviour.DOCKING, Behaviour.EXECUTIVE
# 8 generations: killed at its third, the worker stays dead while the others (paced: they led it by at most 2) go on
# 2 more, and resumes with generations left; coevo check replays every generation of the three.  (12 checked the same
# with half as much again of run and replay.)
MID = GAConfig(generations=8, population=8, episodes=20, best_episodes=20, initial_rules=8)


def _view(board: StatusBoard, behaviour: str) -> dict:
    return next((w for w in board.snapshot() if w["behaviour"] == behaviour), {"generation": 0, "state": "unknown"})


def _curve_len(lr: LocalRun, b: Behaviour) -> int:
    f = lr.worker_dir(b) / "curve.jsonl"
    return len(f.read_text().splitlines()) if f.exists() else 0


def _local_run(tmp_path: Path, run: str, ga: GAConfig = MID, seed: int = 3, max_lead: int | None = 1) -> LocalRun:
    lr = LocalRun(RunSettings.make(run=run, regime="mutual", ga=ga, seed=seed, max_lead=max_lead), root=tmp_path,
                  log_level="INFO")
    lr.create()
    return lr


# ---------------------------------------------------------------------------- checkpoints, in process
def test_a_ga_restored_from_its_checkpoint_goes_on_exactly_as_the_original(tmp_path: Path) -> None:
    cfg = GAConfig(generations=4, population=6, episodes=10, best_episodes=10, initial_rules=8, mutation_model="gh")
    world = WorldConfig()
    partners = PartnerModels(FUEL, T, "mutual", 5, kind="recent", ga=GAConfig(initial_rules=8))
    straight = GA(FUEL, T, world=world, ga=cfg, seed=11)
    reports = [straight.generation(partners.partners()).as_dict() for _ in range(4)]

    first = GA(FUEL, T, world=world, ga=cfg, seed=11)
    models = PartnerModels(FUEL, T, "mutual", 5, kind="recent", ga=GAConfig(initial_rules=8))
    again = [first.generation(models.partners()).as_dict() for _ in range(2)]
    ident = {"run": "r", "behaviour": "tracking", "worker": "t", "seed": 11}
    save_checkpoint(tmp_path / CHECKPOINT, ident, {"ga": first.state_dict(), "models": models.state_dict()})
    state = load_checkpoint(tmp_path / CHECKPOINT, ident)
    second = GA(FUEL, T, world=world, ga=cfg, seed=999)  # another seed: everything must come from the checkpoint
    models2 = PartnerModels(FUEL, T, "mutual", 5, kind="recent", ga=GAConfig(initial_rules=8))
    second.load_state(state["ga"])
    models2.load_state(state["models"])
    again += [second.generation(models2.partners()).as_dict() for _ in range(2)]
    strip = [{k: v for k, v in r.items() if k != "seconds"} for r in reports]
    assert [{k: v for k, v in r.items() if k != "seconds"} for r in again] == strip
    assert second.population == straight.population and (second.genes == straight.genes).all()


def test_a_damaged_or_foreign_checkpoint_is_refused_by_name(tmp_path: Path) -> None:
    ident = {"run": "r", "behaviour": "docking", "worker": "d", "seed": 1}
    path = tmp_path / CHECKPOINT
    assert load_checkpoint(path, ident) is None
    save_checkpoint(path, ident, {"x": list(range(100))})
    (tmp_path / f".{CHECKPOINT}.abc.tmp").write_bytes(b"torn")  # what a crash mid-write leaves: ignored
    assert load_checkpoint(path, ident) == {"x": list(range(100))}
    with pytest.raises(RunDirError, match="another worker: seed 1"):
        load_checkpoint(path, {**ident, "seed": 2})
    data = bytearray(path.read_bytes())
    data[-5] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(RunDirError, match="damaged") as err:
        load_checkpoint(path, ident)
    assert str(path) in str(err.value)
    path.write_bytes(b"\x00garbage")
    with pytest.raises(RunDirError, match="cannot be read"):
        load_checkpoint(path, ident)


def test_a_damaged_or_removed_checkpoint_never_leads_to_a_fresh_start_that_reuses_versions(broker, tmp_path: Path) -> None:
    endpoint, _ = broker
    out = tmp_path / "w"
    args = ["worker", "--behaviour", "executive", "--regime", "independent", "--run", "ck", "--connect", endpoint,
            "--generations", "2", *SMALL, "--max-lead", "off", "--final-sync", "5", "--out", str(out)]
    first = coevo_proc(*args, log=tmp_path / "w.log")
    assert first.wait(120) == 0, (tmp_path / "w.log").read_text()
    logs = {n: (out / n).read_bytes() for n in WorkerPaths.LOGS}
    n = len(logs["published.jsonl"].splitlines())
    assert n >= 1
    ckpt = out / CHECKPOINT
    good = ckpt.read_bytes()
    damaged = bytearray(good)
    damaged[-5] ^= 0xFF

    for harm, what in ((lambda: ckpt.write_bytes(bytes(damaged)), "damaged (CRC mismatch)"),
                       (lambda: ckpt.unlink(), "holds logs but no checkpoint")):
        harm()
        r = coevo_main(*args, "--resume")  # refused before connecting (the worker reads its directory first): in process
        assert r.returncode == 2 and what in r.stderr and "Traceback" not in r.stderr, r.stderr
        err = r.stderr.strip()
        assert "\n" not in err and err.startswith("RunDirError: ")
        assert f"published versions 1..{n}" in err and "coevo run --settings" in err and "move it away" not in err
        assert {k: (out / k).read_bytes() for k in WorkerPaths.LOGS} == logs  # nothing cut, nothing republished
    ckpt.write_bytes(good)  # the advice: an intact checkpoint put back
    r = subprocess.run([sys.executable, "-m", "coevo", *args, "--resume"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (out / "published.jsonl").read_bytes() == logs["published.jsonl"]


def test_worker_directory_rules_fail_before_connecting(tmp_path: Path) -> None:
    base = ["worker", "--behaviour", "tracking", "--regime", "mutual", "--run", "x",
            "--connect", "tcp/127.0.0.1:9", "--connect-timeout", "1", "--out", str(tmp_path / "w")]
    (tmp_path / "w").mkdir()
    (tmp_path / "w" / "curve.jsonl").write_text('{"generation": 1}\n')
    r = coevo_main(*base)  # refused before connecting: in this process
    assert r.returncode == 2 and "already holds a worker's run" in r.stderr and "--resume" in r.stderr
    (tmp_path / "w" / "curve.jsonl").unlink()
    (tmp_path / "w" / "worker.json").write_text(json.dumps({"behaviour": "tracking", "regime": "mutual", "run": "x",
                                                            "seed": 5}))
    r = coevo_main(*base, "--resume")
    assert r.returncode == 2 and "seed was 5, now 0" in r.stderr


# ---------------------------------------------------------------------------- worker death
@pytest.mark.slow
def test_a_killed_worker_shows_dead_within_a_second_the_others_go_on_and_it_resumes(tmp_path: Path) -> None:
    lr = _local_run(tmp_path, "kill")
    lr.start(resume=False)
    try:
        with open_session(lr.client_config()) as s:
            board = StatusBoard(s, "kill")
            poll(lambda: _view(board, "tracking")["generation"] >= 3, 120, "tracking's third generation")
            os.kill(lr.workers[T].pid, signal.SIGKILL)
            t_kill = time.monotonic()
            poll(lambda: _view(board, "tracking")["state"] == "dead", 5, "tracking shown dead")
            assert time.monotonic() - t_kill < 1.0
            lr.workers[T].wait()
            dead_at = _curve_len(lr, T)
            others = {b: _curve_len(lr, b) for b in (D, E)}
            poll(lambda: all(_curve_len(lr, b) >= others[b] + 2 for b in others), 60, "the others evolving on")
            assert _curve_len(lr, T) == dead_at
            lr.start_worker(T, resume=True)
            poll(lambda: _view(board, "tracking")["state"] in ("alive", "done"), 60, "tracking alive again")
            poll(lambda: not lr.workers_running(), 300, "the run to finish")
            board.close()
    finally:
        lr.end_all()
    assert all(p.returncode == 0 for p in lr.workers.values())
    log = (lr.dir / "logs" / "worker-tracking.log").read_text()
    assert "resumed after generation" in log
    check = check_run(lr.dir)  # every generation once, every version in the store, replay exact
    assert check.ok, check.problems


# ---------------------------------------------------------------------------- broker death
@pytest.mark.slow
def test_a_killed_broker_loses_nothing_once_restarted(tmp_path: Path) -> None:
    # 16 generations: the slowest worker is at 3 when the broker dies and needs 3 more before it comes back, so every
    # worker publishes versions the dead broker never hears (a fast one may finish meanwhile, allowed for below: its
    # final sync waits for the store).  24 checked the same with half as much again of run and replay after the restart.
    ga = GAConfig(generations=16, population=8, episodes=20, best_episodes=20, initial_rules=8)
    # Unpaced: with pacing, workers hold at --max-lead while the broker is down (the next test); here they must
    # publish versions the dead broker never hears.
    lr = _local_run(tmp_path, "nobroker", ga=ga, seed=8, max_lead=None)
    lr.start(resume=False)
    try:
        poll(lambda: min(_curve_len(lr, b) for b in Behaviour) >= 3, 120, "three generations each")
        assert lr.broker is not None
        lr.broker.send_signal(signal.SIGKILL)
        lr.broker.wait()
        t_kill = time.time()
        at_kill = {b: _curve_len(lr, b) for b in Behaviour}
        poll(lambda: all(_curve_len(lr, b) >= at_kill[b] + 3 or _curve_len(lr, b) == ga.generations for b in Behaviour),
             120, "workers evolving without a broker")
        t_back = time.time()  # before the restart: what is sent once the new broker listens may be heard at once
        lr.start_broker()
        poll(lambda: not lr.workers_running(), 300, "the run to finish")
    finally:
        lr.end_all()
    assert all(p.returncode == 0 for p in lr.workers.values())
    check = check_run(lr.dir)
    assert check.ok, check.problems
    unheard = {b: [p for x in (lr.worker_dir(b) / "published.jsonl").read_text().splitlines()
                   if t_kill < (p := json.loads(x))["sent_at"] < t_back] for b in Behaviour}
    republished = sum(json.loads((lr.worker_dir(b) / "done.json").read_text())["republished"] for b in Behaviour)
    # What the dead broker missed came again and is in the store (check above).  Each worker's newest version may
    # come back by its routine every-generation put rather than by the store sync, so only the older ones must
    # have been republished.
    assert republished >= sum(max(0, len(v) - 1) for v in unheard.values())
    assert "store reloaded" in (lr.dir / "logs" / "broker.log").read_text()
    # The store's latest (as a broker answers it, reloaded from disk) is each worker's newest published version.
    from coevo.broker.store import PolicyStore

    store = PolicyStore(tmp_path)
    roster = lr.settings.roster or {}
    for b in Behaviour:
        newest = max(json.loads(x)["version"] for x in (lr.worker_dir(b) / "published.jsonl").read_text().splitlines())
        assert store.latest(lr.run, b, worker=roster[b]).version == newest, b


def test_genuine_messages_replayed_after_the_broker_restarted_are_refused_and_counted(tmp_path: Path) -> None:
    """The broker's memory of the messages it took is kept beside the run's store (store/seen.log): genuine policies
    captured and put again after the broker was killed and started again are each refused as replayed and counted,
    none stored twice, while a new genuine one is stored."""
    run, data = "again", tmp_path / "data"
    key = RunKey.create(run)
    RunPaths.of(data, run).dir.mkdir(parents=True)
    key.save(RunPaths.of(data, run).key_file)
    gate = Gate(key=key)  # a genuine member: its messages carry the run's MAC and fresh headers
    kt = keys.policy(run, "tracking")
    sealed = [gate.seal(_update(run, v), kt) for v in (1, 2, 3)]
    store = RunPaths.of(data, run).store_file("tracking")
    endpoint = f"tcp/127.0.0.1:{free_port()}"

    def start_broker() -> subprocess.Popen:
        p = coevo_proc("broker", "--listen", endpoint, "--data-dir", str(data), log=tmp_path / "broker.log")
        with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=20)) as s:
            poll(lambda: any(r.ok is not None for r in s.liveliness().get(keys.BROKER, timeout=1.0)), 20, "the broker")
        return p

    p = start_broker()
    try:
        with open_session(make_config(mode="client", connect=[endpoint])) as s:
            for payload in sealed:
                s.put(kt, payload)
            poll(lambda: _lines(store) == 3, 20, "three stored policies")
        p.kill()
        p.wait()
        p = start_broker()
        counts: dict[str, int] = {}

        def on_status(sample: Any) -> None:
            counts.update(Gate(key=key).decode(str(sample.key_expr), sample.payload.to_bytes()).rejected)

        with open_session(make_config(mode="client", connect=[endpoint])) as s:
            sub = s.declare_subscriber(keys.broker_status(run), on_status)
            for payload in sealed:  # captured before the restart, put again after it
                s.put(kt, payload)
            s.put(kt, gate.seal(_update(run, 4), kt))  # a new genuine one
            poll(lambda: _lines(store) == 4 and counts.get("replayed") == 3, 30, "the replays counted, v4 stored")
            sub.undeclare()
    finally:
        stop(p)
    assert [json.loads(x)["version"] for x in store.read_text().splitlines()] == [1, 2, 3, 4]
    assert counts == {"replayed": 3}, counts


def _update(run: str, version: int) -> PolicyUpdate:
    rules = random_ruleset("tracking", 6, np.random.default_rng(version)).to_dict()
    return PolicyUpdate(run=run, behaviour="tracking", worker="tracking-0", version=version, generation=version,
                        fitness=0.5, episodes=10, rules=rules, sent_at=time.time())


@pytest.mark.slow
def test_pacing_holds_while_the_broker_is_down(tmp_path: Path) -> None:
    """The router carries every token: while it is down the partners are unknown, not gone, so a worker keeps to
    --max-lead (here 1: a worker finishes at most 2 generations more than any partner) and the run goes on once
    the broker is back."""
    ga = GAConfig(generations=200, population=8, episodes=20, best_episodes=20, initial_rules=8)
    lr = _local_run(tmp_path, "outage", ga=ga, seed=5)
    assert lr.settings.max_lead == 1
    lr.start(resume=False)
    worst, down = 0, 8.0
    try:
        poll(lambda: min(_curve_len(lr, b) for b in Behaviour) >= 3, 120, "three generations each")
        assert lr.broker is not None
        lr.broker.send_signal(signal.SIGKILL)
        lr.broker.wait()
        at_kill = {b: _curve_len(lr, b) for b in Behaviour}
        end = time.monotonic() + down
        while time.monotonic() < end:
            first = {b: _curve_len(lr, b) for b in Behaviour}
            second = {b: _curve_len(lr, b) for b in Behaviour}  # read after: a lead is never overstated
            worst = max(worst, max(first.values()) - min(second.values()))
            time.sleep(0.05)
        during = {b: _curve_len(lr, b) - at_kill[b] for b in Behaviour}
        lr.start_broker()
        again = {b: _curve_len(lr, b) for b in Behaviour}
        poll(lambda: all(_curve_len(lr, b) >= again[b] + 3 for b in Behaviour), 120, "every worker going on after")
    finally:
        lr.end_all()
    assert worst <= 2, f"a worker led by {worst} generations while the broker was down ({during} done meanwhile)"
    log = (lr.dir / "logs" / "worker-executive.log").read_text()
    assert "unknown, not gone" in log


@pytest.mark.slow
def test_a_whole_run_killed_at_once_continues_with_run_resume(tmp_path: Path) -> None:
    # 8 generations: killed when Docking (the fastest) has 4, so every worker has some left to resume (12 checked the
    # same with half as much again of resume and replay).
    args = ["--regime", "independent", "--run", "crash", "--root", str(tmp_path), "--generations", "8", *SMALL,
            "--measure-epochs", "2", "--quiet"]
    p = subprocess.Popen([sys.executable, "-m", "coevo", "run", *args], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True)
    curve = tmp_path / "crash" / "workers" / "docking" / "curve.jsonl"
    try:
        poll(lambda: curve.exists() and len(curve.read_text().splitlines()) >= 4, 120, "four docking generations")
    finally:
        os.killpg(p.pid, signal.SIGKILL)  # the machine goes down: coevo run, broker and workers at once
        p.wait()
    time.sleep(0.5)
    assert not (tmp_path / "crash" / "summary.json").exists()
    bad = coevo_main("run", "--resume", str(tmp_path / "crash"), "--generations", "5")  # refused first: in process
    assert bad.returncode == 2 and "--generations" in bad.stderr
    r = subprocess.run([sys.executable, "-m", "coevo", "run", "--resume", str(tmp_path / "crash"), "--quiet"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert json.loads((tmp_path / "crash" / "summary.json").read_text())["resumed"] is True
    check = check_run(tmp_path / "crash")
    assert check.ok, check.problems


# ---------------------------------------------------------------------------- a hung worker
def test_a_hung_worker_shows_stalled_within_five_seconds(broker, tmp_path: Path) -> None:
    endpoint, _ = broker
    inject = str(Path(__file__).parent / "inject")  # its sitecustomize hangs the worker after generation 2
    env = {**os.environ, "COEVO_TEST_HANG_AFTER": "2",
           "PYTHONPATH": os.pathsep.join(p for p in (inject, os.environ.get("PYTHONPATH")) if p)}
    log = tmp_path / "w.log"
    with open(log, "wb") as f:
        p = subprocess.Popen([sys.executable, "-m", "coevo", "worker", "--behaviour", "tracking", "--regime", "independent",
                              "--run", "hang", "--connect", endpoint, "--generations", "100", *SMALL,
                              "--out", str(tmp_path / "w")], stdout=f, stderr=subprocess.STDOUT, env=env)
    try:
        with open_session(make_config(mode="client", connect=[endpoint])) as s:
            board = StatusBoard(s, "hang")
            poll(lambda: _view(board, "tracking")["generation"] >= 2, 60, "generation 2")
            t_last = time.monotonic()
            poll(lambda: _view(board, "tracking")["state"] == "stalled", 8, "stalled")
            assert time.monotonic() - t_last < 5.0
            assert p.poll() is None and _view(board, "tracking")["generation"] == 2  # alive, token held, no progress
            board.close()
    finally:
        stop(p)
    assert "hanging after generation 2" in log.read_text()


# ---------------------------------------------------------------------------- bad messages
def _policy(run: str = "bad", behaviour: str = "tracking", **over) -> dict:
    rs = random_ruleset(behaviour, 6, np.random.default_rng(4))
    base = PolicyUpdate(run=run, behaviour=behaviour, worker="t-x", version=1, generation=1, fitness=0.5, episodes=10,
                        rules=rs.to_dict(), sent_at=time.time()).model_dump(mode="json")
    return {**base, **over}

MALFORMED = {
    "not_msgpack": b"\xc1\xc1 not msgpack",
    "truncated": msgpack.packb(_policy())[:-9],
    "invalid": msgpack.packb({**_policy(), "version": "one", "extra": True}),
    "non_finite": msgpack.packb(_policy(fitness=math.nan)),
    "bad_rules": msgpack.packb(_policy(rules={"behaviour": "tracking", "lo": [[200] * 5], "hi": [[0] * 5],
                                              "action": [[99, 0]], "strength": [0.5]})),
    "schema_version": msgpack.packb(_policy(schema_version=99)),
    "wrong_run": msgpack.packb(_policy(run="another-run")),
    "wrong_behaviour": msgpack.packb(_policy(behaviour="docking")),
    "wrong_key": encode(Status(run="bad", behaviour="tracking", worker="t-x", regime="mutual", generation=1, generations=1,
                               best_fitness=0.0, sent_at=1.0)),
    "oversize": b"\x00" * (MAX_BYTES + 1),
}


def test_every_kind_of_bad_message_is_rejected_counted_and_named_and_changes_nothing(broker, tmp_path: Path) -> None:
    endpoint, _ = broker
    out = tmp_path / "w"
    p = coevo_proc("worker", "--behaviour", "executive", "--regime", "independent", "--run", "bad", "--connect", endpoint,
                   "--generations", "1000", *SMALL, "--max-lead", "off", "--out", str(out), log=tmp_path / "w.log")
    try:
        with open_session(make_config(mode="client", connect=[endpoint])) as s:
            board = StatusBoard(s, "bad")
            poll(lambda: _view(board, "executive")["generation"] >= 1, 60, "first heartbeat")
            key = keys.policy("bad", "tracking")
            for payload in MALFORMED.values():
                # Blocking, not zenoh's default for a put (dropped when a link's queue is full): each is sent once,
                # and in a full run on a busy machine the megabyte one never reached the worker (not even rejected).
                s.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)
                time.sleep(0.3)  # one at a time: each reaches the worker's ring before the next
            poll(lambda: set(MALFORMED) <= set(_view(board, "executive").get("rejected_by_reason", {})), 30,
                 "every reason counted by the worker")
            gen = _view(board, "executive")["generation"]
            for i in range(3000):  # a flood: faster than the worker reads
                s.put(keys.policy("bad", "docking"), b"\xc1 flood %d" % i)
            poll(lambda: "flood" in _view(board, "executive")["rejected_by_reason"], 30, "the flood noticed")
            poll(lambda: _view(board, "executive")["generation"] >= gen + 3, 60, "evolving on after the flood")
            assert _view(board, "executive")["partner_versions"] == {"tracking": 0, "docking": 0}  # nothing adopted
            assert not (out / "adoptions.jsonl").read_text().strip()
            poll(lambda: set(MALFORMED) - {"wrong_key"} <= set(board.broker_view()["rejected"]), 30,
                 lambda: f"every reason counted by the broker: {board.broker_view()}")
            s.put(key, msgpack.packb(_policy()))  # a good one still gets through
            poll(lambda: _view(board, "executive")["partner_versions"].get("tracking") == 1, 30, "the good policy adopted")
            board.close()
    finally:
        stop(p)
    log = (tmp_path / "w.log").read_text()
    for reason in MALFORMED:
        assert f"rejected {reason}" in log
    assert log.count("rejected not_msgpack") < 20  # the flood is summarised, not logged line by line


def test_a_broker_flooded_beyond_its_inbox_drops_and_counts_and_still_stores(tmp_path: Path) -> None:
    from coevo.runs.local import free_port

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    b = coevo_proc("broker", "--listen", endpoint, "--data-dir", str(tmp_path / "data"), "--open", "--inbox-mb", "1",
                   log=tmp_path / "broker.log")
    try:
        with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=20)) as s:
            board = StatusBoard(s, "fl")
            poll(lambda: board.broker_up, 20, "the broker")
            junk = msgpack.packb({"pad": "x" * 400_000})
            for _ in range(100):
                # Blocking, as the bad-message test puts: under zenoh's default (drop when a link's queue is full) a
                # busy machine (a full run of a fresh clone) let too few through to fill the broker's 1 MB inbox.
                s.put(keys.policy("fl", "tracking"), junk, congestion_control=zenoh.CongestionControl.BLOCK)
            poll(lambda: board.broker_view()["dropped"] > 0, 30, "drops counted")
            s.put(keys.policy("fl", "tracking"), msgpack.packb(_policy(run="fl")))
            poll(lambda: board.broker_view()["stored"].get("tracking") == 1, 30, "a good policy stored after the flood")
            view = board.broker_view()
            assert view["rejected"]["flood"] == view["dropped"] > 0
            # Each of the 100 was either dropped at the full inbox (counted as a flood) or read and refused.
            assert sum(view["rejected"].values()) <= 100
            board.close()
    finally:
        stop(b)


# ---------------------------------------------------------------------------- chaos
@pytest.mark.slow
def test_coevo_chaos_kills_and_restarts_and_the_run_comes_out_complete(tmp_path: Path) -> None:
    # 10 generations: several seconds of run, time for some of the 4 faults (a gap of 0.5-1.5 s before each); 20 checked
    # the same with twice the run and twice coevo check's replay of it
    r = subprocess.run([sys.executable, "-m", "coevo", "chaos", "--run", "ch", "--root", str(tmp_path), "--seed", "2",
                        "--generations", "10", "--population", "8", "--episodes", "20", "--ga", "best_episodes=20",
                        "--ga", "initial_rules=8", "--faults", "4", "--gap", "0.5", "1.5", "--down", "0.3", "1.5",
                        "--measure-epochs", "2"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads((tmp_path / "ch" / "chaos.json").read_text())
    assert report["complete"] and sum(report["faults"].values()) >= 1
    for b in ("tracking", "docking", "executive"):
        assert report["facts"][b]["generations"] == 10


def _children(pid: int) -> list[int]:
    try:
        return [int(x) for x in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except OSError:
        return []


def _broker_of(pid: int) -> int | None:
    """The pid of the broker a ``coevo run`` process started (its child running ``coevo ... broker``)."""
    for c in _children(pid):
        try:
            if b"\0broker\0" in Path(f"/proc/{c}/cmdline").read_bytes():
                return c
        except OSError:
            continue
    return None


@pytest.mark.slow
def test_coevo_run_restarts_its_killed_worker_and_its_twice_killed_broker_completes_and_checks(tmp_path: Path) -> None:
    """Issue 39 and item 3 of issue 29, in one run (two faults one after the other, each let finish before the next):
    the run supervises its workers and its broker.  A worker SIGKILLed mid-run is started again from its checkpoint
    and the table says so; the broker, killed twice, is started again on the same endpoint and data directory.  The
    run ends 0, nothing is lost and the store's latest is each worker's newest (coevo check, replay exact); a finishing
    worker is never shown dead.  (The worker's kill had a 12-generation run of its own before: the same assertions.)"""
    # 20 generations: the second broker kill comes when the slowest worker (Tracking) has 6, the fastest (Docking, set
    # back by its restart) before its end (30 checked the same with half as much again of run and replay)
    generations = 20
    p, out = _coevo_run(tmp_path, "sup", "--generations", str(generations), "--max-lead", "off")
    run_dir = tmp_path / "sup"
    try:
        poll(lambda: _lines(run_dir / "workers" / "docking" / "curve.jsonl") >= 3, 120, "three docking generations")
        _kill_worker(p, "docking")
        poll(lambda: "starting it again (restart 1 of at most 5)" in out.read_text(), 30, "the docking worker restarted")
        for n in (1, 2):
            poll(lambda: _curve_len_dir(run_dir) >= 3 * n, 180, f"generations before broker kill {n}")
            pid = poll(lambda: _broker_of(p.pid), 30, "the broker process")
            os.kill(pid, signal.SIGKILL)
            poll(lambda: (run_dir / "logs" / "broker.log").read_text().count("--- start") >= n + 1, 30,
                 f"the broker started again ({n})")
        assert p.wait(timeout=600) == 0, out.read_text()[-3000:]
    finally:
        stop(p)
    text = out.read_text()
    assert "the docking worker was killed by SIGKILL; starting it again (restart 1 of at most 5)" in text
    assert "alive, restarted 1x" in text and "Traceback" not in text
    summary = json.loads((run_dir / "summary.json").read_text())
    assert not summary["interrupted"], summary
    check = check_run(run_dir)
    assert check.ok and check.facts["docking"]["generations"] == generations, check.problems
    # While the broker (the router the status session reaches the workers through) is down every worker looks dead;
    # a worker that finished its generations never does.
    done = f" gen {generations}/{generations} "
    assert not [x for x in text.splitlines() if done in x and x.rstrip().endswith(" dead")], text[-3000:]


def _curve_len_dir(run_dir: Path) -> int:
    return min((len(f.read_text().splitlines()) for f in run_dir.glob("workers/*/curve.jsonl")), default=0)


# ---------------------------------------------------------------------------- coevo run supervises its workers
def _worker_of(pid: int, behaviour: str) -> int | None:
    """The pid of the ``behaviour`` worker a ``coevo run`` process started."""
    for c in _children(pid):
        try:
            if f"\0--behaviour\0{behaviour}\0".encode() in Path(f"/proc/{c}/cmdline").read_bytes():
                return c
        except OSError:
            continue
    return None


def _lines(f: Path) -> int:
    return len(f.read_text().splitlines()) if f.exists() else 0


def _coevo_run(tmp_path: Path, run: str, *args: str) -> tuple[subprocess.Popen, Path]:
    """``coevo run`` of ``run`` under ``tmp_path`` (plain status lines, then its last words, in run.out)."""
    with open(tmp_path / "run.out", "wb") as f:
        p = subprocess.Popen([sys.executable, "-m", "coevo", "run", "--run", run, "--root", str(tmp_path), *SMALL,
                              "--measure-epochs", "2", *args], stdout=f, stderr=subprocess.STDOUT)
    return p, tmp_path / "run.out"


def _kill_worker(p: subprocess.Popen, behaviour: str, *, before: int | None = None) -> int:
    """SIGKILL ``p``'s ``behaviour`` worker (one other than the process ``before``); its pid."""
    pid = poll(lambda: (w := _worker_of(p.pid, behaviour)) != before and w, 30, f"the {behaviour} worker process")
    os.kill(pid, signal.SIGKILL)
    return pid


def test_a_worker_that_cannot_start_stops_the_run_at_once_with_its_reason(tmp_path: Path) -> None:
    """A worker whose checkpoint went bad under it dies, is started again, refuses its checkpoint twice: the run
    stops then, in one line with the worker's own reason, not after the others evolved to their end."""
    p, out = _coevo_run(tmp_path, "ns", "--generations", "40")
    w = tmp_path / "ns" / "workers" / "docking"
    try:
        poll(lambda: _lines(w / "curve.jsonl") >= 3, 120, "three docking generations")
        pid = poll(lambda: _worker_of(p.pid, "docking"), 30, "the docking worker process")
        os.kill(pid, signal.SIGSTOP)  # no checkpoint written between the damage and the kill
        (w / CHECKPOINT).write_bytes(b"\x00" * 64)
        os.kill(pid, signal.SIGKILL)
        t0 = time.monotonic()
        assert p.wait(timeout=120) == 2, out.read_text()[-3000:]
        took = time.monotonic() - t0
    finally:
        stop(p)
    last = out.read_text().strip().splitlines()[-1]
    assert last.startswith("RunDirError: the docking worker cannot start: RunDirError: checkpoint ") and "cannot be read" in last
    assert "twice before a generation" in last and "worker-docking.log" in last
    assert took < 30 and _lines(tmp_path / "ns" / "workers" / "tracking" / "curve.jsonl") < 40
    assert "Traceback" not in out.read_text()


def test_a_worker_that_keeps_dying_ends_the_run_after_its_restarts_in_one_line(tmp_path: Path) -> None:
    """Bounded restarts: the sixth death of the same worker (each after a generation of its own) ends the run."""
    p, out = _coevo_run(tmp_path, "bd", "--generations", "200", "--max-lead", "off")
    curve = tmp_path / "bd" / "workers" / "docking" / "curve.jsonl"
    try:
        pid = None
        for n in range(6):
            done = max(_lines(curve), 1)
            poll(lambda: _lines(curve) > done or p.poll() is not None, 60, f"a docking generation after start {n + 1}")
            pid = _kill_worker(p, "docking", before=pid)
        assert p.wait(timeout=60) == 2, out.read_text()[-3000:]
    finally:
        stop(p)
    last = out.read_text().strip().splitlines()[-1]
    assert last.startswith("RunDirError: the docking worker was killed by SIGKILL after 5 restarts; see "), last
    assert "worker-docking.log" in last and "coevo run --resume" in last and "Traceback" not in out.read_text()


def test_run_resume_refuses_a_damaged_checkpoint_before_starting_anything(finished_mutual: Path,
                                                                          tmp_path: Path) -> None:
    """``coevo run --resume`` reads every checkpoint first: damage is one line naming the file, and the run
    directory is left as it was (no process started, nothing written).  (A damaged store file is set aside and
    refilled instead: tests/test_damaged_files.py.)  On a copy of the session's finished Mutual run."""
    run_dir = copy_of(finished_mutual, tmp_path)

    def files() -> dict[str, bytes]:
        return {str(f): f.read_bytes() for f in sorted(run_dir.rglob("*")) if f.is_file()}

    def refused(damaged: Path) -> None:
        before = files()
        r = coevo_main("run", "--resume", str(run_dir), "--quiet")  # refused before anything starts: in process
        assert r.returncode == 2 and not r.stdout and len(r.stderr.strip().splitlines()) == 1, r.stdout + r.stderr
        assert r.stderr.startswith(f"RunDirError: cannot resume {run_dir}: ") and str(damaged) in r.stderr, r.stderr
        assert files() == before  # run.json, logs, summary: untouched

    ck = run_dir / "workers" / "tracking" / CHECKPOINT
    good = ck.read_bytes()
    ck.write_bytes(good[:40] + bytes(b ^ 0xFF for b in good[40:80]) + good[80:])  # garbled in the middle
    refused(ck)
    ck.write_bytes(b"")  # emptied
    refused(ck)


def test_ctrl_c_to_the_whole_process_group_stops_in_order_and_the_run_resumes_exact(tmp_path: Path) -> None:
    """A terminal's Ctrl-C reaches coevo run and every child: only coevo run takes it, so the workers stop at a
    generation's end and write their done.json, the broker stays up for the final measures, and the stop message
    quotes this run's generations; --resume then completes the run exactly."""
    p, out, run_dir = _run_of_8(tmp_path, ctrl_c_heard)
    try:
        poll(lambda: _lines(run_dir / "workers" / "tracking" / "curve.jsonl") >= 3, 120, "three tracking generations")
        os.killpg(p.pid, signal.SIGINT)
        assert p.wait(timeout=60) == 130, out.read_text()[-3000:]
    finally:
        stop(p)
    _stopped_in_order_and_resumes_exact(run_dir, out)


def test_sigterm_to_a_worker_restarts_it_and_to_the_whole_group_stops_in_order(tmp_path: Path) -> None:
    """A SIGTERM to one worker alone (not the run's own stop) is a death: the supervisor starts it again.  A SIGTERM
    to the whole process group (a scheduler's or a shutdown's) is a stop like Ctrl-C: coevo run's children are in a
    group of their own, so only coevo run hears it and stops them in order (done.json, the final measures);
    --resume then completes the run exactly."""
    p, out, run_dir = _run_of_8(tmp_path, None)
    try:
        poll(lambda: _lines(run_dir / "workers" / "executive" / "curve.jsonl") >= 1, 120, "an executive generation")
        kids = {int(k) for k in Path(f"/proc/{p.pid}/task/{p.pid}/children").read_text().split()}
        assert all(os.getpgid(k) == k for k in kids)  # each child leads a group of its own
        executive = next(k for k in kids if b"executive" in Path(f"/proc/{k}/cmdline").read_bytes())
        os.kill(executive, signal.SIGTERM)
        log = run_dir / "logs" / "worker-executive.log"
        poll(lambda: "--- start 2" in log.read_text(), 60, "the executive worker started again")
        assert "executive worker exited with status 130; starting it again (restart 1 of at most 5)" in out.read_text()
        poll(lambda: _lines(run_dir / "workers" / "tracking" / "curve.jsonl") >= 3, 120, "three tracking generations")
        os.killpg(p.pid, signal.SIGTERM)
        assert p.wait(timeout=60) == 130, out.read_text()[-3000:]
        assert not [k for k in kids if Path(f"/proc/{k}").exists()]  # nothing is left running
    finally:
        stop(p)
    _stopped_in_order_and_resumes_exact(run_dir, out, one_killed=True)


def test_sigterm_to_a_comparisons_process_group_stops_its_runs_in_order_and_it_resumes(tmp_path: Path) -> None:
    """coevo compare (as study and seeds: the replicate runner) takes SIGTERM as Ctrl-C, and so does each coevo run
    under it: the run stops in order (its workers' done.json, its summary), compare exits 130, --resume completes."""
    out = tmp_path / "cmp"
    p = subprocess.Popen([sys.executable, "-m", "coevo", "compare", "--regimes", "independent", "--runs", "1",
                          "--generations", "8", "--population", "6", "--episodes", "10", "--measure-epochs", "1",
                          "--out", str(out), "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    run_dir = out / "runs" / "independent-00"
    try:
        poll(lambda: _lines(run_dir / "workers" / "tracking" / "curve.jsonl") >= 2, 120, "two tracking generations")
        os.killpg(p.pid, signal.SIGTERM)
        _, err = p.communicate(timeout=90)
        assert p.returncode == 130 and "interrupted; finished runs are kept" in err, err
    finally:
        stop(p)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["stopped_here"] and summary["stopped_early"], summary
    for b, n in summary["stopped_early"].items():
        assert json.loads((run_dir / "workers" / b / "done.json").read_text())["generations"] == n
    r = subprocess.run([sys.executable, "-m", "coevo", "compare", "--resume", "--out", str(out), "--quiet"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    check = check_run(run_dir)
    assert check.ok, check.problems



def _sigterm_group_when(p: subprocess.Popen, ready: Any, what: str) -> str:
    """SIGTERM to ``p``'s process group once ``ready()``; its stderr (it must end 130 saying it was interrupted)."""
    try:
        poll(lambda: ready() or p.poll() is not None, 180, what)
        assert p.poll() is None, p.communicate()
        os.killpg(p.pid, signal.SIGTERM)
        _, err = p.communicate(timeout=120)
    finally:
        stop(p)
    assert p.returncode == 130 and "Traceback" not in err, err
    return str(err)


@pytest.mark.slow
def test_sigterm_to_a_studys_process_group_stops_its_run_in_order_and_it_resumes(tmp_path: Path) -> None:
    """coevo study under a scheduler's SIGTERM to its group: the run under it stops in order (every done.json, the
    summary saying who stopped early), the study exits 130, and --resume completes the study and the run, exact."""
    out = tmp_path / "study"
    tiny = ["--factor", "regime=independent", "--runs", "1", "--generations", "8", "--population", "6", "--episodes",
            "4", "--ga", "best_episodes=4", "--ga", "initial_rules=8", "--measure-epochs", "1", "--quiet"]
    p = subprocess.Popen([sys.executable, "-m", "coevo", "study", "--out", str(out), *tiny], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    run_dir = out / "cells" / "00-all" / "runs" / "independent-00"
    err = _sigterm_group_when(p, lambda: _lines(run_dir / "workers" / "tracking" / "curve.jsonl") >= 2,
                              "two tracking generations")
    assert "interrupted; finished runs are kept" in err, err
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["stopped_here"] and summary["stopped_early"], summary
    for b in ("tracking", "docking", "executive"):
        done = json.loads((run_dir / "workers" / b / "done.json").read_text())
        assert done["generations"] == _lines(run_dir / "workers" / b / "curve.jsonl") == \
            summary["stopped_early"].get(b, 8)
    assert not (out / "complete.json").exists()
    r = subprocess.run([sys.executable, "-m", "coevo", "study", "--out", str(out), "--resume", "--quiet"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and (out / "complete.json").exists(), r.stdout + r.stderr
    check = check_run(run_dir)
    assert check.ok, check.problems


@pytest.mark.slow
def test_sigterm_to_a_cel_runs_process_group_stops_it_in_order_and_it_resumes(tmp_path: Path) -> None:
    """coevo cel under a SIGTERM to its group: the learner and the robot stop in order (each its done.json), coevo cel
    exits 130 naming the resume, and --resume completes the run, the learner's replay exact."""
    p = subprocess.Popen([sys.executable, "-m", "coevo", "cel", "--root", str(tmp_path), "--run", "cel", "--generations",
                          "8", "--population", "16", "--episodes", "20", "--ga", "best_episodes=20", "--fail",
                          "3:front", "--seed", "2", "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, start_new_session=True)
    run_dir = tmp_path / "cel"
    err = _sigterm_group_when(p, lambda: _lines(run_dir / "execution" / "performance.jsonl") >= 3,
                              "three generations of the robot's trials")
    assert f"coevo cel --resume {run_dir}" in err, err
    for done in (run_dir / "workers" / "door" / "done.json", run_dir / "execution" / "done.json"):
        assert not json.loads(done.read_text())["finished"], done
    r = subprocess.run([sys.executable, "-m", "coevo", "cel", "--resume", str(run_dir), "--quiet"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert json.loads((run_dir / "execution" / "done.json").read_text())["finished"]
    check = check_run(run_dir)
    assert check.ok, check.problems


@pytest.mark.slow
def test_sigterm_while_coevo_run_starts_leaves_nothing_half_made_and_it_resumes(tmp_path: Path) -> None:
    """A SIGTERM to coevo run's group while it makes its directory, and another once its processes are starting (no
    worker has a generation yet): each an interrupted stop (130), never a half-made directory: the first leaves no run
    directory or a whole one (made beside it and renamed), and nothing beside it; the second resumes to complete."""
    def start(run: str) -> subprocess.Popen:
        return subprocess.Popen([sys.executable, "-m", "coevo", "run", "--run", run, "--root", str(tmp_path), *SMALL,
                                 "--generations", "3", "--measure-epochs", "1", "--quiet"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True)

    made = lambda run: (tmp_path / run).exists() or any(tmp_path.glob(f".{run}.*.partial"))  # noqa: E731
    _sigterm_group_when(start("early"), lambda: made("early"), "the run directory begun")
    assert not list(tmp_path.glob(".early.*")), "a staged run directory was left behind"
    if (tmp_path / "early").exists():  # the signal came after the directory was made: it is whole
        assert {"run.json", "secret.key", "code.json"} <= {f.name for f in (tmp_path / "early").iterdir()}

    run_dir = tmp_path / "starting"
    _sigterm_group_when(start("starting"), lambda: (run_dir / "logs" / "broker.log").exists(), "the broker starting")
    # Sent while it starts; one that lands while its status session still opens waits for that session and stops the
    # run in order (run_local), so a worker may end the generation it began: then it wrote its done.json.
    began = [f.parent for f in run_dir.glob("workers/*/curve.jsonl") if _lines(f)]
    assert all((w / "done.json").exists() for w in began), [w.name for w in began]
    r = subprocess.run([sys.executable, "-m", "coevo", "run", "--resume", str(run_dir), "--quiet"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    check = check_run(run_dir)
    assert check.ok, check.problems


#: The stopped runs' generations: stopped when Tracking has 3, the others (paced, --max-lead 1) at most 2 ahead, so each
#: has some left to resume (12 before checked the same with half as much again of run and replay).
STOPPED_RUN = 8


def _run_of_8(tmp_path: Path, preexec: Any) -> tuple[subprocess.Popen, Path, Path]:
    """An 8-generation coevo run in a session of its own (its group id is its pid), its output (the status lines,
    plain into a file) in run.out."""
    out = tmp_path / "run.out"
    with open(out, "wb") as f:
        p = subprocess.Popen([sys.executable, "-m", "coevo", "run", "--run", "ci", "--root", str(tmp_path), *SMALL,
                              "--generations", str(STOPPED_RUN), "--measure-epochs", "2"], stdout=f, stderr=subprocess.STDOUT,
                             start_new_session=True, preexec_fn=preexec)
    return p, out, tmp_path / "ci"


def _stopped_in_order_and_resumes_exact(run_dir: Path, out: Path, *, one_killed: bool = False) -> None:
    """Every worker wrote its done.json, the summary has the final measures and says who stopped early (the output
    too), and --resume completes the run, replay exact."""
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["interrupted"] and summary["stopped_here"] and "measures" in summary, summary
    counts = {b: _lines(run_dir / "workers" / b / "curve.jsonl") for b in ("tracking", "docking", "executive")}
    for b, n in counts.items():
        done = json.loads((run_dir / "workers" / b / "done.json").read_text())
        assert done["finished"] == (n == STOPPED_RUN) and done["generations"] == n
    assert summary["stopped_early"] == {b: n for b, n in counts.items() if n < STOPPED_RUN}
    assert all(f"{b} after {n}" in out.read_text() for b, n in summary["stopped_early"].items())
    # The status lines (plain, into a file) read true: a worker that stopped is "stopped", never "dead".
    lines = out.read_text().splitlines()
    if not one_killed:  # (a worker killed on purpose reads dead until its supervisor has started it again)
        assert not [x for x in lines if x.endswith(" dead")], lines
    for b in summary["stopped_early"]:
        assert re.search(r" stopped(, restarted \d+x)?$", [x for x in lines if f" {b}-" in x][-1]), lines
    r = subprocess.run([sys.executable, "-m", "coevo", "run", "--resume", str(run_dir), "--quiet"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    check = check_run(run_dir)
    assert check.ok, check.problems
