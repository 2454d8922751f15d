"""A refused command changes nothing (issue 54).

Every command that writes into an existing directory reads every file it will read before it changes anything: a
damaged one is refused in one line naming it, status 2, no traceback, and the directory is left byte for byte as it
was (a digest of every path, kind, mode and content before and after).  Tried as a matrix of command x file x damage
(64 random bytes appended, cut to half, not UTF-8, a directory in its place, deleted), each command run in process
(tests/procs.py: ``coevo_main``, what ``python -m coevo`` runs, with what it prints and logs): a refusal comes before
anything starts, so a process of its own would add only an interpreter's start-up, about 170 of them.

A damage that a command is built to take is not refused: a log's bytes after what the checkpoint saw (a crash's
leftovers, cut aside by the resume), a store file (a replica of the workers' published.jsonl, set aside and refilled),
a done.json or summary.json (written again).  For those the matrix asks, in process, that the command's verification
finds nothing (their real resumes are run in tests/test_damaged_files.py and tests/test_faults.py); one finished run,
comparison and study (the session's shared ones, tests/conftest.py), a seeds folder and a CEL run (made for this
module) are copied for every case, so the matrix costs little CPU.
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from procs import coevo_main


from coevo.experiments.compare.experiment import held_spec, problems
from coevo.experiments.study.declaration import study_cells
from coevo.experiments.study.experiment import check_cells, held_declaration
from coevo.runs.local import LocalRun

pytestmark = pytest.mark.service


def _append(f: Path) -> None:
    with open(f, "ab") as fh:
        fh.write(random.Random(54).randbytes(64))


def _truncate(f: Path) -> None:
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])


def _not_utf8(f: Path) -> None:
    f.write_bytes(b"\xff\xfe" + f.read_bytes()[2:])


def _directory(f: Path) -> None:
    f.unlink()
    f.mkdir()


DAMAGES: dict[str, Callable[[Path], None]] = {"appended": _append, "truncated": _truncate, "not_utf8": _not_utf8,
                                              "directory": _directory, "deleted": Path.unlink}

#: The files of a finished run that ``coevo run --resume`` reads or replaces, and the damages it takes (not refused).
REPLACED = {"appended", "truncated", "not_utf8", "deleted"}  # a file the command writes again
RUN_FILES: dict[str, set[str]] = {
    "run.json": set(),
    "secret.key": set(),
    "workers/tracking/worker.json": set(),
    "workers/tracking/checkpoint.msgpack": set(),
    "workers/tracking/curve.jsonl": {"appended"},  # after what the checkpoint saw: cut aside, kept in .cut-1
    "workers/tracking/published.jsonl": {"appended"},
    "workers/docking/adoptions.jsonl": {"appended"},
    "store/tracking.jsonl": REPLACED,  # a replica of published.jsonl: set aside and refilled
    "workers/tracking/done.json": REPLACED,
    "summary.json": REPLACED,
    "logs/worker-tracking.log": REPLACED,  # appended to
    "code.json": {"deleted"},  # a run made before code.json: resumed as always, and given one
}

#: The files of a finished comparison that ``coevo compare --resume`` and ``--report-only`` read, and the damages
#: each takes.  A finished run's summary.json deleted makes it unfinished: resumed, or left out of the report.
RUN = "runs/independent-00"
COMPARE_FILES: dict[str, dict[str, set[str]]] = {
    "compare.json": {"resume": set(), "report-only": set()},
    f"{RUN}/summary.json": {"resume": {"deleted"}, "report-only": {"deleted"}},
    f"{RUN}/workers/executive/curve.jsonl": {"resume": set(), "report-only": set()},
    f"{RUN}/workers/docking/best.rules": {"resume": set(), "report-only": set()},
    "code.json": {"resume": {"deleted"}, "report-only": set(DAMAGES)},  # a report reads no code.json
}


#: The same for ``coevo study --resume`` and ``--report-only`` (a study of one cell, a comparison of one run).
CELL = "cells/00-all"
STUDY_FILES: dict[str, set[str]] = {
    "study.json": set(),
    f"{CELL}/compare.json": set(),
    f"{CELL}/{RUN}/summary.json": {"deleted"},
    f"{CELL}/{RUN}/workers/executive/curve.jsonl": set(),
}


#: The same for ``coevo seeds --resume`` (one docking seed): a run without its measures is unfinished and run again;
#: the report's files are written again.
SEEDS = ["seeds", "--behaviours", "docking", "--seeds", "1", "--generations", "2", "--learn-arg=--population=6",
         "--learn-arg=--episodes=4", "--learn-arg=--measure-epochs=1", "--quiet"]
SEEDS_FILES: dict[str, set[str]] = {
    "runs/docking-seed0/measures.json": {"deleted"},
    "runs/docking-seed0/timing.json": {"deleted"},
    "summary.json": REPLACED,
}


#: The same for ``coevo cel --resume``: the execution module's directory and the learner's own logs.
CEL_FILES: dict[str, set[str]] = {
    "execution/execution.json": set(),
    "execution/checkpoint.msgpack": set(),
    "execution/performance.jsonl": {"appended"},
    "workers/door/cases.jsonl": {"appended", "truncated", "not_utf8"},  # empty (no case base): all past the checkpoint
    "workers/door/changes.jsonl": {"appended"},
    "execution/done.json": REPLACED,
    "cel.json": REPLACED,
}


def coevo(*args: str) -> subprocess.CompletedProcess[str]:
    """``coevo ARGS`` as a process, for what the module makes (a comparison, a study, ...): 600 s, as
    tests/procs.py's shared runs (120 s ran out making the comparison under load 30)."""
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, errors="replace",
                          timeout=600)


