"""Helpers for the tests that run coevo as real processes: start, wait, stop, and a broker fixture."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from coevo.bus import keys
from coevo.bus.session import make_config, open_session
from coevo.runs.local import end_processes, free_port, wait_until

__all__ = ["SMALL", "poll", "coevo_proc", "stop", "broker", "ctrl_c_heard"]

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
