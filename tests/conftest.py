"""The suite's shared set-up.

**What tests share** (issue 53: the whole suite is bound by the processes its runs start; docs/development.md).  Each
of these session fixtures is made once per test session, by the first test (of any xdist worker) that asks, under a
file lock (tests/procs.py: ``made_once``), and is read-only: a test that damages, resumes or otherwise changes one
works on ``copy_of(it, tmp_path)``; the session fails at its end if a test changed a shared one.  Asking for any of
them makes a test a ``service`` test (the whole suite's, ``--all``).

- ``finished_mutual``: a finished Mutual run of the fuel task, 3 generations, population 6, episodes 4, seed 0
  (``procs.FINISHED_MUTUAL``; the run directory ``.../small``).
- ``finished_independent``: a finished Independent run, 4 generations at ``procs.SMALL`` (``.../hist``), the history
  an offline Executive learns from.
- ``finished_comparison``: a finished ``coevo compare`` of both regimes, one run each (``runs/mutual-00``,
  ``runs/independent-00``), 3 generations of population 4, episodes 4 (``procs.FINISHED_COMPARISON``).
- ``finished_study``: a finished ``coevo study`` of one cell, ``regime=independent`` (``cells/00-all``), a comparison
  of one run at the same sizes (``procs.FINISHED_STUDY``).
- ``three_run_comparison``: a finished ``coevo compare`` of both regimes, 3 runs each (the fewest that give a 95 %
  interval and the dashboard's band), 3 generations of population 4, episodes 4 (``procs.THREE_RUN_COMPARISON``);
  what the command printed making it: ``procs.said_when_made(it)``.
- ``broker``: not shared, a ``coevo broker`` of the test's own on a free loopback port.

A new one: a ``FINISHED_...`` command and a session fixture calling ``made_once`` in tests/procs.py, imported here.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest
from procs import (  # noqa: F401  (fixtures for every test module)
    broker,
    finished_comparison,
    finished_independent,
    finished_mutual,
    finished_study,
    three_run_comparison,
)

from coevo.config import GAConfig
from coevo.tasks.fuel.settings import WorldConfig


@pytest.fixture
def world_cfg() -> WorldConfig:
    return WorldConfig()


@pytest.fixture
def small_ga() -> GAConfig:
    return GAConfig(generations=2, population=6, episodes=20, best_episodes=20, initial_rules=8)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


# ---------------------------------------------------------------- Dask's clusters, idle
#: The Dask clusters the tests start (``--cluster local:2``, a scheduler and workers by hand) without Dask's own
#: diagnostics: each worker's statistical profiler (a sample every 10 ms, for Dask's dashboard, which no test opens) and
#: the 20 ms tick that watches for a blocked event loop.  An idle local:2 cluster cost 3-4.5 CPU-s a minute with them,
#: under 1 without (60 s idle, twice each, alternated; docs/development.md), and a test's cluster idles most of its
#: life while its replicates run.  Environment variables, so the processes the tests start inherit them; what Dask
#: schedules and how is unchanged, and a user's clusters keep Dask's defaults.
for _name, _value in (("DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED", "False"),
                      ("DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL", "500ms")):
    os.environ.setdefault(_name, _value)


# ---------------------------------------------------------------- bytecode, once
def pytest_configure(config: pytest.Config) -> None:
    """Under PYTHONDONTWRITEBYTECODE (set on this kind of machine), Python never caches coevo's compiled modules (an
    editable install has none: pip compiles only what it copies), so each of the suite's hundreds of processes
    compiled the modules it imports again: a tiny five-process run cost 3.9 CPU-seconds, 3.5 with them compiled
    (docs/development.md).  The controller compiles them once, before the xdist workers start; a module edited later
    is compiled again on import, as always (the cache records its source's time and size)."""
    if sys.dont_write_bytecode and not hasattr(config, "workerinput"):
        import compileall

        import coevo

        for where in (Path(coevo.__file__).parent, Path(__file__).parent):
            compileall.compile_dir(where, quiet=1)


# ---------------------------------------------------------------- the two test sets
#: The fixtures that start processes (the broker, and the shared finished run, comparison and study): a test that
#: asks for one is a service test.
SHARED_PROCESSES = {"broker", "finished_mutual", "finished_independent", "finished_comparison", "finished_study",
                    "three_run_comparison"}


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--all", action="store_true",
                     help="also run the tests that start processes (service, faults, trust, deploy, whole comparisons): "
                          "the whole suite, what CI runs")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Without --all, the fast set: tests marked service or slow (and any using the broker fixture or a shared finished
    run, processes) are
    left out, and say so in the summary.  With it, the slow tests first, then the other service tests, then the rest
    (each in file order), for the scheduler below: the longest start first and short ones fill in at the end."""
    for item in items:
        if SHARED_PROCESSES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.service)
    if config.getoption("--all"):
        items.sort(key=lambda i: 0 if i.get_closest_marker("slow") else 1 if i.get_closest_marker("service") else 2)
        return
    keep = [i for i in items if not (i.get_closest_marker("service") or i.get_closest_marker("slow"))]
    dropped = [i for i in items if i not in keep]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = keep


# ---------------------------------------------------------------- how many xdist workers, and the order they take tests in
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """``-n auto`` (addopts): one worker more than this machine has cores.  Many tests spend much of their time
    waiting on the processes and sessions they start; a third worker on 2 cores uses that time (the whole suite
    6 min 52 s with two workers, 5 min 58 s with three, back to back on a quiet machine; the fast set 59 s and 56 s).
    PYTEST_XDIST_AUTO_NUM_WORKERS, when set, still decides."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return cores + 1