def digest(d: Path) -> str:
    """Every path under ``d`` with its kind, mode and content, as one sha256."""
    h = hashlib.sha256()
    for root, dirs, files in sorted(os.walk(d)):
        dirs.sort()
        for name in sorted(dirs + files):
            p = Path(root) / name
            st = p.lstat()
            h.update(f"{p.relative_to(d)}\0{st.st_mode}\0".encode())
            if p.is_file():
                h.update(p.read_bytes())
    return h.hexdigest()


def refused_in_one_line(res: subprocess.CompletedProcess[str], f: Path) -> str:
    """The command's one-line refusal (status 2), which names ``f`` (a deleted one: its name and folder)."""
    assert "Traceback" not in res.stderr, res.stderr
    err = res.stderr.strip()
    assert res.returncode == 2 and len(err.splitlines()) == 1, (res.returncode, res.stdout, err)
    assert str(f) in err or (f.name in err and str(f.parent) in err), err
    return err


@pytest.fixture(scope="module")
def finished(finished_mutual: Path) -> Path:
    """A finished Mutual run: the session's shared one (tests/procs.py), read-only: each case changes a copy."""
    return finished_mutual


@pytest.fixture(scope="module")
def comparison(finished_comparison: Path) -> Path:
    """A finished comparison (one run a regime): the session's shared one, read-only."""
    return finished_comparison


@pytest.fixture(scope="module")
def study(finished_study: Path) -> Path:
    """A finished study of one cell: the session's shared one, read-only."""
    return finished_study


def made(factory: pytest.TempPathFactory, name: str, *argv: str) -> Path:
    """What ``coevo ARGV --out DIR`` (or ``--root``, for a CEL run) makes, for this module's cases to copy."""
    out = factory.mktemp(name) / name
    res = coevo(*argv, str(out))
    assert res.returncode == 0, res.stdout + res.stderr
    return out


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return made(tmp_path_factory, "sd", *SEEDS, "--out")


@pytest.fixture(scope="module")
def cel_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return made(tmp_path_factory, "cel", "cel", "--run", "c", "--generations", "3", "--fail", "2:front", "--population",
                "6", "--episodes", "4", "--quiet", "--root") / "c"


