"""Pacing over real Zenoh sessions on loopback: a worker waits for slow partners, not for absent ones."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import pytest

from coevo.agents.pacing import Pacer, parse_max_lead
from coevo.bus import keys
from coevo.bus.messages import Status, encode
from coevo.bus.session import make_config, open_session
from coevo.errors import ConfigError
from coevo.tasks.fuel.behaviours import Behaviour

RUN = "pace"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture
def sessions() -> Iterator[tuple[object, object]]:
    """A router session (the pacer's side) and a client session (the partner's side)."""
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    with open_session(make_config(mode="router", listen=[endpoint])) as router, \
            open_session(make_config(mode="client", connect=[endpoint], connect_timeout=10)) as client:
        yield router, client


def _report(session: object, behaviour: str, generation: int, *, done: bool = False) -> None:
    msg = Status(run=RUN, behaviour=behaviour, worker=f"{behaviour}-0", regime="mutual", generation=generation,
                 generations=10, best_fitness=0.0, done=done, sent_at=time.time())
    session.put(keys.status(RUN, Behaviour(behaviour), f"{behaviour}-0"), encode(msg))


def test_parse_max_lead_accepts_off_and_counts_and_names_bad_values() -> None:
    assert parse_max_lead("off") is None and parse_max_lead(None) is None
    assert parse_max_lead("0") == 0 and parse_max_lead(3) == 3
    for bad in ("-1", "two", "1.5"):
        with pytest.raises(ConfigError, match=repr(bad) if bad != "-1" else "-1"):
            parse_max_lead(bad)


def test_waits_for_a_slow_partner_and_ticks_meanwhile(sessions) -> None:
    router, client = sessions
    pacer = Pacer(router, RUN, [Behaviour.TRACKING], max_lead=1, wait_limit=30)
    stop = threading.Event()
    try:
        assert pacer.wait(1, stop) < 0.05  # generation 1 needs the partner at generation 0: no wait
        ticks: list[float] = []
        timer = threading.Timer(1.5, _report, (client, "tracking", 2))
        timer.start()
        t0 = time.monotonic()
        pacer.wait(3, stop, tick=lambda: ticks.append(time.monotonic()), tick_every=0.2)
        waited = time.monotonic() - t0
        timer.join()
        assert 1.0 < waited < 10.0, waited  # released by the partner's heartbeat, not by the limit
        assert len(ticks) >= 3  # the waiting worker kept its own heartbeat going
    finally:
        pacer.close()


def test_an_absent_partner_is_waited_for_once_then_not_until_it_reports(sessions) -> None:
    router, client = sessions
    pacer = Pacer(router, RUN, [Behaviour.DOCKING], max_lead=0, wait_limit=0.5)
    stop = threading.Event()
    try:
        assert pacer.wait(2, stop) >= 0.5  # never heard of: the limit passes once
        t0 = time.monotonic()
        pacer.wait(3, stop)
        assert time.monotonic() - t0 < 0.2  # now absent: no more waiting
        _report(client, "docking", 1)  # it comes back, behind
        deadline = time.monotonic() + 5
        while Behaviour.DOCKING in pacer._absent and time.monotonic() < deadline:
            pacer._poll()
            time.sleep(0.05)
        assert pacer.wait(4, stop) >= 0.5  # waited for again
    finally:
        pacer.close()


def test_a_partner_whose_token_goes_is_not_waited_for_until_it_is_back(sessions) -> None:
    router, client = sessions
    pacer = Pacer(router, RUN, [Behaviour.TRACKING], max_lead=0, wait_limit=30)
    stop = threading.Event()
    try:
        token = client.liveliness().declare_token(keys.alive(RUN, Behaviour.TRACKING, "tracking-0"))
        _report(client, "tracking", 1)
        assert pacer.wait(1, stop) < 1.0
        token.undeclare()  # the partner dies (SIGKILL looks the same to the router)
        time.sleep(0.3)
        _report(client, "tracking", 1)  # a heartbeat still on its way, read after the death: must not revive it
        time.sleep(0.3)
        t0 = time.monotonic()
        assert pacer.wait(5, stop) < 2.0, "a dead partner must not hold the others back"
        assert time.monotonic() - t0 < 2.0
        token = client.liveliness().declare_token(keys.alive(RUN, Behaviour.TRACKING, "tracking-0"))  # resumed
        deadline = time.monotonic() + 5
        while Behaviour.TRACKING in pacer._gone and time.monotonic() < deadline:
            time.sleep(0.02)
        timer = threading.Timer(1.0, _report, (client, "tracking", 6))
        timer.start()
        assert 0.8 < pacer.wait(6, stop) < 10  # waited for again, released by its heartbeat
        timer.join()
        token.undeclare()
    finally:
        pacer.close()


def test_a_partner_never_seen_is_not_waited_for_after_the_grace(sessions) -> None:
    """A restarted worker whose partner finished meanwhile: no token, no heartbeat ever comes."""
    router, _ = sessions
    pacer = Pacer(router, RUN, [Behaviour.EXECUTIVE], max_lead=0, wait_limit=60, grace=1.0)
    try:
        assert 0.5 < pacer.wait(7, threading.Event()) < 5
        assert pacer.wait(8, threading.Event()) < 0.2
    finally:
        pacer.close()


def test_a_finished_partner_or_a_stop_releases_at_once(sessions) -> None:
    router, client = sessions
    pacer = Pacer(router, RUN, [Behaviour.EXECUTIVE], max_lead=1, wait_limit=30)
    stop = threading.Event()
    try:
        threading.Timer(0.3, stop.set).start()
        assert pacer.wait(5, stop) < 5
        stop.clear()
        _report(client, "executive", 3, done=True)
        deadline = time.monotonic() + 5
        while Behaviour.EXECUTIVE not in pacer._finished and time.monotonic() < deadline:
            pacer._poll()
            time.sleep(0.05)
        assert pacer.wait(8, stop) < 0.1
    finally:
        pacer.close()


def test_pacing_off_never_waits(sessions) -> None:
    router, _ = sessions
    pacer = Pacer(router, RUN, [Behaviour.TRACKING, Behaviour.DOCKING], max_lead=None, wait_limit=30)
    try:
        assert pacer.wait(40, threading.Event()) == 0.0
    finally:
        pacer.close()
