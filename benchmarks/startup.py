"""How fast the command line answers and a worker process is ready to work.

    python benchmarks/startup.py [--repeats 7] [--against OTHER_CHECKOUT]

Each command's figure is the median CPU time (user + system) of ``--repeats`` fresh processes, beside the same
median for a bare ``python -c pass`` measured in the same run; the worker's is wall time:

* ``coevo --help``, ``coevo status --help``, ``coevo worker --help`` (targets: the first two < 0.3 s);
* a worker ready to work: from ``Popen`` of ``coevo worker`` until its liveliness token is on the bus (it
  has read its settings, made its directory and GA and opened its session; target < 0.5 s), against a
  broker that is already up;
* what ``coevo status`` imports before it opens its session (the status board and its command).

With ``--against PYTHON`` (the interpreter of another checkout's own virtual environment, e.g. ``git worktree add
/tmp/base COMMIT`` and ``python3 -m venv /tmp/basevenv && /tmp/basevenv/bin/pip install -e /tmp/base``; an
editable install binds its checkout, so one environment cannot hold two) every figure is measured for both in
turn, repeat by repeat, so the machine's load falls on both alike: the before-and-after of a change.
"""

from __future__ import annotations

import argparse
import resource
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


def _timed(argv: list[str], py: str = PY) -> float:
    """The CPU-seconds (user + system) of one run of ``argv``: unlike its wall time, not stretched by what else
    the machine is doing."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([py, *argv], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def median_of(argv: list[str], repeats: int, pythons: tuple[str, ...] = (PY,)) -> list[float]:
    """The median over ``repeats`` of ``python ARGV``'s CPU time for each interpreter, the interpreters in turn."""
    for py in pythons:
        _timed(argv, py)  # warm the page cache
    times: list[list[float]] = [[] for _ in pythons]
    for _ in range(repeats):
        for i, py in enumerate(pythons):
            times[i].append(_timed(argv, py))
    return [statistics.median(t) for t in times]


def worker_ready(repeats: int, work: Path, py: str = PY) -> float:
    """Median seconds from starting a worker to its liveliness token, with a broker already up."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    broker = subprocess.Popen([py, "-m", "coevo", "broker", "--listen", endpoint, "--data-dir", str(work / "data"), "--open"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    times = []
    try:
        with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=20)) as s:
            for i in range(repeats + 1):
                run = f"startup-{i}"
                t0 = time.perf_counter()
                w = subprocess.Popen([py, "-m", "coevo", "worker", "--run", run, "--regime", "independent",
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


STATUS_IMPORTS = "import coevo.runs.command, coevo.bus.status, coevo.bus.session"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--against", metavar="PYTHON", help="another checkout's interpreter (its own venv), measured in turn")
    args = ap.parse_args()
    pythons = (PY,) + ((args.against,) if args.against else ())
    rows = [("python -c pass (baseline)", median_of(["-c", "pass"], args.repeats, pythons))]
    for cmd in (["--help"], ["status", "--help"], ["worker", "--help"]):
        rows.append((f"coevo {' '.join(cmd)}", median_of(["-m", "coevo", *cmd], args.repeats, pythons)))
    rows.append(("coevo status's imports", median_of(["-c", STATUS_IMPORTS], args.repeats, pythons)))
    with tempfile.TemporaryDirectory() as tmp:
        ready: list[list[float]] = [[] for _ in pythons]
        for _ in range(3):  # three rounds of repeats, the interpreters in turn
            for i, py in enumerate(pythons):
                ready[i].append(worker_ready(max(1, args.repeats // 3), Path(tmp) / f"{i}-{len(ready[i])}", py))
        rows.append(("worker ready (token on the bus)", [statistics.median(r) for r in ready]))
    head = "".join(f"  {t[-28:]:>28s}" for t in pythons)
    print(f"{'what (median CPU-s; the worker: wall s)':36s}{head}")
    for what, ts in rows:
        print(f"{what:36s}" + "".join(f"  {t:28.3f}" for t in ts))


if __name__ == "__main__":
    main()
