"""What a network cut between two sites costs, for a given lease: delay, or lost updates.

    sudo python benchmarks/link_cut.py --cases 3:2 3:6 10:5 10:12      (LEASE_S:CUT_S pairs)

For each case: ``coevo broker`` (site A) and ``coevo router`` (site B) joined across one
link, every process with ``--lease LEASE``; a publisher at site B puts numbered policy
updates every 0.1 s (as a worker does, without retrying), a subscriber at site A counts
which arrived.  Mid-stream router2's cable to site A is pulled for CUT seconds.  Reported:
updates sent, received, lost, and the longest gap between arrivals (the delay a run sees).
Zenoh keeps the session while the cut is shorter than the lease (TCP retransmits what was
queued: nothing lost, only delayed); a longer cut expires the session and what was put
meanwhile is dropped silently.  Prints JSON.
"""

from __future__ import annotations

import argparse
import itertools
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

PUBLISHER = r"""
import sys, time
from coevo.bus.session import make_config, open_session
with open_session(make_config(mode="client", connect=[sys.argv[1]], lease_ms=int(float(sys.argv[2]) * 1000))) as s:
    pub = s.declare_publisher("coevo/cut/policy/docking")
    print("ready", flush=True)
    n = int(sys.argv[3])
    for v in range(1, n + 1):
        pub.put(str(v).encode())
        time.sleep(0.1)
    time.sleep(1)
"""

SUBSCRIBER = r"""
import sys, time
from coevo.bus.session import make_config, open_session
out = open(sys.argv[3], "w", buffering=1)
with open_session(make_config(mode="client", connect=[sys.argv[1]], lease_ms=int(float(sys.argv[2]) * 1000))) as s:
    sub = s.declare_subscriber("coevo/cut/policy/docking", lambda smp: out.write(f"{smp.payload.to_bytes().decode()} {time.time()}\n"))
    print("ready", flush=True)
    sys.stdin.read()
"""


def case(lease: float, cut: float, tmp: Path) -> dict:
    from netns import Lab

    sent = int((cut + lease + 12) / 0.1)
    arrivals = tmp / f"arrivals-{lease}-{cut}.txt"
    with Lab() as lab:
        lab.lan("a")
        lab.lan("b")
        lab.host("broker", a="10.77.1.1")
        lab.host("router2", a="10.77.1.2", b="10.77.2.1")
        lab.host("sub", a="10.77.1.20")
        lab.host("pub", b="10.77.2.10")
        coevo = [sys.executable, "-m", "coevo"]
        lease_flag = ["--lease", str(lease)]
        lab.popen("broker", coevo + ["broker", "--listen", "tcp/10.77.1.1:7447", "--data-dir", str(tmp / "data"), "--open", *lease_flag],
                  log=tmp / "broker.log")
        lab.popen("router2", coevo + ["router", "--listen", "tcp/10.77.2.1:7447", "--connect", "tcp/10.77.1.1:7447", *lease_flag],
                  log=tmp / "router2.log")
        time.sleep(2.0)
        sub = subprocess.Popen(["ip", "netns", "exec", lab.ns("sub"), sys.executable, "-c", SUBSCRIBER, "tcp/10.77.1.1:7447",
                                str(lease), str(arrivals)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        lab.procs.append(sub)
        assert sub.stdout.readline().strip() == "ready"
        pub = subprocess.Popen(["ip", "netns", "exec", lab.ns("pub"), sys.executable, "-c", PUBLISHER, "tcp/10.77.2.1:7447",
                                str(lease), str(sent)], stdout=subprocess.PIPE, text=True)
        lab.procs.append(pub)
        assert pub.stdout.readline().strip() == "ready"
        time.sleep(3.0)
        lab.link("router2", "a", up=False)
        time.sleep(cut)
        lab.link("router2", "a", up=True)
        pub.wait(sent * 0.1 + 60)
        time.sleep(2.0)
        sub.stdin.close()
    rows = [line.split() for line in arrivals.read_text().splitlines()]
    got = {int(v) for v, _ in rows}
    times = sorted(float(t) for _, t in rows)
    return {"lease_s": lease, "cut_s": cut, "sent": sent, "received": len(got), "lost": sent - len(got),
            "longest_gap_s": round(max((b - a for a, b in itertools.pairwise(times)), default=0.0), 2)}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", default=["3:2", "3:6", "10:5", "10:12"], metavar="LEASE:CUT")
    a = ap.parse_args()
    from netns import unavailable

    if (why := unavailable()) is not None:
        raise SystemExit(f"cannot run: {why}")
    tmp = Path(tempfile.mkdtemp(prefix="link-cut-"))
    print(json.dumps([case(*map(float, c.split(":")), tmp) for c in a.cases], indent=2))