class TestRefusals:
    """One class, so that one xdist worker makes the module's run and comparison once and takes every case."""

    @pytest.mark.parametrize("how", DAMAGES)
    @pytest.mark.parametrize("name", RUN_FILES)
    def test_run_resume_refuses_a_damaged_file_and_changes_nothing(self, finished: Path, tmp_path: Path, name: str,
                                                                  how: str) -> None:
        run = tmp_path / finished.name
        shutil.copytree(finished, run)
        f = run / name
        DAMAGES[how](f)
        if how in RUN_FILES[name]:  # taken: the resume's verification finds nothing to refuse
            assert LocalRun.resumable(run).problems() == []
            return
        before = digest(run)
        refused_in_one_line(coevo_main("run", "--resume", str(run), "--measure-epochs", "1", "--quiet"), f)
        assert digest(run) == before

    @pytest.mark.parametrize("command", ["resume", "report-only"])
    @pytest.mark.parametrize("how", DAMAGES)
    @pytest.mark.parametrize("name", COMPARE_FILES)
    def test_compare_refuses_a_damaged_file_and_changes_nothing(self, comparison: Path, tmp_path: Path, name: str,
                                                                how: str, command: str) -> None:
        out = tmp_path / "cmp"
        shutil.copytree(comparison, out)
        f = out / name
        DAMAGES[how](f)
        if how in COMPARE_FILES[name][command]:
            spec = held_spec(out)
            assert spec is not None and problems(out, spec, report_only=command == "report-only") == []
            return
        before = digest(out)
        # no settings repeated: the comparison's own are used (compare.json)
        refused_in_one_line(coevo_main("compare", f"--{command}", "--out", str(out), "--quiet"), f)
        assert digest(out) == before

    def test_compare_resume_and_report_only_use_the_comparisons_own_settings(self, comparison: Path,
                                                                             tmp_path: Path) -> None:
        out = tmp_path / "cmp"
        shutil.copytree(comparison, out)
        for command in ("--resume", "--report-only"):
            res = coevo_main("compare", command, "--out", str(out), "--quiet")
            assert res.returncode == 0 and "Traceback" not in res.stderr, res.stdout + res.stderr
            assert "differs" not in res.stderr
        assert "2 of 2 runs already done, 0 to run" in coevo_main("compare", "--resume", "--out", str(out),
                                                                  "--quiet").stdout
        # a setting given that is not the comparison's is still refused, naming it
        res = coevo_main("compare", "--resume", "--out", str(out), "--runs", "2", "--quiet")
        assert res.returncode == 2 and "differs in: runs" in res.stderr and "Traceback" not in res.stderr

    @pytest.mark.parametrize("command", ["resume", "report-only"])
    @pytest.mark.parametrize("how", DAMAGES)
    @pytest.mark.parametrize("name", STUDY_FILES)
    def test_study_refuses_a_damaged_file_and_changes_nothing(self, study: Path, tmp_path: Path, name: str, how: str,
                                                              command: str) -> None:
        out = tmp_path / "st"
        shutil.copytree(study, out)
        f = out / name
        DAMAGES[how](f)
        if how in STUDY_FILES[name]:
            spec = held_declaration(out)
            assert spec is not None
            check_cells(out, study_cells(spec), report_only=command == "report-only")  # raises what it finds
            return
        before = digest(out)
        refused_in_one_line(coevo_main("study", f"--{command}", "--out", str(out), "--quiet"), f)
        assert digest(out) == before

    @pytest.mark.parametrize("how", DAMAGES)
    @pytest.mark.parametrize("name", CEL_FILES)
    def test_cel_resume_refuses_a_damaged_file_and_changes_nothing(self, cel_run: Path, tmp_path: Path, name: str,
                                                                   how: str) -> None:
        from coevo.cel_service.run import CelRun

        run = tmp_path / cel_run.name
        shutil.copytree(cel_run, run)
        f = run / name
        DAMAGES[how](f)
        if how in CEL_FILES[name]:
            assert CelRun.resumable(run).problems() == []
            return
        before = digest(run)
        refused_in_one_line(coevo_main("cel", "--resume", str(run), "--quiet"), f)
        assert digest(run) == before

    @pytest.mark.parametrize("how", DAMAGES)
    @pytest.mark.parametrize("name", SEEDS_FILES)
    def test_seeds_resume_refuses_a_damaged_file_and_changes_nothing(self, seeds: Path, tmp_path: Path, name: str,
                                                                     how: str) -> None:
        from coevo.experiments.seeds.experiment import problems as seeds_problems

        out = tmp_path / "sd"
        shutil.copytree(seeds, out)
        f = out / name
        DAMAGES[how](f)
        if how in SEEDS_FILES[name]:
            assert seeds_problems(out, ["docking"], [0]) == []
            return
        before = digest(out)
        refused_in_one_line(coevo_main(*SEEDS, "--resume", "--out", str(out)), f)
        assert digest(out) == before

    def test_a_resume_on_other_code_is_refused_unless_forced_and_an_old_run_resumes(self, finished: Path,
                                                                                     tmp_path: Path) -> None:
        from coevo.rundir.code import code_version
        from coevo.runs.check import check_run

        run = tmp_path / finished.name
        shutil.copytree(finished, run)
        code = run / "code.json"
        assert json.loads(code.read_text()) == {**code_version(), "earlier": []}
        code.unlink()  # a run made before code.json existed
        res = coevo_main("run", "--resume", str(run), "--measure-epochs", "1", "--quiet")  # complete: says so, no more
        assert res.returncode == 0 and "is complete" in res.stdout, res.stdout + res.stderr
        assert not code.exists()
        workers = run / "workers" / "tracking"
        (workers / "done.json").unlink()  # its last generation not done: there is something to continue
        res = coevo("run", "--resume", str(run), "--measure-epochs", "1", "--quiet")
        assert res.returncode == 0 and "is complete" not in res.stdout, res.stdout + res.stderr
        assert json.loads(code.read_text()) == {**code_version(), "earlier": []}
        other = {"package": "0.0.9", "source": "0123456789abcdef"}
        code.write_text(json.dumps({**other, "earlier": []}))
        (workers / "done.json").unlink()
        before = digest(run)
        err = refused_in_one_line(coevo_main("run", "--resume", str(run), "--measure-epochs", "1", "--quiet"), run)
        assert "coevo 0.0.9 (source 0123456789abcdef)" in err and code_version()["source"] in err and "--force" in err
        assert digest(run) == before
        res = coevo("run", "--resume", str(run), "--measure-epochs", "1", "--quiet", "--force")
        assert res.returncode == 0, res.stdout + res.stderr
        assert json.loads(code.read_text()) == {**code_version(), "earlier": [other]}
        check = check_run(run)
        assert check.ok, check.problems

    @pytest.mark.parametrize("command", ["compare", "study"])
    def test_a_comparison_or_study_on_other_code_is_refused_unless_forced(self, comparison: Path, study: Path,
                                                                           tmp_path: Path, command: str) -> None:
        from coevo.rundir.code import code_version

        out = tmp_path / command
        shutil.copytree(comparison if command == "compare" else study, out)
        code = out / ("code.json" if command == "compare" else f"{CELL}/code.json")
        other = {"package": "0.0.9", "source": "0123456789abcdef"}
        code.write_text(json.dumps({**other, "earlier": []}))
        before = digest(out)
        err = refused_in_one_line(coevo_main(command, "--resume", "--out", str(out), "--quiet"), code.parent)
        assert "coevo 0.0.9 (source 0123456789abcdef)" in err and code_version()["source"] in err and "--force" in err
        assert digest(out) == before
        res = coevo_main(command, "--resume", "--force", "--out", str(out), "--quiet")  # nothing left to run: a report
        assert res.returncode == 0, res.stdout + res.stderr
        assert json.loads(code.read_text()) == {**code_version(), "earlier": [other]}

    def test_replay_says_which_files_it_did_not_read(self, finished: Path, tmp_path: Path) -> None:
        run = tmp_path / finished.name
        shutil.copytree(finished, run)
        (run / "run.json").write_bytes(random.Random(54).randbytes(64))  # garbage a replay never reads
        res = coevo_main("replay", str(run))
        assert res.returncode == 0 and res.stdout.count("reproduced exactly") == 3, res.stdout + res.stderr
        last = res.stdout.splitlines()[-1]
        assert last.startswith("not read, so not vouched for: run.json, summary.json") and f"coevo check {run}" in last
        assert "workers/*/published.jsonl" in last and "workers/*/checkpoint.msgpack" in last

    def test_check_is_not_complete_for_a_run_whose_checkpoint_a_resume_refuses(self, finished: Path,
                                                                                tmp_path: Path) -> None:
        from coevo.runs.check import check_run

        run = tmp_path / finished.name
        shutil.copytree(finished, run)
        assert check_run(run, replay=False).ok
        f = run / "workers" / "tracking" / "checkpoint.msgpack"
        f.write_bytes(random.Random(54).randbytes(300))
        problems = check_run(run, replay=False).problems
        assert len(problems) == 1 and str(f) in problems[0], problems


