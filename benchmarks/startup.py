"""How fast the command line answers and a worker process is ready to work (issue 27's start-up targets).

    python benchmarks/startup.py [--repeats 7]

Each figure is the median wall time of ``--repeats`` fresh processes, beside the same median for a bare
``python -c pass`` measured in the same run (the machine's noise floor):

* ``coevo --help``, ``coevo status --help``, ``coevo worker --help`` (targets: the first two < 0.3 s);
* a worker ready to work: from ``Popen`` of ``coevo worker`` until its liveliness token is on the bus (it
  has read its settings, made its directory and GA and opened its session; target < 0.5 s), against a
  broker that is already up.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from coevo.bus import keys
from coevo.bus.session import make_config, open_session
from coevo.runs.local import free_port

PY = sys.executable


def _timed(argv: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    return time.perf_counter() - t0


def median_of(argv: list[str], repeats: int) -> float:
    _timed(argv)  # warm the page cache
    return statistics.median(_timed(argv) for _ in range(repeats))


def worker_ready(repeats: int, work: Path) -> float:
    """Median seconds from starting a worker to its liveliness token, with a broker already up."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    broker = subprocess.Popen([PY, "-m", "coevo", "broker", "--listen", endpoint, "--data-dir", str(work / "data"), "--open"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    times = []
    try:
        with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=20)) as s:
            for i in range(repeats + 1):
                run = f"startup-{i}"
                t0 = time.perf_counter()
                w = subprocess.Popen([PY, "-m", "coevo", "worker", "--run", run, "--regime", "independent",
                                      "--behaviour", "tracking", "--connect", endpoint, "--generations", "1",
                                      "--out", str(work / run), "--final-sync", "0"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                while not list(s.liveliness().get(keys.alive(run), timeout=0.05)):
                    if time.perf_counter() - t0 > 30:
                        raise SystemExit("no worker token after 30 s")
                if i:  # the first start warms the page cache
                    times.append(time.perf_counter() - t0)
                w.terminate()
                w.wait(30)
    finally:
        broker.terminate()
        broker.wait(30)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    rows = [("python -c pass (baseline)", median_of([PY, "-c", "pass"], args.repeats))]
    for cmd in (["--help"], ["status", "--help"], ["worker", "--help"]):
        rows.append((f"coevo {' '.join(cmd)}", median_of([PY, "-m", "coevo", *cmd], args.repeats)))
    with tempfile.TemporaryDirectory() as tmp:
        rows.append(("worker ready (token on the bus)", worker_ready(args.repeats, Path(tmp))))
    print(f"{'what':36s} median of {args.repeats}")
    for what, t in rows:
        print(f"{what:36s} {t:.3f} s")


if __name__ == "__main__":
    main()
