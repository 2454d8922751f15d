"""The Quick start's end (issue 55): ``coevo run``'s last lines say what was learned in the task's words, with units
and the run's Table 1 class, and give the next commands with the run's own path, which run as written; the states
read true (a worker not yet heard from shows the run's generations, one that ends on a stop is *stopped*); and
``--resume`` of a finished run says it is complete and starts nothing."""

from __future__ import annotations

import contextlib
import itertools
import re
import shlex
import time
from pathlib import Path

import pytest

from procs import coevo_main, copy_of, poll, tree_digest

from coevo.bus import keys
from coevo.bus.session import make_config, open_session
from coevo.bus.status import StatusBoard
from coevo.experiments.compare.table1 import classify
from coevo.tasks import get_task
from coevo.tasks.base import measures_text
from coevo.tasks.checker import check_task
from coevo.tasks.corridor import CorridorTask

MEASURES = {"quality_tracking": 72.2, "successful_docking": 8.1, "dock_choice": 9.4, "docking_success_rate": 85.9,
            "average_epoch_length": 7.05, "executive_payoff": 0.6604, "collision_rate": 3.1, "episodes": 900}


def test_the_fuel_tasks_words_name_each_measure_with_its_unit_and_the_payoff_to_three_places() -> None:
    items = measures_text(get_task("fuel"), MEASURES)
    assert items == ["Quality Tracking 72.2 %", "Successful Docking 8.1 %", "docked of picked 85.9 %",
                     "Docking picked 9.4 %", "Average Epoch Length 7.0 episodes", "Executive payoff 0.660",
                     "collisions 3.1 %"]  # no count (episodes), no raw field name, the payoff not 0.7


def test_a_task_without_terms_shows_its_own_field_names() -> None:
    corridor = get_task("corridor")
    assert corridor.measure_terms == {} and corridor.run_verdict({"reached": 0.5}) is None
    assert measures_text(corridor, {"reached": 0.5, "steps": 12, "mean_steps": 31.25}) == ["reached 0.5",
                                                                                           "mean_steps 31.2"]


def test_the_runs_verdict_gives_the_class_a_comparison_gives() -> None:
    """The fuel task's verdict and compare's Table 1 classing (experiments/compare/table1.py) agree at and around
    every threshold."""
    fuel = get_task("fuel")
    for choice, docked, qt in itertools.product((0.0, 4.9, 5.0, 40.0), (0.0, 19.9, 20.0, 90.0),
                                                (10.0, 30.0, 30.1, 60.0, 60.1)):
        m = {"dock_choice": choice, "docking_success_rate": docked, "quality_tracking": qt}
        verdict = fuel.run_verdict(m)
        assert verdict is not None and verdict.startswith(f"Table 1 class {classify(m)}: "), (m, verdict)
    assert fuel.run_verdict({"quality_tracking": 50.0}) is None  # measures missing: no class


def test_resume_of_a_finished_run_says_it_is_complete_starts_nothing_and_its_next_commands_run(
        finished_mutual: Path, tmp_path: Path) -> None:
    run_dir = copy_of(finished_mutual, tmp_path)
    before = tree_digest(run_dir)
    r = coevo_main("run", "--resume", str(run_dir))
    assert r.returncode == 0, r.stdout + r.stderr
    assert tree_digest(run_dir) == before  # no run.json rewritten, no summary removed, no log started
    lines = r.stdout.splitlines()
    assert lines[0] == "run small is complete: every worker finished its generations; nothing to continue"
    text = "\n".join(lines)
    assert "final policies together: Quality Tracking " in text and "Executive payoff 0." in text
    assert "quality_tracking" not in text and "executive_payoff" not in text
    assert re.search(r"^Table 1 class (Good|Poor|No) Docking / (Hi|Med|Lo): ", text, flags=re.M), text
    where = shlex.quote(str(run_dir))
    nexts = [m.group(1) for line in lines if (m := re.match(r"^(?:next:)?\s+(coevo \S+ \S+)  \(", line))]
    assert nexts == [f"coevo show {where}", f"coevo check {where}", f"coevo dashboard {where}"], lines
    for command in nexts[:2]:  # as written; the dashboard's page is served and read in tests/test_dashboard.py
        out = coevo_main(*shlex.split(command)[1:])
        assert out.returncode == 0, command + "\n" + out.stdout + out.stderr
    assert "complete (replay exact)" in out.stdout
    assert list(run_dir.glob("show-epoch-*.png"))