def test_an_endpoint_of_an_unknown_protocol_is_refused_before_zenoh_tries_it() -> None:
    from coevo.bus.session import PROTOCOLS, check_endpoint
    from coevo.errors import ConfigError

    with pytest.raises(ConfigError, match="unknown protocol 'xyz'") as exc:
        check_endpoint("xyz/127.0.0.1:7447", listen=False)
    assert all(p in str(exc.value) for p in PROTOCOLS)
    for p in ("tcp/127.0.0.1:7447", "unixsock-stream//tmp/sock"):
        check_endpoint(p, listen=False)


class TestHistory:
    """``coevo learn --history RUN`` reads a run's partner logs as every reader does (in process: not about processes)."""

    @pytest.mark.parametrize("log", ["published.jsonl", "adoptions.jsonl"])
    def test_a_damaged_partner_log_is_refused_naming_file_and_line(self, finished: Path, tmp_path: Path,
                                                                   log: str) -> None:
        from coevo.agents.history import HistoryFeed
        from coevo.errors import RunDirError

        run = tmp_path / finished.name
        shutil.copytree(finished, run)
        HistoryFeed(run, 1.0, partners=("tracking", "docking"))
        f = run / "workers" / "docking" / log
        lines = len(f.read_bytes().splitlines())
        with open(f, "ab") as fh:
            fh.write(b"\xff\xfe\n")
        with pytest.raises(RunDirError, match=f"{f} line {lines + 1} is not UTF-8"):
            HistoryFeed(run, 1.0, partners=("tracking", "docking"))

    def test_a_run_of_another_task_is_named_as_such_not_as_unfinished(self, finished: Path, tmp_path: Path) -> None:
        from coevo.agents.history import HistoryFeed
        from coevo.errors import RunDirError
        from coevo.rundir.settings import RunSettings

        run = tmp_path / finished.name
        shutil.copytree(finished, run)
        RunSettings.make(run=run.name, task="door", regime="independent").save(run / "run.json")
        with pytest.raises(RunDirError, match="is a run of the door task .* holds no tracking or docking history"):
            HistoryFeed(run, 1.0, partners=("tracking", "docking"))


