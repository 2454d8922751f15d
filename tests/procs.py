"""Helpers for the tests that run coevo as real processes: start, wait, stop, and a broker fixture."""

from __future__ import annotations

import fcntl
import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from coevo.bus import keys
from coevo.bus.session import make_config, open_session
from coevo.runs.local import end_processes, free_port, wait_until

__all__ = ["SMALL", "poll", "coevo_proc", "coevo_main", "stop", "broker", "ctrl_c_heard", "made_once", "copy_of", "finished_mutual",
           "finished_independent", "finished_comparison", "finished_study", "three_run_comparison", "said_when_made",
           "FINISHED_MUTUAL", "FINISHED_INDEPENDENT", "FINISHED_COMPARISON", "FINISHED_STUDY", "THREE_RUN_COMPARISON"]

SMALL = ["--population", "6", "--episodes", "10", "--ga", "best_episodes=10", "--ga", "initial_rules=8"]

poll = wait_until  # fails the test with what it waited for


def ctrl_c_heard() -> None:
    """``preexec_fn`` for a child a test sends Ctrl-C (SIGINT): its default action, whatever the suite inherited.

    A shell starts a background job (``pytest ... &`` in a script) with SIGINT ignored, the children inherit that,
    and Python then installs no KeyboardInterrupt handler: the child never hears the test's Ctrl-C, as it should
    not (a user's ``coevo run &`` in a script is meant to be deaf to the terminal's Ctrl-C).  Seen in a fresh-clone
    run of the suite started in the background."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def coevo_proc(*args: str, log: Path) -> subprocess.Popen:
    with open(log, "wb") as f:
        return subprocess.Popen([sys.executable, "-m", "coevo", "--log-level", "INFO", *args], stdout=f,
                                stderr=subprocess.STDOUT)


def coevo_main(*args: str) -> subprocess.CompletedProcess[str]:
    """``coevo ARGS`` in this process (coevo.cli.main, as ``python -m coevo`` runs it), for a refusal that happens
    before anything starts: no interpreter started for it (0.5-1 CPU-s each, numpy and pydantic imported again).
    Its exit status (a bad flag's SystemExit included), what it printed, and what it logged at WARNING and above,
    as the process's basicConfig handler would print it, on stderr."""
    import contextlib
    import io
    import logging

    from coevo.cli import main

    out, err = io.StringIO(), io.StringIO()
    handler = logging.StreamHandler(err)
    handler.setLevel(logging.WARNING)
    logging.getLogger().addHandler(handler)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(args))
            except SystemExit as exc:  # argparse: a bad flag or value, --help
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        logging.getLogger().removeHandler(handler)
    return subprocess.CompletedProcess(["coevo", *args], code, out.getvalue(), err.getvalue())


