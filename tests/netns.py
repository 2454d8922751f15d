"""A small lab of Linux network namespaces: hosts on switched LANs, each with its own network stack.

Used by ``test_deploy.py`` and ``benchmarks/two_routers.py``.  Every name carries a
per-lab tag, so labs of parallel test runs never collide, and :meth:`Lab.close`
(idempotent, also run on ``with`` exit) deletes every namespace it made, which
takes their veth links and bridges with them.

    with Lab() as lab:
        lab.lan("a")                       # a bridge (a switch) in the lab's switch namespace
        lab.host("broker", a="10.77.1.1")  # a namespace with one interface on LAN a
        lab.popen("broker", [...], log=path)
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

__all__ = ["Lab", "unavailable"]


def _ip(*args: str) -> None:
    r = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)
    if r.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {r.stderr.strip()}")


def unavailable() -> str | None:
    """Why namespaces cannot be made here, or None if they can (tries one for real)."""
    if shutil.which("ip") is None:
        return "the 'ip' command (iproute2) is not installed"
    if os.geteuid() != 0:
        return "creating network namespaces needs root"
    name = f"cvprobe{os.getpid()}"
    try:
        _ip("netns", "add", name)
    except (RuntimeError, OSError) as exc:
        return f"cannot create a network namespace: {exc}"
    try:
        _ip("link", "add", f"{name}a", "netns", name, "type", "veth", "peer", "name", f"{name}b", "netns", name)
    except RuntimeError as exc:
        return f"cannot create veth links: {exc}"
    finally:
        subprocess.run(["ip", "netns", "del", name], capture_output=True, timeout=30)
    return None


class Lab:
    def __init__(self) -> None:
        self.tag = f"{os.getpid() % 10000:04d}{os.urandom(1).hex()}"
        self.switch = self._ns("sw")
        self.namespaces = [self.switch]
        self.lans: set[str] = set()
        self.ifaces: dict[tuple[str, str], str] = {}  # (host, lan) -> interface name inside the host
        self.procs: list[subprocess.Popen] = []
        self._n = 0
        _ip("netns", "add", self.switch)

    def _ns(self, name: str) -> str:
        return f"cv{self.tag}-{name}"

    def ns(self, host: str) -> str:
        return self._ns(host)

    def lan(self, name: str) -> None:
        """A switch (bridge) named ``name``."""
        _ip("-n", self.switch, "link", "add", f"br{name}", "type", "bridge")
        _ip("-n", self.switch, "link", "set", f"br{name}", "up")
        self.lans.add(name)

    def host(self, host: str, **addresses: str) -> str:
        """A namespace with one interface per ``lan=address`` (a /24), loopback up; returns its name."""
        ns = self._ns(host)
        _ip("netns", "add", ns)
        self.namespaces.append(ns)
        _ip("-n", ns, "link", "set", "lo", "up")
        for lan, addr in addresses.items():
            self._n += 1
            inner, outer = f"eth-{lan}"[:15], f"v{self.tag}{self._n}"[:15]
            _ip("-n", ns, "link", "add", inner, "type", "veth", "peer", "name", outer, "netns", self.switch)
            _ip("-n", self.switch, "link", "set", outer, "master", f"br{lan}")
            _ip("-n", self.switch, "link", "set", outer, "up")
            _ip("-n", ns, "addr", "add", f"{addr}/24", "dev", inner)
            _ip("-n", ns, "link", "set", inner, "up")
            self.ifaces[(host, lan)] = inner
        return ns

    def link(self, host: str, lan: str, up: bool) -> None:
        """Bring ``host``'s interface on ``lan`` down or up (cut or mend its cable)."""
        _ip("-n", self._ns(host), "link", "set", self.ifaces[(host, lan)], "up" if up else "down")

    def popen(self, host: str, argv: list[str], *, log: Path, env: dict[str, str] | None = None) -> subprocess.Popen:
        """Start ``argv`` inside ``host``'s namespace (``ip netns exec`` execs it: the pid is the program's)."""
        f = open(log, "wb")
        p = subprocess.Popen(["ip", "netns", "exec", self._ns(host), *argv], stdout=f, stderr=subprocess.STDOUT,
                             stdin=subprocess.DEVNULL, env=env)
        f.close()
        self.procs.append(p)
        return p

    def close(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        self.procs = []
        for ns in reversed(self.namespaces):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=30)
        self.namespaces = []

    def __enter__(self) -> Lab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
