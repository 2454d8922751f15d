"""Damaged run files (issue 39): every reader of a run directory, as a real command, says what is wrong in one line.

One small finished run (the session's, shared with other modules: tests/procs.py) is copied for each case; one file
of the copy is damaged in one way (not UTF-8, not a JSON object, NaN, fields of the wrong type, a torn last line) and
each command that reads that file is run on it: coevo's own main() in the test's process (procs.coevo_main, what
``python -m coevo`` runs, without an interpreter started for each of some 35 reads), and ``coevo run --resume``, which
starts processes, as a process.  None may end in a traceback (in process: raise anything but its one-line error);
each names the file (and the line, for a log)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from procs import coevo_main, copy_of

from coevo.broker.store import PolicyStore
from coevo.dashboard.model import RunFiles
from coevo.rundir.layout import read_jsonl, read_store

pytestmark = pytest.mark.service

#: One appended line of each kind of damage (the torn one has no newline: a write cut short).
LINES = {
    "not_utf8": b"\xff\xfe\n",
    "not_object": b"1\n",
    "nan": b'{"generation": NaN, "version": NaN, "fitness": NaN}\n',
    "wrong_types": b'{"generation": "4", "version": "2", "partner": 3, "rules": []}\n',
    "torn": b'{"generation": 4, "vers',
}

#: The logs of a run directory, and the commands beyond coevo check (which reads them all) that read each; the
#: dashboard reads them too (an in-process test below), coevo show none of them.
LOGS = {
    "published": ("workers/tracking/published.jsonl", []),
    "adoptions": ("workers/docking/adoptions.jsonl", ["replay"]),
    "curve": ("workers/tracking/curve.jsonl", ["replay"]),
    "store": ("store/tracking.jsonl", ["replay", "history"]),
}

#: run.json damaged in each way (read by coevo check and coevo show; coevo replay reads each worker.json).
SETTINGS: dict[str, Callable[[bytes], bytes]] = {
    "not_utf8": lambda text: b"\xff" + text,
    "not_object": lambda text: b"[1]\n",
    "nan": lambda text: text.replace(b'"seed": 0', b'"seed": NaN'),
    "torn": lambda text: text[: len(text) // 2],
}


@pytest.fixture
def finished(finished_mutual: Path) -> Path:
    """The session's small finished Mutual run (tests/procs.py: FINISHED_MUTUAL, run "small"), shared with the other
    tests that read one; each case here damages a copy of it."""
    return finished_mutual


def coevo(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, errors="replace",
                          timeout=120)


def reader(command: str, run: Path, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    args = {"check": ["check", str(run)], "replay": ["replay", str(run)], "show": ["show", str(run), "--rules"],
            "history": ["learn", "--behaviour", "executive", "--history", str(run), "--generations", "1",
                        "--population", "4", "--episodes", "2", "--measure-epochs", "1", "--quiet",
                        "--out", str(tmp_path / "learned")]}[command]
    return coevo_main(*args)  # a reader of files: coevo's main() in this process, no interpreter started for it


def one_line_naming(res: subprocess.CompletedProcess[str], path: Path) -> str:
    """The command's one-line error (exit status 2), which names ``path``."""
    assert "Traceback" not in res.stderr, res.stderr
    err = res.stderr.strip()
    assert res.returncode == 2 and len(err.splitlines()) == 1 and str(path) in err, (res.returncode, err)
    return err


def damage_log(run: Path, log: str, damage: str) -> tuple[Path, str]:
    """Append a damaged line to one log of ``run``: the file, and how a reader names its line."""
    f = run / LOGS[log][0]
    lines = len(f.read_bytes().splitlines())
    with open(f, "ab") as fh:
        fh.write(LINES[damage])
    return f, f"{f} line {lines + 1} "

