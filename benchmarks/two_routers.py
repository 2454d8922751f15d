"""Extra latency of an improvement crossing two routers instead of one, in network namespaces.

    sudo python benchmarks/two_routers.py --messages 400     (root: it makes namespaces)

Two sites as in ``tests/test_deploy.py``: ``coevo broker`` on LAN a, ``coevo router`` joined
to it and on LAN b.  A subscriber (a client of the broker, as a worker at site A is) receives
real-size policy updates (48-rule Docking rule sets, msgpack) from two publishers: one at
site A (client of the broker: one router on the way) and one at site B (client of router2:
two routers).  The publishers take turns, one put every ``--gap`` seconds, so both paths are
measured in the same run under the same load.  Latency is ``arrival - sent_at``: every
namespace reads the same kernel clock, so one-way times are exact.  Prints JSON.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

PUBLISHER = r"""
import sys, time
import numpy as np
from coevo.bus import keys
from coevo.bus.session import make_config, open_session
from coevo.bus.messages import PolicyUpdate, encode
from coevo.policy import random_ruleset
rules = random_ruleset("docking", 48, np.random.default_rng(1)).to_dict()
with open_session(make_config(mode="client", connect=[sys.argv[1]], lease_ms=10000)) as s:
    pub = s.declare_publisher(keys.policy("lat", "docking"))
    print("ready", flush=True)
    for v, _ in enumerate(sys.stdin, start=1):
        pub.put(encode(PolicyUpdate(run="lat", behaviour="docking", worker=sys.argv[2], version=v, generation=v,
                                    fitness=0.5, episodes=10, rules=rules, sent_at=time.time())))
"""

SUBSCRIBER = r"""
import sys, time
from coevo.bus import keys
from coevo.bus.session import make_config, open_session
from coevo.bus.messages import decode
out = open(sys.argv[2], "w", buffering=1)
def got(smp):
    t = time.time()
    m = decode(bytes(smp.payload.to_bytes()))
    out.write(f"{m.worker} {m.version} {t - m.sent_at}\n")
with open_session(make_config(mode="client", connect=[sys.argv[1]], lease_ms=10000)) as s:
    sub = s.declare_subscriber(keys.policy("lat", "docking"), got)
    print("ready", flush=True)
    sys.stdin.read()   # until the benchmark closes our stdin
"""


def _pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def main(messages: int, gap: float) -> dict:
    from netns import Lab, unavailable

    why = unavailable()
    if why:
        raise SystemExit(f"cannot run: {why}")
    py = [sys.executable, "-c"]
    tmp = Path(tempfile.mkdtemp(prefix="two-routers-"))
    with Lab() as lab:
        lab.lan("a")
        lab.lan("b")
        lab.host("broker", a="10.77.1.1")
        lab.host("router2", a="10.77.1.2", b="10.77.2.1")
        lab.host("sub", a="10.77.1.20")
        lab.host("pub1", a="10.77.1.10")
        lab.host("pub2", b="10.77.2.10")
        coevo = [sys.executable, "-m", "coevo"]
        lab.popen("broker", coevo + ["broker", "--listen", "tcp/10.77.1.1:7447", "--data-dir", str(tmp / "data"), "--lease", "10"],
                  log=tmp / "broker.log")
        lab.popen("router2", coevo + ["router", "--listen", "tcp/10.77.2.1:7447", "--connect", "tcp/10.77.1.1:7447", "--lease", "10"],
                  log=tmp / "router2.log")
        time.sleep(2.0)
        procs = {}
        for host, ep, code, arg in (("sub", "10.77.1.1", SUBSCRIBER, str(tmp / "arrivals.txt")),
                                    ("pub1", "10.77.1.1", PUBLISHER, "one-router"),
                                    ("pub2", "10.77.2.1", PUBLISHER, "two-routers")):
            p = subprocess.Popen(["ip", "netns", "exec", lab.ns(host), *py, code, f"tcp/{ep}:7447", arg],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
            lab.procs.append(p)
            if p.stdout.readline().strip() != "ready":
                raise SystemExit(f"{host} did not start")
            procs[host] = p
        time.sleep(1.0)  # let the subscriptions propagate through both routers
        warmup = 20
        for i in range(messages + warmup):
            for host in ("pub1", "pub2") if i % 2 == 0 else ("pub2", "pub1"):
                procs[host].stdin.write("\n")
                procs[host].stdin.flush()
                time.sleep(gap)
        time.sleep(1.0)
        for p in procs.values():
            p.stdin.close()
        rows = [line.split() for line in (tmp / "arrivals.txt").read_text().splitlines()]
    warmup = 20
    lat: dict[str, list[float]] = {"one-router": [], "two-routers": []}
    for worker, version, seconds in rows:
        if int(version) > warmup:
            lat[worker].append(float(seconds) * 1000)
    out = {"messages_per_path": {k: len(v) for k, v in lat.items()}, "sent_per_path": messages,
           "gap_s": gap}
    for k, v in lat.items():
        out[k] = {"median_ms": round(statistics.median(v), 3), "p10_ms": round(_pct(v, 0.10), 3),
                  "p90_ms": round(_pct(v, 0.90), 3), "p99_ms": round(_pct(v, 0.99), 3)}
    out["extra_median_ms"] = round(out["two-routers"]["median_ms"] - out["one-router"]["median_ms"], 3)
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--messages", type=int, default=400, help="puts per path (default 400)")
    ap.add_argument("--gap", type=float, default=0.02, help="seconds between puts (default 0.02)")
    a = ap.parse_args()
    print(json.dumps(main(a.messages, a.gap), indent=2))
