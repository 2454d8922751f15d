"""Members only, for real: a protected broker process, members that join, intruders that cannot.

Certificates are made with openssl by ``deploy/make-certs.sh`` (the script the deploy guide uses):
a CA with a router and a worker certificate, and a second CA with an intruder's certificate.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from procs import SMALL, coevo_proc, poll, stop

from coevo.bus import keys
from coevo.bus.session import PASSWORD_ENV, Security, make_config, open_session
from coevo.errors import ConfigError, ServiceError
from coevo.runs.local import free_port

REPO = Path(__file__).resolve().parent.parent
pytestmark = [pytest.mark.skipif(shutil.which("openssl") is None, reason="openssl is not installed"),
              pytest.mark.service]  # starts brokers and workers as processes: run with --all


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("certs")
    make = [str(REPO / "deploy" / "make-certs.sh")]
    router = "DNS:localhost,IP:127.0.0.1"
    subprocess.run(make + [str(d / "ca"), f"router={router}", "worker", f"broker={router}", "member", "tracking", "docking",
                           "viewer", "owner"], check=True, timeout=60)
    subprocess.run(make + [str(d / "other"), "intruder", "member"], check=True, timeout=60)
    return d


def _start_broker(tmp_path: Path, flags: list[str], member: Security, scheme: str) -> Iterator[tuple[str, Path, Security]]:
    port = free_port()
    data = tmp_path / "data"
    p = coevo_proc("broker", "--listen", f"{scheme}/127.0.0.1:{port}", "--data-dir", str(data), "--open", *flags,
                   log=tmp_path / "broker.log")
    endpoint = f"{scheme}/{'localhost' if scheme == 'tls' else '127.0.0.1'}:{port}"
    try:
        with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=20, security=member)) as s:
            poll(lambda: any(r.ok is not None for r in s.liveliness().get(keys.BROKER, timeout=1.0)), 20, "the broker token")
        yield endpoint, data, member
    finally:
        stop(p)
    assert p.returncode == 0, (tmp_path / "broker.log").read_text()


@pytest.fixture
def tls_broker(certs: Path, tmp_path: Path) -> Iterator[tuple[str, Path, Security]]:
    ca = certs / "ca"
    member = Security(tls_ca=str(ca / "ca.pem"), tls_cert=str(ca / "worker.pem"), tls_key=str(ca / "worker.key"))
    flags = ["--tls-ca", str(ca / "ca.pem"), "--tls-cert", str(ca / "router.pem"), "--tls-key", str(ca / "router.key")]
    yield from _start_broker(tmp_path, flags, member, "tls")


@pytest.fixture
def pwd_broker(tmp_path: Path) -> Iterator[tuple[str, Path, Security]]:
    users = tmp_path / "users.txt"
    users.write_text("alice:correct-horse\nbob:battery-staple\n")
    yield from _start_broker(tmp_path, ["--auth-file", str(users)], Security(user="alice", password="correct-horse"), "tcp")


def _worker(tmp_path: Path, name: str, endpoint: str, run: str, flags: list[str], env: dict[str, str] | None = None,
            generations: int = 2) -> subprocess.Popen:
    log = tmp_path / f"{name}.log"
    f = open(log, "wb")
    p = subprocess.Popen([sys.executable, "-m", "coevo", "worker", "--behaviour", "tracking", "--regime", "independent",
                          "--run", run, "--connect", endpoint, "--connect-timeout", "4", "--generations", str(generations),
                          *SMALL, "--out", str(tmp_path / name), *flags],
                         stdout=f, stderr=subprocess.STDOUT, env={**os.environ, **(env or {})})
    f.close()
    return p


def _assert_member_joins_and_intruders_do_not(tmp_path: Path, endpoint: str, data: Path, member: Security,
                                               good: subprocess.Popen, bad: dict[str, tuple[subprocess.Popen, Security]]) -> None:
    assert good.wait(180) == 0, (tmp_path / "member.log").read_text()
    # A member reads the run: the worker's best is in the store and answers a member's query.
    with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=10, security=member)) as s:
        got = poll(lambda: [r for r in s.get(keys.store_latest("members", "tracking"), timeout=2.0) if r.ok], 10, "the stored best")
        assert len(got) == 1
    assert (data / "members" / "store" / "tracking.jsonl").read_text().strip()
    for name, (p, sec) in bad.items():
        rc = p.wait(60)
        log = (tmp_path / f"{name}.log").read_text()
        assert rc == 2 and "ServiceError: cannot open the zenoh" in log, f"{name} got in (exit {rc}):\n{log}"
        # Nor can it read from, or publish into, the run from a session of its own (a refused session is a
        # ServiceError since issue 14's error policy: the bus refused this process).
        with pytest.raises(ServiceError):
            with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=3, security=sec)):
                pass
    assert not (data / "intruders").exists(), "an intruder's policy reached the store"
    assert not any((tmp_path / n / "curve.jsonl").exists() and (tmp_path / n / "curve.jsonl").read_text() for n in bad)


def test_mutual_tls_admits_members_only(tls_broker, certs: Path, tmp_path: Path) -> None:
    endpoint, data, member = tls_broker
    ca, other = certs / "ca", certs / "other"
    good = _worker(tmp_path, "member", endpoint, "members",
                   ["--tls-ca", str(ca / "ca.pem"), "--tls-cert", str(ca / "worker.pem"), "--tls-key", str(ca / "worker.key")])
    no_cert = Security(tls_ca=str(ca / "ca.pem"))  # trusts the router but has no certificate to show
    wrong_cert = Security(tls_ca=str(ca / "ca.pem"), tls_cert=str(other / "intruder.pem"), tls_key=str(other / "intruder.key"))
    bad = {
        "no-cert": (_worker(tmp_path, "no-cert", endpoint, "intruders", ["--tls-ca", str(ca / "ca.pem")]), no_cert),
        "wrong-cert": (_worker(tmp_path, "wrong-cert", endpoint, "intruders", [
            "--tls-ca", str(ca / "ca.pem"), "--tls-cert", str(other / "intruder.pem"), "--tls-key", str(other / "intruder.key")]),
            wrong_cert),
    }
    try:
        _assert_member_joins_and_intruders_do_not(tmp_path, endpoint, data, member, good, bad)
    finally:
        for p in [good, *(b[0] for b in bad.values())]:
            stop(p)


def test_a_second_router_joins_a_tls_broker_with_its_own_certificate(tls_broker, certs: Path, tmp_path: Path) -> None:
    """Two sites under mutual TLS: router2 is a client of the broker (its certificate) and a router to its members."""
    endpoint, data, _ = tls_broker
    ca = certs / "ca"
    tls = ["--tls-ca", str(ca / "ca.pem"), "--tls-cert", str(ca / "router.pem"), "--tls-key", str(ca / "router.key")]
    port = free_port()
    router2 = coevo_proc("router", "--listen", f"tls/127.0.0.1:{port}", "--connect", endpoint, *tls, log=tmp_path / "router2.log")
    try:
        good = _worker(tmp_path, "member", f"tls/localhost:{port}", "site-b",
                       ["--tls-ca", str(ca / "ca.pem"), "--tls-cert", str(ca / "worker.pem"), "--tls-key", str(ca / "worker.key")])
        assert good.wait(180) == 0, (tmp_path / "member.log").read_text()
        assert "no coevo broker seen" not in (tmp_path / "member.log").read_text()
        stored = data / "site-b" / "store" / "tracking.jsonl"
        poll(lambda: stored.exists() and stored.read_text().strip(), 10, "the worker's policy in the broker's store")
    finally:
        stop(router2)
    assert router2.returncode == 0, (tmp_path / "router2.log").read_text()


def test_user_password_admits_members_only(pwd_broker, tmp_path: Path) -> None:
    endpoint, data, member = pwd_broker
    good = _worker(tmp_path, "member", endpoint, "members", ["--user", "alice"], env={PASSWORD_ENV: "correct-horse"})
    bad = {
        "wrong-password": (_worker(tmp_path, "wrong-password", endpoint, "intruders", ["--user", "alice", "--password", "guess"]),
                           Security(user="alice", password="guess")),
        "no-password": (_worker(tmp_path, "no-password", endpoint, "intruders", []), Security()),
    }
    try:
        _assert_member_joins_and_intruders_do_not(tmp_path, endpoint, data, member, good, bad)
    finally:
        for p in [good, *(b[0] for b in bad.values())]:
            stop(p)


@pytest.mark.parametrize("flags, message", [
    (["--tls-ca", "/no/such/ca.pem"], "'/no/such/ca.pem' does not exist"),
    (["--tls-ca", "CA", "--tls-cert", "CA"], "--tls-cert and --tls-key go together"),
    (["--connect", "tls/localhost:1"], "no CA is set"),
    (["--tls-ca", "CA", "--connect", "tcp/127.0.0.1:1"], "is not tls/"),
    (["--user", "alice"], "--user needs a password"),
    (["--zenoh-config", "/no/such.json5"], "'/no/such.json5' does not exist"),
])
def test_bad_security_settings_fail_clearly(certs: Path, flags: list[str], message: str) -> None:
    flags = [str(certs / "ca" / "ca.pem") if f == "CA" else f for f in flags]
    env = {k: v for k, v in os.environ.items() if k != PASSWORD_ENV}
    r = subprocess.run([sys.executable, "-m", "coevo", "status", "--run", "x", "--connect-timeout", "1", *flags],
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2 and "ConfigError" in r.stderr and message in r.stderr, r.stderr


def test_auth_file_is_for_routers_and_checked(tmp_path: Path) -> None:
    bad = tmp_path / "users.txt"
    bad.write_text("alice\n")
    r = subprocess.run([sys.executable, "-m", "coevo", "router", "--auth-file", str(bad)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "line 1" in r.stderr and str(bad) in r.stderr, r.stderr
    ok = tmp_path / "ok.txt"
    ok.write_text("alice:pw\n")
    with pytest.raises(ConfigError, match="router"):
        Security(auth_file=str(ok)).apply(make_config(mode="client"), "client")


def _deploy_config(tmp_path: Path, name: str, port: int, subst: dict[str, str]) -> str:
    """A copy of deploy/zenoh/NAME.json5 pointed at this machine (host names, ports, file paths)."""
    text = (REPO / "deploy" / "zenoh" / f"{name}.json5").read_text()
    for old, new in {"broker.site-a.example:7447": f"localhost:{port}", "0.0.0.0:7447": f"127.0.0.1:{port}", **subst}.items():
        text = text.replace(old, new)
    out = tmp_path / f"{name}-{len(list(tmp_path.glob('*.json5')))}.json5"
    out.write_text(text)
    return str(out)


@pytest.mark.parametrize("kind", ["tls", "usrpwd"])
def test_the_shipped_deploy_configs_protect_a_broker(kind: str, certs: Path, tmp_path: Path) -> None:
    """deploy/zenoh/broker-KIND.json5 and client-KIND.json5 as shipped (only hosts and paths changed)."""
    port = free_port()
    users = tmp_path / "users.txt"
    users.write_text("tracking:change-me\n")
    good = {"/etc/coevo/certs/": f"{certs / 'ca'}/", "/etc/coevo/users.txt": str(users)}
    bad = {"/etc/coevo/certs/ca.pem": str(certs / "ca" / "ca.pem"), "/etc/coevo/certs/": f"{certs / 'other'}/",
           "change-me": "wrong"}
    broker = coevo_proc("broker", "--zenoh-config", _deploy_config(tmp_path, f"broker-{kind}", port, good),
                        "--data-dir", str(tmp_path / "data"), "--open", log=tmp_path / "broker.log")
    try:
        def status(subst: dict[str, str]) -> subprocess.CompletedProcess:
            return subprocess.run([sys.executable, "-m", "coevo", "status", "--run", "x", "--duration", "1.5", "--json", "--connect-timeout", "5",
                                   "--zenoh-config", _deploy_config(tmp_path, f"client-{kind}", port, subst)],
                                  capture_output=True, text=True, timeout=120)

        member = poll(lambda: (r := status(good)).returncode == 0 and r, 40, "a member to join the broker")
        assert '"run": "x"' in member.stdout
        intruder = status(bad)
        assert intruder.returncode == 2 and "cannot open the zenoh" in intruder.stderr, intruder.stderr
    finally:
        stop(broker)
    assert broker.returncode == 0, (tmp_path / "broker.log").read_text()


def test_security_flags_and_the_password_variable_make_the_settings(certs: Path, tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from coevo.cli import build_parser

    users = tmp_path / "users.txt"
    users.write_text("alice:pw\n")
    ca = certs / "ca"
    sec = Security(tls_ca=str(ca / "ca.pem"), tls_cert=str(ca / "router.pem"), tls_key=str(ca / "router.key"),
                   user="alice", password="pw", auth_file=str(users))
    flags = ["--tls-ca", sec.tls_ca, "--tls-cert", sec.tls_cert, "--tls-key", sec.tls_key, "--user", "alice",
             "--auth-file", str(users)]
    monkeypatch.setenv(PASSWORD_ENV, "pw")  # the password never on a command line: a flag shows in ps
    assert Security.from_args(build_parser().parse_args(["broker", *flags])) == sec
    with pytest.raises(SystemExit):  # --auth-file is for routers only
        build_parser().parse_args(["worker", "--behaviour", "tracking", *flags])


@pytest.mark.parametrize("kind", ["tls", "usrpwd"])
def test_the_shipped_access_control_lets_each_member_publish_only_on_its_own_keys(kind: str, certs: Path,
                                                                                   tmp_path: Path) -> None:
    """deploy/zenoh/broker-KIND.json5's access_control, with members as the shipped client-KIND.json5 makes them."""
    import numpy as np

    from coevo.bus.auth import RunKey
    from coevo.bus.messages import Control, PolicyUpdate, encode
    from coevo.policy import random_ruleset

    port = free_port()
    passwords = {"tracking": "pt", "docking": "pd", "viewer": "pv", "owner": "po", "outsider": "px"}
    users = tmp_path / "users.txt"
    users.write_text("".join(f"{u}:{p}\n" for u, p in passwords.items()))
    data = tmp_path / "data"
    (data / "r").mkdir(parents=True)
    key = RunKey.create("r")
    key.save(data / "r" / "secret.key")  # the broker stores run r: its key is in its data directory
    paths = {"/etc/coevo/certs/": f"{certs / 'ca'}/", "/etc/coevo/users.txt": str(users)}
    broker = coevo_proc("broker", "--zenoh-config", _deploy_config(tmp_path, f"broker-{kind}", port, paths),
                        "--data-dir", str(data), log=tmp_path / "broker.log")

    def member(name: str):  # the shipped client config as identity NAME (an outsider: CA-signed / in the dictionary)
        cert = "worker" if name == "outsider" else name
        subst = {**paths, "member.pem": f"{cert}.pem", "member.key": f"{cert}.key", 'user: "tracking"': f'user: "{name}"',
                 "change-me": passwords[name]}
        return open_session(make_config(mode="client", config_file=_deploy_config(tmp_path, f"client-{kind}", port, subst),
                                        connect_timeout=20))

    def policy(behaviour: str, version: int) -> tuple[str, bytes]:
        k = keys.policy("r", behaviour)
        rules = random_ruleset(behaviour, 6, np.random.default_rng(version)).to_dict()
        return k, encode(PolicyUpdate(run="r", behaviour=behaviour, worker=f"{behaviour}-x", version=version, generation=version,
                                      fitness=0.5, episodes=10, rules=rules, sent_at=time.time()), key=k, secret=key.secret)

    seen: list[tuple[str, int]] = []
    try:
        with member("viewer") as viewer, member("tracking") as tracking, member("docking") as docking, \
                member("owner") as owner, member("outsider") as outsider:
            viewer.declare_subscriber("coevo/**", lambda smp: seen.append((str(smp.key_expr), len(smp.payload.to_bytes()))))
            poll(lambda: any(r.ok is not None for r in viewer.liveliness().get(keys.BROKER, timeout=1.0)), 20, "the broker token")
            stop_msg = encode(Control(run="r", command="stop", sent_at=time.time()), key=keys.control("r"), secret=key.secret)
            # Docking holds the run's key, so only the access control can stop it here.
            docking.put(*policy("tracking", 7))
            docking.put(keys.control("r"), stop_msg)
            phantom = docking.liveliness().declare_token(keys.alive("r", "tracking", "phantom"))
            outsider.put(*policy("docking", 8))
            tracking.put(*policy("tracking", 1))
            docking.put(*policy("docking", 2))
            owner.put(keys.control("r"), stop_msg)
            token = tracking.liveliness().declare_token(keys.alive("r", "tracking", "tracking-x"))
            want = {keys.policy("r", "tracking"), keys.policy("r", "docking"), keys.control("r")}
            poll(lambda: want <= {k for k, _ in seen}, 20, "the members' own puts at the viewer")
            tokens = poll(lambda: [str(r.ok.key_expr) for r in viewer.liveliness().get(keys.alive("r"), timeout=1.0)
                                   if r.ok is not None], 10, "tracking's token")
            assert tokens == [keys.alive("r", "tracking", "tracking-x")]
            stored = data / "r" / "store"
            poll(lambda: len(list(stored.glob("*.jsonl"))) == 2, 10, "both own policies stored")
            assert [json.loads(x)["version"] for x in (stored / "tracking.jsonl").read_text().splitlines()] == [1]
            assert [json.loads(x)["version"] for x in (stored / "docking.jsonl").read_text().splitlines()] == [2]
            # The store answers members only.
            assert len([r for r in viewer.get(keys.store_latest("r", "tracking"), timeout=2.0) if r.ok is not None]) == 1
            assert not [r for r in outsider.get(keys.store_latest("r"), timeout=2.0) if r.ok is not None]
            # An oversize put is dropped by the transport; the link carries the puts after it.  The small put goes
            # again while it waits: the 5 MiB cross TLS and the router first, which took over 20 s on a machine at
            # load 20, and the point here is that the session still carries puts, not how soon.
            seen.clear()
            tracking.put(keys.policy("r", "tracking"), b"x" * (5 << 20))
            after = keys.current("r", "tracking")
            poll(lambda: tracking.put(after, b"after") or (after, 5) in seen, 90, "the puts after the oversize one")
            assert all(n < (2 << 20) for _, n in seen), seen
            phantom.undeclare()
            token.undeclare()
    finally:
        stop(broker)
    assert broker.returncode == 0, (tmp_path / "broker.log").read_text()