def test_cluster_says_at_once_where_it_connects_and_gives_up_after_its_timeout(tmp_path: Path) -> None:
    """``--cluster ADDRESS`` with nothing listening: a line naming the scheduler first, a line every 1.5 s while it
    waits, then one error after ``--cluster-timeout`` (it was 30 s of silence).  Nothing is timed from the start:
    under load 40 an interpreter took 20 s to print anything; the gaps between lines are what it controls."""
    import time

    p = subprocess.Popen([sys.executable, "-m", "coevo", "seeds", "--cluster", "tcp://127.0.0.1:1", "--cluster-timeout",
                          "8", "--out", str(tmp_path / "seeds"), "--quiet"], stderr=subprocess.PIPE, text=True)
    assert p.stderr is not None
    lines, times = [], []
    for line in p.stderr:
        lines.append(line.rstrip("\n"))
        times.append(time.monotonic())
    p.wait(timeout=60)
    assert "connecting to the Dask scheduler at tcp://127.0.0.1:1" in lines[0], lines
    assert p.returncode != 0 and not [x for x in lines if "Traceback" in x], lines
    assert lines[-1].startswith("ClusterLost: cannot reach the Dask scheduler tcp://127.0.0.1:1 within 8 s"), lines
    waits = lines[1:-1]
    assert len(waits) >= 3 and all(x.startswith("still connecting to the Dask scheduler at tcp://127.0.0.1:1") for x in waits)
    assert max(b - a for a, b in zip(times, times[1:])) < 6, times  # 1.5 s apart (a busy machine delays a wake-up)