def test_a_worker_shows_the_runs_generations_before_its_first_heartbeat_and_a_stop_reads_stopped(broker) -> None:
    """Real sessions on the bus: a worker's liveliness token alone (no heartbeat yet) reads 0/50 on a board told the
    run's 50 generations, not 0/0; a token that goes is *dead*, unless the board was told of a stop: *stopped*."""
    endpoint, _ = broker
    conf = make_config(mode="client", connect=[endpoint])
    with open_session(conf) as watcher, open_session(conf) as workers:
        board = StatusBoard(watcher, "ends", generations=50)
        try:
            tokens = {w: workers.liveliness().declare_token(keys.alive("ends", b, w))
                      for b, w in (("tracking", "tracking-0"), ("docking", "docking-1"))}

            def states() -> dict[str, tuple[str, str]]:
                return {w["worker"]: (w["state"], f"{w['generation']}/{w['generations']}") for w in board.snapshot()}

            poll(lambda: len(states()) == 2, 20, "both tokens")
            assert states() == {"tracking-0": ("starting", "0/50"), "docking-1": ("starting", "0/50")}
            tokens["tracking-0"].undeclare()
            poll(lambda: states()["tracking-0"][0] != "starting", 20, "the token gone")
            assert states()["tracking-0"][0] == "dead"  # nobody asked it to stop
            board.stopping()
            tokens["docking-1"].undeclare()
            poll(lambda: states()["docking-1"][0] != "starting", 20, "the token gone")
            assert states() == {"tracking-0": ("dead", "0/50"), "docking-1": ("stopped", "0/50")}
        finally:
            board.close()


def test_a_worker_whose_last_heartbeat_says_it_stops_reads_stopped_on_a_board_not_told(broker) -> None:
    """Real sessions on the bus, a board in "another terminal" (never told the run stops): a worker's last heartbeat
    says it stops in order (Status.stopped), so its token's going reads *stopped*, whichever arrives first; a worker
    whose token goes without it reads *dead*; a worker started again under the same id is not stopped by the first's
    words."""
    from coevo.bus.messages import Status, encode

    endpoint, _ = broker
    conf = make_config(mode="client", connect=[endpoint])
    with open_session(conf) as watcher, open_session(conf) as workers:
        board = StatusBoard(watcher, "ends", generations=50)
        pubs = {w: workers.declare_publisher(keys.status("ends", b, w)) for b, w in
                (("tracking", "tracking-0"), ("docking", "docking-1"), ("executive", "executive-2"))}

        def beat(b: str, w: str, *, stopped: bool) -> None:
            pubs[w].put(encode(Status(run="ends", behaviour=b, worker=w, regime="mutual", generation=3, generations=50,
                                      best_fitness=0.1, stopped=stopped, sent_at=time.time())))

        def states() -> dict[str, str]:
            return {w["worker"]: w["state"] for w in board.snapshot()}

        try:
            tokens = {w: workers.liveliness().declare_token(keys.alive("ends", b, w))
                      for b, w in (("tracking", "tracking-0"), ("docking", "docking-1"), ("executive", "executive-2"))}
            for b, w in (("tracking", "tracking-0"), ("docking", "docking-1"), ("executive", "executive-2")):
                beat(b, w, stopped=False)
            poll(lambda: set(states().values()) == {"alive"}, 20, "three workers alive")
            beat("tracking", "tracking-0", stopped=True)  # its words first, then its token
            poll(lambda: board.poll() or board.workers["tracking-0"].stopping, 20, "tracking's last heartbeat")
            tokens["tracking-0"].undeclare()
            tokens["docking-1"].undeclare()  # its token goes first, then its words
            poll(lambda: states()["docking-1"] == "dead", 20, "docking's token gone")
            beat("docking", "docking-1", stopped=True)
            tokens["executive-2"].undeclare()  # a death: no words
            poll(lambda: states() == {"tracking-0": "stopped", "docking-1": "stopped", "executive-2": "dead"}, 20,
                 lambda: f"stopped, stopped, dead: {states()}")
            again = workers.liveliness().declare_token(keys.alive("ends", "tracking", "tracking-0"))  # restarted
            poll(lambda: states()["tracking-0"] != "stopped", 20, "tracking started again")
            again.undeclare()
            poll(lambda: states()["tracking-0"] == "dead", 20, lambda: f"the restarted tracking dead: {states()}")
        finally:
            board.close()


@pytest.mark.service  # a whole command as a process: the whole suite's, not the fast set's
def test_ctrl_c_to_a_run_reads_stopped_in_coevo_status_from_another_terminal(tmp_path: Path) -> None:
    """A real coevo run stopped by a terminal's Ctrl-C (SIGINT to its process group) while ``coevo status`` follows
    it from another terminal (its board, on its own session, not told of the stop): every worker that stopped short
    of its generations reads *stopped*, none *dead*."""
    import json
    import os
    import signal
    import subprocess
    import sys

    from procs import SMALL, ctrl_c_heard, stop

    out = tmp_path / "run.out"
    with open(out, "wb") as f:
        p = subprocess.Popen([sys.executable, "-m", "coevo", "run", "--run", "cc", "--root", str(tmp_path), *SMALL,
                              "--generations", "30", "--measure-epochs", "1", "--quiet"], stdout=f,
                             stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=ctrl_c_heard)
    board = None
    try:
        settings = tmp_path / "cc" / "run.json"
        poll(settings.exists, 120, "the run's run.json")
        conf = make_config(mode="client", connect=[json.loads(settings.read_text())["endpoint"]])
        with open_session(conf) as watcher:
            board = StatusBoard(watcher, "cc")

            def states() -> dict[str, str]:
                return {w["worker"]: w["state"] for w in board.snapshot()}

            poll(lambda: len(states()) == 3 and set(states().values()) == {"alive"}, 120,
                 lambda: f"three workers alive: {states()}")
            os.killpg(p.pid, signal.SIGINT)
            assert p.wait(timeout=120) == 130, out.read_text()[-3000:]
            seen = states()
            early = json.loads((tmp_path / "cc" / "summary.json").read_text())["stopped_early"]
            assert early, "no worker stopped early: the check would prove nothing"
            assert {w: s for w, s in seen.items() if w.split("-")[0] in early} == {
                w: "stopped" for w in seen if w.split("-")[0] in early}, seen
            assert "dead" not in seen.values(), seen
            board.close()
            board = None
    finally:
        stop(p)


