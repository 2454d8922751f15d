"""How long a published improvement takes to reach another worker, through the broker.

    python benchmarks/bus_latency.py --messages 300

Starts ``coevo broker`` and a subscriber process (a client, as a worker is);
this process publishes real-size policy updates (48-rule Docking rule sets) at
20 Hz; the subscriber reports ``arrival - sent_at`` (same machine clock).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

import numpy as np

from coevo.bus import keys
from coevo.bus.messages import PolicyUpdate, encode
from coevo.bus.session import make_config, open_session
from coevo.policy import random_ruleset
from coevo.runs.local import free_port

SUBSCRIBER = r"""
import sys, time, json
from coevo.bus.session import make_config, open_session
from coevo.bus.messages import decode
from coevo.bus import keys
lat = []
with open_session(make_config(mode="client", connect=[sys.argv[1]])) as s:
    sub = s.declare_subscriber(keys.policy("lat", "docking"),
                               lambda smp: lat.append(time.time() - decode(bytes(smp.payload.to_bytes())).sent_at))
    print("ready", flush=True)
    n = int(sys.argv[2])
    end = time.time() + 120
    while len(lat) < n and time.time() < end:
        time.sleep(0.05)
    sub.undeclare()
print(json.dumps(lat), flush=True)
"""


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--messages", type=int, default=300)
    args = ap.parse_args()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    broker = subprocess.Popen([sys.executable, "-m", "coevo", "broker", "--listen", endpoint, "--data-dir", "/tmp/coevo-lat-store", "--open"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(1.0)
        sub = subprocess.Popen([sys.executable, "-c", SUBSCRIBER, endpoint, str(args.messages)], stdout=subprocess.PIPE, text=True)
        assert sub.stdout.readline().strip() == "ready"
        time.sleep(0.5)
        rules = random_ruleset("docking", 48, np.random.default_rng(0)).to_dict()
        with open_session(make_config(mode="client", connect=[endpoint])) as s:
            pub = s.declare_publisher(keys.policy("lat", "docking"))
            for v in range(1, args.messages + 1):
                msg = PolicyUpdate(run="lat", behaviour="docking", worker="bench", version=v, generation=v, fitness=0.5,
                                   episodes=120, rules=rules, sent_at=time.time())
                pub.put(encode(msg))
                time.sleep(0.05)
        lat = json.loads(sub.stdout.read().strip().splitlines()[-1])
        sub.wait(10)
    finally:
        broker.terminate()
        broker.wait(10)
    ms = sorted(1000 * x for x in lat)
    print(f"received {len(ms)}/{args.messages}; payload {len(encode(msg))} bytes")
    print(f"latency ms: median {statistics.median(ms):.2f}, p95 {ms[int(0.95 * len(ms)) - 1]:.2f}, max {ms[-1]:.2f}")


if __name__ == "__main__":
    main()