def test_a_router_that_cannot_be_reached_is_said_while_it_is_waited_for() -> None:
    """``coevo status --connect`` to a port nobody listens on waits up to ``--connect-timeout`` (zenoh retries): a line
    every 1.5 s names what it reaches and how long it waits, then one error line (it was 30 s of silence, then a path
    of zenoh's Rust sources)."""
    r = coevo_main("status", "--run", "x", "--connect", "tcp/127.0.0.1:1", "--connect-timeout", "5", "--duration", "1")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) >= 2, r.stderr
    assert all(x.startswith("still opening the zenoh status session (connecting to tcp/127.0.0.1:1, giving up after "
                            "5 s: --connect-timeout): ") for x in lines[:-1]), lines
    assert lines[-1].startswith("ServiceError: cannot open the zenoh status session: Unable to connect to any of ")
    assert ".rs:" not in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize(("argv", "named"), [
    (["router", "--listen", "tcp/192.0.2.1:7447"], "tcp/192.0.2.1:7447"),  # not an address of this host
    (["router", "--listen", "tcp/999.1.1.1:7447"], "lookup address"),
    (["status", "--run", "x", "--connect", "tcp/127.0.0.1:9", "--connect-timeout", "0", "--duration", "1"],
     "tcp/127.0.0.1:9"),
    (["status", "--run", "x", "--connect", "tcp/127.0.0.1:9", "--listen", "tcp/192.0.2.1:7447"], "tcp/192.0.2.1:7447"),
    (["status", "--run", "x", "--config", "CONFIG"], "Unsupported file type"),
])
def test_zenoh_errors_are_said_in_one_line_without_zenohs_source_paths(argv: list[str], named: str,
                                                                       tmp_path: Path) -> None:
    config = tmp_path / "zenoh-config"
    config.write_text("{}")
    r = coevo_main(*[str(config) if a == "CONFIG" else a for a in argv])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert named in r.stderr and ".rs:" not in r.stderr and ".cargo" not in r.stderr, r.stderr


def test_compare_resume_of_a_folder_without_a_comparison_and_no_settings_is_refused(tmp_path: Path) -> None:
    """``coevo compare --resume --out TYPO`` used to start the report's whole default comparison there (20 runs at
    the report's parameters), silently for minutes; without a compare.json or any setting there is nothing to
    continue.  With settings it still starts one (the same command line each time: start, then continue)."""
    for out in (tmp_path / "missing", tmp_path):
        r = coevo_main("compare", "--resume", "--out", str(out), "--quiet")
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert r.stderr.startswith(f"ConfigError: --resume: {out} holds no comparison (no compare.json)"), r.stderr
    assert not (tmp_path / "missing").exists() and list(tmp_path.iterdir()) == []


def test_a_learn_stopped_by_sigterm_leaves_no_partial_folder(tmp_path: Path) -> None:
    """``coevo learn`` writes its folder under a hidden temporary name; SIGTERM (a scheduler's, a backend's stop) now
    removes it as a Ctrl-C does, where it used to end the process at once and leave ``.NAME.*.partial`` behind."""
    from coevo.runs.local import wait_until

    p = subprocess.Popen([sys.executable, "-m", "coevo", "learn", "--behaviour", "docking", "--generations", "1000",
                          "--population", "6", "--episodes", "4", "--out", str(tmp_path / "x"), "--quiet"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        wait_until(lambda: list(tmp_path.glob(".x.*.partial/config.json")) or p.poll() is not None, 60,
                   "coevo learn's staged folder")
        assert p.poll() is None
    finally:
        p.terminate()
        _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == []
