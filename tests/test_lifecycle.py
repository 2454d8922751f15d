"""The lifecycle every process on the bus shares (coevo.bus.lifecycle): its order of ending, and its stop signal.

Real zenoh sessions (a peer on loopback that connects to no one) and real signals to a real process.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from coevo.broker.server import Broker
from coevo.bus.lifecycle import Lifecycle
from coevo.bus.session import make_config

PEER = dict(mode="peer", listen=["tcp/127.0.0.1:0"], connect_timeout=None)


class Ended:
    def __init__(self, log: list[str], name: str) -> None:
        self.log, self.name = log, name

    def __enter__(self) -> Ended:
        return self

    def __exit__(self, *exc: object) -> None:
        self.log.append(self.name)

    def undeclare(self) -> None:
        self.log.append(self.name)


def test_a_life_ends_what_it_holds_newest_first_once() -> None:
    ended: list[str] = []
    with Lifecycle(make_config(**PEER), what="test session") as life:
        life.enter(Ended(ended, "context manager"))
        life.start(lambda: life.stop.wait(10), name="waiter", wake=lambda: ended.append("woken"))
        life.declare(Ended(ended, "subscriber"))
        life.declare(life.session.declare_publisher("coevo/test/lifecycle"))
        life.at_end(lambda: ended.append("last registered"))
        assert not life.stop.is_set()
    assert ended == ["last registered", "subscriber", "woken", "context manager"]
    assert life.stop.is_set()
    life.close()  # again: nothing more happens
    assert ended == ["last registered", "subscriber", "woken", "context manager"]
    with pytest.raises(RuntimeError, match="not open"):
        life.session


# A process whose work drops every KeyboardInterrupt, as Python does for one raised in a finaliser (pymunk frees its
# objects in __del__): the signal must end it all the same, through its life's stop.
DEAF = """
import sys, time
from coevo.bus.lifecycle import Lifecycle, main_of
from coevo.bus.session import make_config

def work():
    with Lifecycle(make_config(mode="peer", listen=["tcp/127.0.0.1:0"], connect_timeout=None), what="deaf") as life:
        print("ready", flush=True)
        while not life.stop.is_set():
            try:
                time.sleep(0.05)
            except KeyboardInterrupt:
                pass
        return "ended"

sys.exit(130 if main_of(work) is None else 0)
"""


@pytest.mark.service
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_signal_ends_the_work_even_when_its_interrupt_is_dropped(sig: signal.Signals) -> None:
    from procs import ctrl_c_heard

    p = subprocess.Popen([sys.executable, "-c", DEAF], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=ctrl_c_heard)
    try:
        assert p.stdout is not None and p.stdout.readline().strip() == "ready"
        t0 = time.monotonic()
        p.send_signal(sig)
        assert p.wait(timeout=30) == 130, p.stderr.read() if p.stderr else ""
        assert time.monotonic() - t0 < 10
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()


def test_a_broker_closing_under_a_status_put_keeps_its_session_till_the_end(tmp_path: Path) -> None:
    # The broker's report thread reads the store's accounts, then puts each run's status.  Here it is held between
    # the two until close() has begun: its put must meet the session (or SessionGone), never a broker without one.
    closing, errors = threading.Event(), []
    hook = threading.excepthook
    threading.excepthook = lambda args: errors.append(args.exc_value)
    try:
        broker = Broker(make_config(mode="router", listen=["tcp/127.0.0.1:0"], connect_timeout=None), tmp_path,
                        status_every=0.01, open_runs=True)

        def held() -> dict[str, tuple[dict[str, int], dict[str, int], int]]:
            closing.wait(10)
            return {"run-a": ({}, {}, 0)}

        broker.store.accounts = held  # type: ignore[method-assign]
        with broker:
            time.sleep(0.05)  # the report thread is waiting in held()
            threading.Timer(0.05, closing.set).start()  # once close() is under way
        broker.close()  # again: nothing more happens
    finally:
        threading.excepthook = hook
    assert closing.is_set()
    assert errors == []
