"""Helpers for the tests that run coevo as real processes: start, wait, stop, and a broker fixture."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from coevo.bus import keys
from coevo.bus.session import make_config, open_session
from coevo.runs.local import end_processes, free_port, wait_until

__all__ = ["SMALL", "poll", "coevo_proc", "stop", "broker"]

SMALL = ["--population", "6", "--episodes", "10", "--ga", "best_episodes=10", "--ga", "initial_rules=8"]

poll = wait_until  # fails the test with what it waited for


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