class TestDamagedRuns:
    """The cases on the session's finished run (made once, whichever worker asks first)."""

    @pytest.mark.parametrize("damage", LINES)
    def test_coevo_check_names_each_damaged_line_in_one_line(self, finished: Path, tmp_path: Path,
                                                             damage: str) -> None:
        run = copy_of(finished, tmp_path)
        where = [damage_log(run, log, damage)[1] for log in LOGS]
        res = reader("check", run, tmp_path)
        assert "Traceback" not in res.stderr, res.stderr
        problems = [p for p in res.stdout.splitlines() if p.startswith("PROBLEM: ")]
        assert res.returncode == 1, problems
        assert all(any(p.startswith(f"PROBLEM: {w}") for p in problems) for w in where), problems


    @pytest.mark.parametrize("damage", LINES)
    @pytest.mark.parametrize("log", [log for log, (_, readers) in LOGS.items() if readers])
    def test_replay_and_learn_history_refuse_a_damaged_line_in_one_line_naming_file_and_line(
            self, finished: Path, tmp_path: Path, log: str, damage: str) -> None:
        run = copy_of(finished, tmp_path)
        f, where = damage_log(run, log, damage)
        for command in LOGS[log][1]:
            assert where in one_line_naming(reader(command, run, tmp_path), f), command


    @pytest.mark.parametrize("damage", SETTINGS)
    def test_a_damaged_run_json_is_one_line_naming_it(self, finished: Path, tmp_path: Path, damage: str) -> None:
        run = copy_of(finished, tmp_path)
        f = run / "run.json"
        f.write_bytes(SETTINGS[damage](f.read_bytes()))
        res = reader("check", run, tmp_path)
        assert "Traceback" not in res.stderr, res.stderr
        assert res.returncode == 1 and f"PROBLEM: {str(f)!r}" in res.stdout, res.stdout
        one_line_naming(reader("show", run, tmp_path), f)


    def test_the_dashboard_skips_damaged_lines_and_says_so(self, finished: Path, tmp_path: Path) -> None:
        run = copy_of(finished, tmp_path)
        for name, _ in LOGS.values():
            with open(run / name, "ab") as fh:
                fh.write(b"".join(LINES.values()))
        view = RunFiles(run).read()
        # not UTF-8, not an object, NaN (and on the curve, a line without its columns) skipped; the torn line waits for
        # its end, as a line being written does
        for name, bad in (("workers/tracking/curve.jsonl", 4), ("workers/docking/adoptions.jsonl", 3),
                          ("store/tracking.jsonl", 3)):
            assert f"{run / name}: {bad} damaged lines skipped" in view.problems, view.problems
        assert {w["behaviour"]: w["generation"] for w in view.workers} == {"tracking": 3, "docking": 3, "executive": 3}


    def test_a_store_file_of_random_bytes_is_kept_aside_and_refilled_by_a_resumed_run(
            self, finished: Path, tmp_path: Path) -> None:
        run = copy_of(finished, tmp_path)
        garbage = bytes(range(14, 247))  # 233 bytes, no newline: the broker reads it as a torn last line
        (run / "store" / "tracking.jsonl").write_bytes(garbage)
        res = coevo("run", "--resume", str(run), "--measure-epochs", "1", "--quiet")
        assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr
        assert (run / "store" / "tracking.jsonl.cut-1").read_bytes() == garbage  # what the broker cut, kept
        res = reader("check", run, tmp_path)
        assert res.returncode == 0 and "complete (replay exact)" in res.stdout, res.stdout + res.stderr


    def test_a_store_reload_keeps_what_it_cuts_and_skips_damaged_lines(self, finished: Path, tmp_path: Path) -> None:
        run = copy_of(finished, tmp_path)
        f = run / "store" / "tracking.jsonl"
        whole = f.read_bytes()
        f.write_bytes(LINES["not_utf8"] + whole + LINES["torn"])
        store = PolicyStore(tmp_path)
        assert store.history("small", "tracking") == read_store(finished / "store" / "tracking.jsonl")
        assert f.read_bytes() == LINES["not_utf8"] + whole  # the damaged line in the middle stays, as it was
        assert (run / "store" / "tracking.jsonl.cut-1").read_bytes() == LINES["torn"]


    def test_a_resume_keeps_what_it_cuts_back(self, finished: Path, tmp_path: Path) -> None:
        run = copy_of(finished, tmp_path)
        curve = run / "workers" / "tracking" / "curve.jsonl"
        rows = read_jsonl(curve)
        with open(curve, "ab") as fh:
            fh.write(LINES["torn"])
        res = coevo("run", "--resume", str(run), "--measure-epochs", "1", "--quiet")
        assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr
        assert read_jsonl(curve) == rows
        assert (curve.parent / "curve.jsonl.cut-1").read_bytes() == LINES["torn"]
