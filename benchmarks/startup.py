"""How fast the command line answers and a worker process is ready to work.

    python benchmarks/startup.py [--repeats 7] [--against OTHER_CHECKOUT]

Each figure is the median wall time of ``--repeats`` fresh processes, beside the same median for a bare
``python -c pass`` measured in the same run (the machine's noise floor):

* ``coevo --help``, ``coevo status --help``, ``coevo worker --help`` (targets: the first two < 0.3 s);
* a worker ready to work: from ``Popen`` of ``coevo worker`` until its liveliness token is on the bus (it
  has read its settings, made its directory and GA and opened its session; target < 0.5 s), against a
  broker that is already up;
* what ``coevo status`` imports before it opens its session (the status board and its command).

With ``--against DIR`` (another checkout of coevo, e.g. ``git worktree add /tmp/base COMMIT``) every figure is
measured for both trees in turn, repeat by repeat, in the same environment (each tree on ``PYTHONPATH``), so the
machine's load falls on both alike: the before-and-after of a change.
"""

from __future__ import annotations

import argparse
import os
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
HERE = Path(__file__).resolve().parent.parent


def _env(tree: Path) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(tree)}


def _timed(argv: list[str], tree: Path = HERE) -> float:
    t0 = time.perf_counter()
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False, env=_env(tree))
    return time.perf_counter() - t0


def median_of(argv: list[str], repeats: int, trees: list[Path] = [HERE]) -> list[float]:  # noqa: B006 - read only
    """The median over ``repeats`` of each tree's time, the trees taking turns."""
    for tree in trees:
        _timed(argv, tree)  # warm the page cache
    times: list[list[float]] = [[] for _ in trees]
    for _ in range(repeats):
        for i, tree in enumerate(trees):
            times[i].append(_timed(argv, tree))
    return [statistics.median(t) for t in times]


def worker_ready(repeats: int, work: Path, tree: Path = HERE) -> float:
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
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=_env(tree))
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
    ap.add_argument("--against", type=Path, metavar="DIR", help="another checkout of coevo, measured in turn")
    args = ap.parse_args()
    trees = [HERE] + ([args.against.resolve()] if args.against else [])
    rows = [("python -c pass (baseline)", median_of([PY, "-c", "pass"], args.repeats, trees))]
    for cmd in (["--help"], ["status", "--help"], ["worker", "--help"]):
        rows.append((f"coevo {' '.join(cmd)}", median_of([PY, "-m", "coevo", *cmd], args.repeats, trees)))
    rows.append(("coevo status's imports", median_of([PY, "-c", STATUS_IMPORTS], args.repeats, trees)))
    with tempfile.TemporaryDirectory() as tmp:
        ready = [[] for _ in trees]  # type: list[list[float]]
        for _ in range(3):  # three rounds of repeats, the trees in turn
            for i, tree in enumerate(trees):
                ready[i].append(worker_ready(max(1, args.repeats // 3), Path(tmp) / f"{i}-{len(ready[i])}", tree))
        rows.append(("worker ready (token on the bus)", [statistics.median(r) for r in ready]))
    head = "".join(f"  {str(t)[-28:]:>28s}" for t in trees)
    print(f"{'what (median s)':36s}{head}")
    for what, ts in rows:
        print(f"{what:36s}" + "".join(f"  {t:28.3f}" for t in ts))


if __name__ == "__main__":
    main()