def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object:
    """For ``--dist load`` (addopts): the xdist workers take tests one at a time in collection order (above: slow
    first with --all), the tests of a class together (one worker sets up their class or module fixture once).

    xdist's own load scheduling hands out runs of consecutive tests in file order, so the slow tests that come last
    in the files (the trust end-to-end runs) ran last, one worker busy while the other idled (14-37 s on 2 cores).
    (Its loadgroup does not group under pytest 9: xdist 3.8 renames the items' ``_nodeid``, which pytest 9 no longer
    reads; hence a class here.)"""
    if config.getvalue("dist") != "load":
        return None  # another --dist asked for on the command line: xdist's own
    from xdist.scheduler import LoadScopeScheduling

    class OneAtATime(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            parts = nodeid.split("::")
            return "::".join(parts[:2]) if len(parts) > 2 else nodeid  # a test in a class: the class

    config.option.loadscopereorder = False  # collection order, not the largest class first
    return OneAtATime(config, log)


# ---------------------------------------------------------------- where the suite's CPU goes
@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> object:
    """With COEVO_TEST_CPU=FILE, each test's CPU-seconds (setup, call and teardown; this process and the processes
    it started and reaped, which is all of them: a test waits for what it starts) and wall seconds are appended to
    FILE as ``cpu wall nodeid``.  The suite is bound by CPU on 2 cores, so this, not --durations, says where its time
    goes (docs/development.md)."""
    path = os.environ.get("COEVO_TEST_CPU")
    if not path:
        yield
        return
    import resource
    import time

    def cpu() -> float:
        return sum(u.ru_utime + u.ru_stime for u in (resource.getrusage(resource.RUSAGE_SELF),
                                                     resource.getrusage(resource.RUSAGE_CHILDREN)))

    c0, w0 = cpu(), time.monotonic()
    yield
    with open(path, "a", encoding="utf-8") as f:
        f.write(f"{cpu() - c0:.2f} {time.monotonic() - w0:.2f} {item.nodeid}\n")


# ---------------------------------------------------------------- what tests share stayed as it was made
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """The directories made once and shared (tests/procs.py: made_once) are read-only for the tests: one a test
    changed would make the tests after it depend on the order they ran in.  The controller (or the only process,
    without xdist) compares each with what it held when it was made, and fails the session if one moved."""
    if hasattr(session.config, "workerinput") or not hasattr(session.config, "_tmp_path_factory"):
        return
    from procs import tree_digest

    shared = session.config._tmp_path_factory.getbasetemp() / "shared"
    moved = [d.name.removesuffix(".done") for d in sorted(shared.glob("*.done"))
             if d.read_text() != tree_digest(shared / d.name.removesuffix(".done"))]
    if moved:
        session.config.get_terminal_writer().line(
            f"a test changed the shared {', '.join(moved)} (tests/procs.py: made_once) instead of a copy", red=True)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