def test_resume_of_no_directory_is_still_one_line(tmp_path: Path) -> None:
    r = coevo_main("run", "--resume", str(tmp_path / "nosuch"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "nosuch" in r.stderr, r.stderr


class _Misnamed(CorridorTask):
    """A corridor whose measure terms are plain strings, not Terms."""

    measure_terms = {"reached": "Reached %"}  # type: ignore[dict-item]


def test_the_task_checker_names_measure_terms_that_are_not_terms() -> None:
    problems = check_task(_Misnamed(), pictures=False)
    assert [p for p in problems if p.startswith("measure_terms: ")] == [
        "measure_terms: give a dict (measure -> coevo.tasks.base.Term: name, unit, definition), empty if none"], problems
    assert check_task(CorridorTask(), pictures=False) == []


def test_replay_and_check_show_their_progress_on_a_terminal_and_nothing_in_a_pipe(finished_mutual: Path) -> None:
    """They replay every generation (tens of seconds for a 50-generation run): on a terminal a line per behaviour
    says how far; piped, their output is only their verdict."""
    import os
    import pty
    import subprocess
    import sys
    import threading

    for command, verdict in (("replay", "reproduced exactly"), ("check", "complete (replay exact)")):
        master, slave = pty.openpty()
        p = subprocess.Popen([sys.executable, "-m", "coevo", command, str(finished_mutual)], stdout=subprocess.PIPE,
                             stderr=slave, text=True)
        os.close(slave)
        seen: list[bytes] = []

        def read(fd: int = master) -> None:  # read as it comes: a full terminal buffer would block the writer
            with contextlib.suppress(OSError):  # the terminal's other end closes with the process
                while chunk := os.read(fd, 65536):
                    seen.append(chunk)

        reader = threading.Thread(target=read)
        reader.start()
        out, _ = p.communicate(timeout=300)
        reader.join(10)
        os.close(master)
        assert p.returncode == 0 and verdict in out, out
        shown = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", b"".join(seen).decode(errors="replace"))  # colours, moves
        for b in ("tracking", "docking", "executive"):
            assert re.search(rf"replaying {b}\s.*3/3 generations", shown), shown
        assert "replaying" not in out


def test_show_draws_the_median_epoch_by_payoff_and_says_which_and_that_it_is_one_sample(finished_mutual: Path,
                                                                                        tmp_path: Path) -> None:
    from statistics import median

    from coevo.show.source import from_path

    run_dir = copy_of(finished_mutual, tmp_path)
    r = coevo_main("show", str(run_dir))
    assert r.returncode == 0, r.stdout + r.stderr
    m = re.match(r"drawing seed (\d+): the median of 9 epochs \(seeds 0-8\) by Executive payoff, ([\d.]+) \(they range "
                 r"([\d.]+) to ([\d.]+)\); one sample of the robot: --seed N draws another$", r.stdout.splitlines()[0])
    assert m, r.stdout
    seed = int(m.group(1))
    assert r.stdout.splitlines()[1].startswith(f"wrote {run_dir / f'show-epoch-seed{seed}.png'} (")
    shown = from_path(run_dir, world_over={}, partners={}, wanted=None)  # the same nine epochs, played here
    payoffs = [shown.display.show_score(shown.display.show_play(shown.robot, seed=s, episodes=None))[1]
               for s in range(9)]
    assert f"{median(payoffs):.3f}" == m.group(2) == f"{payoffs[seed]:.3f}"
    assert (m.group(3), m.group(4)) == (f"{min(payoffs):.3f}", f"{max(payoffs):.3f}")
    r = coevo_main("show", str(run_dir), "--seed", "2")  # a seed given: that one, nothing picked
    assert r.returncode == 0 and r.stdout.startswith(f"wrote {run_dir / 'show-epoch-seed2.png'} ("), r.stdout


def test_a_workers_rule_file_is_shown_with_its_partners_from_its_run_directory(finished_mutual: Path) -> None:
    """`coevo show RUN/workers/executive/best.rules --rules` found no Tracking or Docking before: they sit beside it."""
    r = coevo_main("show", str(finished_mutual / "workers" / "executive" / "best.rules"), "--rules")
    assert r.returncode == 0, r.stdout + r.stderr
    tables = [line.split(":")[0] for line in r.stdout.splitlines() if "rules by strength" in line]
    assert sorted(tables) == ["docking", "executive", "tracking"], r.stdout
