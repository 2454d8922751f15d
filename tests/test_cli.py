"""The command line, run as a real subprocess: outputs, bad input, nothing half-written."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from coevo.policy import parse_ruleset


def coevo(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=300, cwd=cwd)


def test_learn_writes_a_complete_run_directory(tmp_path: Path) -> None:
    out = tmp_path / "run"
    r = coevo("learn", "--behaviour", "docking", "--generations", "2", "--population", "4", "--episodes", "10",
              "--ga", "best_episodes=10", "--measure-epochs", "3", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["best.png", "best.rules", "config.json", "curve.csv", "curve.json", "measures.json",
                                                  "timing.json"]
    curve = json.loads((out / "curve.json").read_text())
    assert [c["generation"] for c in curve] == [1, 2]
    assert len((out / "curve.csv").read_text().strip().splitlines()) == 3
    best = parse_ruleset((out / "best.rules").read_text())
    assert best.behaviour == "docking"
    m = json.loads((out / "measures.json").read_text())
    assert "docking_from_random_starts" in m and 0 <= m["quality_tracking"] <= 100


def test_executive_learns_from_rule_files(tmp_path: Path) -> None:
    (tmp_path / "t.rules").write_text("# behaviour: tracking\nIF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)\n")
    (tmp_path / "d.rules").write_text("# behaviour: docking\nIF ANY THEN SET turn = 8 AND speed = 4 (strength 0.5)\n")
    r = coevo("learn", "--behaviour", "executive", "--tracking", str(tmp_path / "t.rules"), "--docking", str(tmp_path / "d.rules"),
              "--generations", "1", "--population", "4", "--episodes", "10", "--ga", "best_episodes=10",
              "--measure-epochs", "2", "--out", str(tmp_path / "ex"), "--quiet")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "ex" / "best.png").exists()
    r = coevo("show", str(tmp_path / "ex"), "--rules")  # the combined robot, from the partners kept beside best.rules
    assert r.returncode == 0, r.stderr
    assert "executive:" in r.stdout and "tracking:" in r.stdout and "docking:" in r.stdout


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--population", "0"], "--population: invalid number 0: give a whole number from 2 to 10000"),
        (["--generations", "-1"], "--generations: invalid number -1"),
        (["--ga", "mutation_rate=2"], "mutation_rate=2"),
        (["--ga", "no_such=1"], "no_such"),
        (["--world", "tracking_min=70"], "tracking_min"),
        (["--ga", "oops"], "name=value"),
        (["--seed-policy", "/nonexistent/file.rules"], "no such file"),
        (["--initial", "sometimes"], "initial='sometimes'"),
        (["--seed", "-1"], "invalid seed -1"),
        (["--ga", "docking_fresh_starts=maybe"], "docking_fresh_starts='maybe'"),
        (["--out", "/etc/passwd/run"], "cannot create output directory"),
    ],
)
def test_bad_parameters_fail_clearly_and_write_nothing(tmp_path: Path, args: list[str], needle: str) -> None:
    out = tmp_path / "run"
    r = coevo("learn", "--behaviour", "tracking", "--out", str(out), "--quiet", *args)
    assert r.returncode == 2
    assert needle in r.stderr and "Traceback" not in r.stderr
    assert not out.exists() and not list(tmp_path.iterdir())


def test_unparseable_rule_file_names_file_line_and_value(tmp_path: Path) -> None:
    bad = tmp_path / "bad.rules"
    bad.write_text("# behaviour: tracking\nIF range = [35, 999] THEN SET turn = 0 AND speed = 0 (strength 0.5)\n")
    r = coevo("learn", "--behaviour", "tracking", "--seed-policy", str(bad), "--out", str(tmp_path / "run"), "--quiet")
    assert r.returncode == 2
    assert "bad.rules" in r.stderr and "line 2" in r.stderr and "999" in r.stderr
    assert not (tmp_path / "run").exists()


def test_executive_without_partners_is_refused(tmp_path: Path) -> None:
    r = coevo("learn", "--behaviour", "executive", "--out", str(tmp_path / "run"), "--quiet")
    assert r.returncode == 2 and "--tracking" in r.stderr


def test_existing_output_directory_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    r = coevo("learn", "--behaviour", "tracking", "--generations", "1", "--population", "4", "--episodes", "10", "--out", str(out), "--quiet")
    assert r.returncode == 2 and "already exists" in r.stderr
    assert (out / "keep.txt").read_text() == "mine"


def test_bench_json_reports_both_figures_and_ratio() -> None:
    r = coevo("bench", "--lanes", "200", "--repeats", "1", "--baseline-seconds", "0.3", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["batched_steps_per_s"] > 0 and d["baseline_steps_per_s"] > 0
    assert d["ratio"] == pytest.approx(d["batched_steps_per_s"] / d["baseline_steps_per_s"])


def test_bench_times_at_least_one_baseline_episode_however_short_its_budget() -> None:
    """A budget shorter than one clock tick (or a busy CI machine) once left the baseline empty: ratio 1/0."""
    from coevo.tasks.fuel.bench import bench
    from coevo.tasks.fuel.settings import WorldConfig

    res = bench(world=WorldConfig(), lanes=1, repeats=1, rules=1, baseline_seconds=1e-12)
    assert res.baseline_robot_steps > 0 and res.ratio == pytest.approx(res.batched_steps_per_s / res.baseline_steps_per_s)


def test_bench_rejects_bad_sizes() -> None:
    r = coevo("bench", "--lanes", "0")
    assert r.returncode == 2 and "--lanes: invalid number 0" in r.stderr


class _Board:
    """A status board as `coevo status` sees it, filled with wide but plausible values."""

    def __init__(self, generation: int = 420, robot: bool = False) -> None:
        self.generation = generation
        self.robot = robot

    def robots_view(self) -> list[dict[str, object]]:
        if not self.robot:
            return []
        return [{"robot": "robot", "trial": 5007, "trials": 10100, "generation": 50, "performance": 37.0,
                 "rules_version": 31, "capabilities": ["far_left", "left", "front_left", "far_right"], "changes": 1,
                 "last_change": 5000, "rejected_by_reason": {"not_roster": 2}, "state": "alive"}]

    def snapshot(self) -> list[dict[str, object]]:
        rejected = {"flood": 99999, "not_msgpack": 17, "schema_version": 5, "wrong_behaviour": 1234}
        measures = {"executive": {"dock_choice": 23.4, "docking_success_rate": 40.0, "quality_tracking": 61.0},
                    "tracking": {"quality_tracking": 62.0}, "docking": {"docking_from_random": 71.0}}
        return [{"behaviour": b, "worker": f"{b}-7", "generation": self.generation, "generations": 500,
                 "best_fitness": 0.412345, "measures": measures[b], "buffered": 12, "rejected_by_reason": rejected,
                 "partner_versions": {p: 123 for p in measures if p != b}, "state": "stalled"}
                for b in ("executive", "tracking", "docking")]

    def broker_view(self) -> dict[str, object]:
        return {"state": "up", "stored": {"docking": 120, "executive": 480, "tracking": 333},
                "rejected": {"oversize": 3, "wrong_key": 12}, "dropped": 0}


def test_status_table_fits_80_columns_without_cutting_words() -> None:
    from rich.console import Console

    from coevo.bus.status import _status_rows, status_table

    board = _Board()
    console = Console(width=80, record=True, color_system=None)
    console.print(status_table(board, "run independent-20261123-140544 (independent)"))
    text = console.export_text()
    lines = text.splitlines()
    assert "…" not in text
    assert max(len(line) for line in lines) <= 80
    words = set(text.split())
    for row in _status_rows(board):
        for cell in row:
            for word in cell.split():
                assert word in words, word  # whole: wrapped between words, never inside one
    assert "stalled" in words and "wrong_behaviour" in words and "picks-D=23%" in words


def test_a_cel_runs_status_shows_the_robot_and_fits_80_columns() -> None:
    from rich.console import Console

    from coevo.bus.status import PlainStatus, status_table

    console = Console(width=80, record=True, color_system=None)
    console.print(status_table(_Board(robot=True), "CEL run cel-20261123-140544: 100 generations"))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80 and "…" not in text
    words = set(text.split())
    assert {"ext=37%", "v31,", "not_roster"} <= words
    robot = [line for line in PlainStatus().lines(_Board(robot=True)) if " robot " in line]
    assert len(robot) == 1 and "robot gen 50 ext=37% rules v31, 4 sensors, 1 changes" in robot[0], robot
    assert "best" not in robot[0] and "unconfirmed" not in robot[0]


def test_coevo_cels_table_says_what_the_run_is_doing_in_80_columns() -> None:
    from rich.console import Console

    from coevo.cel_service.status import CelPlain, cel_table

    class Cel(_Board):
        def snapshot(self) -> list[dict[str, object]]:
            return [{"behaviour": "door", "worker": "door-0", "generation": 51, "generations": 100, "best_fitness": 0.9,
                     "measures": {"success": 96.4}, "rejected_by_reason": {}, "state": "alive"}]

    console = Console(width=80, record=True, color_system=None)
    console.print(cel_table(100)(Cel(robot=True), "CEL run x: 100 generations"))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80
    for expected in ("51 / 100", "96 % success", "37 % of its last trials", "far_left, left, front_left, far_right",
                     "trial 5000 (generation 50), change 1", "learner alive, robot alive, broker up"):
        assert expected in " ".join(text.split()), expected
    plain = CelPlain(100)
    assert len(plain.lines(Cel(robot=True))) == 1 and plain.lines(Cel(robot=True)) == []


def test_status_as_plain_lines_one_per_worker_when_it_changes() -> None:
    from coevo.bus.status import PlainStatus

    plain = PlainStatus()
    first = plain.lines(_Board())
    assert len(first) == 4 and [line.split()[1] for line in first] == ["executive-7", "tracking-7", "docking-7", "broker"]
    assert not any(ch in "".join(first) for ch in "│┃─━┏┗")
    assert "gen 420/500 best 0.412 picks-D=23% docked=40% QT=61% with Dv123 Tv123" in first[0]
    assert plain.lines(_Board()) == []  # nothing changed, nothing printed
    assert len(plain.lines(_Board(generation=421))) == 3  # the workers moved on, the broker did not


def test_max_lead_off_is_not_the_same_as_not_given() -> None:
    """`coevo run --max-lead off` ran paced with a lead of 1: "off" parsed to None, which meant "not given"."""
    from coevo.cli import build_parser
    from coevo.console import max_lead_of

    def lead(*argv: str, default: int | None = 1) -> int | None:
        return max_lead_of(build_parser().parse_args(list(argv)).max_lead, default)

    assert lead("run", "--max-lead", "off") is None and lead("run") == 1 and lead("run", "--max-lead", "3") == 3
    assert lead("compare", "--max-lead", "off") is None and lead("cel", default=0) == 0


def test_a_worker_that_finishes_is_shown_done_never_dead_in_the_table_the_lines_and_json() -> None:
    """Its final heartbeat and its token's going travel apart (measured: "gen 50/50 ... dead", then "done"): a worker
    whose token goes after its heartbeats showed its last generation is done; one that goes mid-run is dead."""
    import json as _json
    import time as _time

    from rich.console import Console

    from coevo.bus import keys
    from coevo.bus.messages import Status, encode
    from coevo.bus.session import make_config, open_session
    from coevo.bus.status import PlainStatus, StatusBoard, status_table
    from coevo.runs.local import free_port, wait_until

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with open_session(make_config(mode="router", listen=[endpoint])) as router, \
            open_session(make_config(mode="client", connect=[endpoint], connect_timeout=10)) as worker:
        board = StatusBoard(router, "fin")
        plain = PlainStatus()
        for beh, gen in (("tracking", 50), ("docking", 20)):  # tracking finishes; docking dies at 20 of 50
            wid = f"{beh}-1"
            token = worker.liveliness().declare_token(keys.alive("fin", beh, wid))
            wait_until(lambda: any(w["worker"] == wid and w["state"] == "starting" for w in board.snapshot()), 10,
                       "starting (no generation done yet)")
            worker.put(keys.status("fin", beh, wid), encode(Status(run="fin", behaviour=beh, worker=wid, regime="mutual",
                                                                   generation=gen, generations=50, best_fitness=0.5,
                                                                   sent_at=_time.time())))
            wait_until(lambda: any(w["worker"] == wid and w["generation"] == gen for w in board.snapshot()), 10, "gen")
            token.undeclare()  # its done heartbeat not (yet) here
            wait_until(lambda: any(w["worker"] == wid and w["state"] not in ("alive", "starting") for w in board.snapshot()),
                       10, "gone")
        states = {w["worker"]: w["state"] for w in board.snapshot()}
        assert states == {"tracking-1": "done", "docking-1": "dead"}
        lines = plain.lines(board)
        assert any("tracking-1 gen 50/50" in x and x.endswith(" done") for x in lines), lines
        assert not any("tracking-1" in x and "dead" in x for x in lines), lines
        assert {w["worker"]: w["state"] for w in _json.loads(board.json_line())["workers"]}["tracking-1"] == "done"
        console = Console(width=100, record=True, color_system=None)
        console.print(status_table(board, "fin"))
        row = next(x for x in console.export_text().splitlines() if "tracking-1" in x)
        assert row.rstrip().endswith("done"), row
        board.close()


def test_a_loading_worker_is_starting_and_a_broker_already_up_is_never_first_shown_down() -> None:
    """Piped, coevo status printed "gen 0/0 ... alive" and "broker down" then "broker up" in its first second, and a
    worker that was loading showed "stalled"; each state now reads true from the first line."""
    from coevo.bus import keys
    from coevo.bus.messages import Status, encode
    from coevo.bus.session import make_config, open_session
    from coevo.bus.status import PlainStatus, StatusBoard
    from coevo.runs.local import free_port, wait_until

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with open_session(make_config(mode="router", listen=[endpoint])) as router, \
            open_session(make_config(mode="client", connect=[endpoint], connect_timeout=10)) as worker:
        broker_token = router.liveliness().declare_token(keys.BROKER)
        with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=10)) as follower:
            board = StatusBoard(follower, "st", stall=0.5)
            first = PlainStatus().lines(board)
            assert any(line.endswith("broker up stored -") for line in first), first  # up from the first line
            token = worker.liveliness().declare_token(keys.alive("st", "tracking", "tracking-0"))
            worker.put(keys.status("st", "tracking", "tracking-0"),
                       encode(Status(run="st", behaviour="tracking", worker="tracking-0", regime="mutual", generation=0,
                                     generations=50, best_fitness=0.0, sent_at=time.time())))
            wait_until(lambda: board.snapshot() and board.snapshot()[0]["generations"] == 50, 10, "the heartbeat")
            time.sleep(1.0)  # longer than --stall without a heartbeat: still loading, not stalled
            assert board.snapshot()[0]["state"] == "starting"
            lines = PlainStatus().lines(board)
            assert any(line.endswith("tracking-0 starting") for line in lines), lines
            board.workers["tracking-0"].generation = 1  # a generation done: its line in full, without rejections
            full = PlainStatus().lines(board)
            assert any("tracking-0 gen 1/50 best 0.000 stalled" in line for line in full), full
            assert all(len(line) <= 100 for line in full)
            token.undeclare()
            board.close()
        broker_token.undeclare()


def test_run_listen_on_a_port_in_use_is_one_line_before_anything_starts(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    from coevo.cli import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        code = main(["run", "--listen", f"tcp/127.0.0.1:{port}", "--root", str(tmp_path / "runs")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith(f"ConfigError: --listen tcp/127.0.0.1:{port}: cannot listen"), err
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("endpoint", ["nan", "-1", "/etc", "tcp/", "unixsock-stream/tmp/x.sock", "tcp/127.0.0.1:-1",
                                      "tcp/127.0.0.1:99999"])
def test_a_listen_endpoint_that_cannot_be_a_runs_broker_is_one_line_before_anything(
        endpoint: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from coevo.cli import main

    code = main(["run", "--run", "x", "--root", str(tmp_path / "root"), "--listen", endpoint])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("ConfigError: ") and endpoint in err[0], err
    assert not (tmp_path / "root").exists()


def test_a_learn_killed_mid_run_leaves_a_staged_copy_that_the_next_one_removes(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ("learn", "--behaviour", "docking", "--population", "4", "--episodes", "10", "--ga", "best_episodes=10",
            "--measure-epochs", "3", "--out", str(out), "--quiet")
    p = subprocess.Popen([sys.executable, "-m", "coevo", *args, "--generations", "500"])
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob(".run.*.partial/.owner")) and time.monotonic() < deadline:
            time.sleep(0.1)
    finally:
        p.kill()
        p.wait()
    [killed] = tmp_path.glob(".run.*.partial")  # a killed process cannot remove its copy
    live = tmp_path / ".run.live.partial"  # one that a running process of this host writes (this one)
    away = tmp_path / ".run.away.partial"  # one of another host sharing the folder: not ours to judge
    for d, owner in ((live, f"{socket.gethostname()} {os.getpid()}"), (away, f"elsewhere {p.pid}")):
        d.mkdir()
        (d / ".owner").write_text(owner)
    r = coevo(*args, "--generations", "1")
    assert r.returncode == 0, r.stderr
    assert not killed.exists() and live.exists() and away.exists()
    assert (out / "measures.json").exists() and not (out / ".owner").exists()


def test_a_reader_that_goes_away_ends_the_command_without_a_traceback() -> None:
    """``coevo run --ga help | head -0``: the reader is gone before the listing is written, and the command ends
    quietly with a shell's status for it (141: 128 + SIGPIPE), not in a BrokenPipeError or an "Exception ignored"."""
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-m", "coevo", "run", "--ga", "help"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    assert p.stdout is not None and p.stderr is not None
    p.stdout.close()  # before the interpreter has started: its first write finds no reader
    err = p.stderr.read().decode()
    assert p.wait(timeout=60) == 141 and "Traceback" not in err and "Exception" not in err, err