def stop(p: subprocess.Popen) -> None:
    end_processes([p])


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """A ``coevo broker`` process on a free loopback port: (endpoint, data directory)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    data = tmp_path / "data"
    p = coevo_proc("broker", "--listen", endpoint, "--data-dir", str(data), "--open", log=tmp_path / "broker.log")
    with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=20)) as s:
        poll(lambda: any(r.ok is not None for r in s.liveliness().get(keys.BROKER, timeout=1.0)), 20, "the broker token")
    yield endpoint, data
    stop(p)
    assert p.returncode == 0, (tmp_path / "broker.log").read_text()


# ---------------------------------------------------------------- what tests share: made once per test session
def made_once(factory: pytest.TempPathFactory, name: str, make: Callable[[Path], None]) -> Path:
    """The directory ``name``, made by ``make(path)`` once per test session and shared by every test (and every
    xdist worker) that asks for it: the whole suite's cost is mostly the processes its runs start (docs/development.md),
    so tests that only read a finished run, comparison or study read one.  Under xdist the workers' base temporary
    directories (``popen-gwN``) share a parent, the session's; a lock file there makes the first worker to ask make it
    while the others wait.  A make that failed is not tried again by each later test: they fail at once with its error.

    Shared means read-only: a test that changes what it was given works on :func:`copy_of` it."""
    base = factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    root = base / "shared"
    root.mkdir(exist_ok=True)
    out, done, failed = root / name, root / f"{name}.done", root / f"{name}.failed"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when closed, also when this process dies
        if failed.exists():
            pytest.fail(f"the shared {name} could not be made (the first test that asked says why): "
                        f"{failed.read_text()}")
        if not done.exists():
            if out.exists():
                shutil.rmtree(out)
            try:
                make(out)
            except BaseException as exc:
                failed.write_text(f"{type(exc).__name__}: {exc}"[:3000])
                raise
            done.write_text(tree_digest(out))  # tests/conftest.py checks it at the session's end: nobody changed it
    return out


def tree_digest(root: Path) -> str:
    """Each file under ``root``, its size and its time of change: what a test that changed a shared directory
    (instead of a copy) would have moved."""
    return "".join(f"{p.relative_to(root)} {p.stat().st_size} {p.stat().st_mtime_ns}\n"
                   for p in sorted(root.rglob("*")) if p.is_file())


def copy_of(shared: Path, where: Path) -> Path:
    """A copy of a shared directory, under its own name (a run's run.json names it), to change."""
    out = where / shared.name
    shutil.copytree(shared, out)
    return out


def _coevo_ok(*args: str, said: Path | None = None) -> None:
    """``coevo ARGS`` as a process, which must end with status 0; what it printed kept in ``said``, if given."""
    r = subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    if said is not None:
        said.write_text(r.stdout)


#: A finished Mutual run, as small as a run can be while each worker has a few generations: 3 generations of 6
#: episodes-4 policies, seed 0.  tests/test_damaged_files.py damages copies of it, tests/test_service.py replays it
#: and tampers with a copy, tests/test_faults.py damages a copy's checkpoint.
FINISHED_MUTUAL = ["run", "--regime", "mutual", "--generations", "3", "--population", "6", "--episodes", "4",
                   "--measure-epochs", "1", "--run", "small", "--quiet"]
#: A finished Independent run (the history an offline Executive learns from): 4 generations at SMALL.
FINISHED_INDEPENDENT = ["run", "--regime", "independent", "--run", "hist", "--generations", "4", *SMALL,
                        "--measure-epochs", "2", "--quiet"]


@pytest.fixture(scope="session")
def finished_mutual(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The run directory of FINISHED_MUTUAL, made once per session (read-only: change a :func:`copy_of` it)."""
    root = made_once(tmp_path_factory, "mutual-run", lambda out: _coevo_ok(*FINISHED_MUTUAL, "--root", str(out)))
    return root / "small"


@pytest.fixture(scope="session")
def finished_independent(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The run directory of FINISHED_INDEPENDENT, made once per session (read-only)."""
    root = made_once(tmp_path_factory, "independent-run",
                     lambda out: _coevo_ok(*FINISHED_INDEPENDENT, "--root", str(out)))
    return root / "hist"


#: A finished comparison, the smallest with both regimes: one run each, 3 generations of 4 episodes-4 policies.
#: tests/test_refusals.py damages copies of it, tests/test_replicates.py compares it with the same comparison on Dask.
FINISHED_COMPARISON = ["compare", "--runs", "1", "--generations", "3", "--population", "4", "--episodes", "4",
                       "--measure-epochs", "1", "--quiet"]
#: A finished study of one cell (regime=independent), a comparison of one run at FINISHED_COMPARISON's sizes.
FINISHED_STUDY = ["study", "--factor", "regime=independent", "--runs", "1", "--generations", "3", "--population", "4",
                  "--episodes", "4", "--measure-epochs", "1", "--quiet"]


@pytest.fixture(scope="session")
def finished_comparison(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The comparison directory of FINISHED_COMPARISON (its runs under runs/mutual-00 and runs/independent-00), made
    once per session (read-only: change a :func:`copy_of` it)."""
    return made_once(tmp_path_factory, "comparison", lambda out: _coevo_ok(*FINISHED_COMPARISON, "--out", str(out)))


@pytest.fixture(scope="session")
def finished_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The study directory of FINISHED_STUDY (its one cell under cells/00-all), made once per session (read-only)."""
    return made_once(tmp_path_factory, "study", lambda out: _coevo_ok(*FINISHED_STUDY, "--out", str(out)))


#: A finished comparison of both regimes, 3 runs each, the fewest that give a regime a 95 % interval and the
#: dashboard a band (3 generations of population 4, episodes 4): tests/test_compare.py reads its report and resumes a
#: copy, tests/test_dashboard.py opens it in a browser.
THREE_RUN_COMPARISON = ["compare", "--runs", "3", "--generations", "3", "--population", "4", "--episodes", "4", "--ga",
                        "best_episodes=4", "--ga", "initial_rules=8", "--measure-epochs", "2", "--jobs", "2", "--quiet"]


def said_when_made(shared: Path) -> str:
    """What the command that made a shared directory printed (kept beside it by the fixtures that keep it)."""
    return (shared.parent / f"{shared.name}.stdout").read_text()


@pytest.fixture(scope="session")
def three_run_comparison(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The comparison directory of THREE_RUN_COMPARISON (runs/mutual-00 ... runs/independent-02), made once per
    session (read-only); what ``coevo compare`` printed making it: :func:`said_when_made`."""
    return made_once(tmp_path_factory, "three-run-comparison",
                     lambda out: _coevo_ok(*THREE_RUN_COMPARISON, "--out", str(out),
                                           said=out.parent / f"{out.name}.stdout"))
