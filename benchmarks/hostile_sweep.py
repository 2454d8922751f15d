"""Hostile command lines as real processes: does every one end in words, and is any silent for long (issue 54)?

    python benchmarks/hostile_sweep.py [--jobs 2] [--timeout 60] [--only run,status] [--show-all] [--stream]
                                       [--json FILE]

Every flag of every command (read from :func:`coevo.cli.build_parser`, so a new flag is tried without touching this
file) is given bad or extreme values, each on a base command line that would otherwise do little (tiny settings):

* numbers: not a number, far beyond any bound (an empty value is one rule of the parser for every flag, tried here
  for the names and files, and for every flag in process by tests/test_bad_input.py);
* endpoints (``--connect``, ``--listen``, ``--cluster``): a protocol zenoh (or Dask) does not know, a closed port, an
  address that answers nothing (TEST-NET-1), a malformed address, empty;
* files and directories read: missing, a file, a directory, random bytes, a broken run directory, empty; written: a
  file in the way, ``/proc/x/y``, empty;
* names (``--regime``, ``--task``, ``--model``, ...): one that does not exist, empty;

and a few whole-directory cases (``--resume`` of a missing, an empty or a broken directory, a ``compare.json`` of
random bytes).  Each line runs as its own process (``python -m coevo``, a session of its own, killed with its group
after ``--timeout`` seconds; a server, ``broker``, ``router`` or ``dashboard``, still up after 10 s is *serving*, not a
problem) and its stdout and stderr are read as they arrive.  For each: the exit status, whether stderr holds a
Python traceback, whether a path of zenoh's Rust sources (``.rs:``) shows, and the longest silence beyond start-up:
the longest gap between two pieces of output (or from the last to the exit), or the wait for the first less the
command's start-up (the median wait of that command's lines refused by the parser, measured in the same sweep and
so under the same load: importing a command costs 1-2 s of wall time on a busy 2-core machine).  The summary counts
the lines, the tracebacks, the ``.rs:`` paths, the silences over 2 s and the lines killed at the timeout, and lists
each line that has one of these (``--show-all``: every line; ``--stream``: each line's result as it ends).

It costs about 0.5 CPU-s a line (an interpreter's start-up and the command's imports; a line whose value is
accepted runs its tiny work): about 500 CPU-s and 20 minutes for the 1,046 lines with ``--jobs 3`` on 2 busy cores.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import selectors
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

from coevo.cli import build_parser

TINY = ["--generations", "1", "--population", "2", "--episodes", "1", "--ga", "best_episodes=1"]
NUMBERS = ["nan", "1e308"]  # not a number, far beyond any bound (an empty value: one rule for every flag, below)
ENDPOINTS = ["xyz/127.0.0.1:7447", "tcp/127.0.0.1:1", "tcp/192.0.2.1:7447", "tcp/127.0.0.1", "tcp/999.1.1.1:7447", ""]
CLUSTERS = ["xyz://127.0.0.1:8786", "tcp://127.0.0.1:1", "tcp://192.0.2.1:8786", "local:0", "local:abc", ""]
NAMES = ["nosuch", ""]
OUTPUTS = {"--out", "--root", "--data-dir", "--runs-dir", "--shared-dir"}  # written (a missing one is made)
SILENT_S = 2.0
SERVERS = {"broker": 10.0, "router": 10.0, "dashboard": 10.0}  # up this long without a refusal: serving


@dataclass
class Result:
    argv: list[str]
    status: int | None  # None: killed at the timeout
    traceback: bool
    rs_path: bool
    first_s: float  # from the start to the first byte of output (an interpreter's start-up at least)
    gap_s: float  # the longest time with no output after the first byte (and to the exit)
    wall_s: float
    last_line: str
    serving: bool = False  # a server (broker, router, dashboard) still up at its timeout: its quiet is its work
    silent_s: float = 0.0  # beyond start-up: set by the summary (see silence())

    @property
    def problems(self) -> list[str]:
        p = []
        if self.status is None and not self.serving:
            p.append("timeout")
        if self.traceback:
            p.append("traceback")
        if self.rs_path:
            p.append(".rs: path")
        if self.silent_s > SILENT_S:
            p.append(f"silent {self.silent_s:.1f} s")
        return p


def _places(root: Path) -> dict[str, Path]:
    """Hostile files and directories under ``root``."""
    p = {"file": root / "a-file", "dir": root / "a-dir", "random": root / "random.bin", "missing": root / "missing",
         "broken-run": root / "broken-run", "broken-worker": root / "broken-worker", "empty-dir": root / "empty-dir",
         "bad-compare": root / "bad-compare", "bad-study": root / "bad-study", "bad-seeds": root / "bad-seeds"}
    p["file"].write_text("not what you expected\n")
    p["dir"].mkdir()
    (p["dir"] / "x").write_text("x")
    p["empty-dir"].mkdir()
    p["random"].write_bytes(random.Random(54).randbytes(256))
    for what in ("broken-run", "broken-worker"):
        d = p[what]
        (d / "workers" / "tracking").mkdir(parents=True)
        (d / "run.json").write_text('{"run": ' if what == "broken-run" else '{"run": "broken-worker", "regime": "mutual"}')
        (d / "workers" / "tracking" / "worker.json").write_text("[1, 2" if what == "broken-worker" else "{}")
    for what, name in (("bad-compare", "compare.json"), ("bad-study", "study.json"), ("bad-seeds", "seeds.json")):
        p[what].mkdir()
        (p[what] / name).write_bytes(random.Random(what).randbytes(64))
    return p


def _base(command: str, flag: str, fresh: str, places: dict[str, Path]) -> list[str]:
    """A command line for ``command`` that would do little, leaving ``flag`` to the value under test."""
    nobus = ["--connect", "tcp/127.0.0.1:9", "--connect-timeout", "0"]
    nolisten = ["--listen", "tcp/192.0.2.1:7447"]
    bases: dict[str, list[str]] = {
        "learn": ["--behaviour", "executive" if flag in ("--history", "--rate") else "tracking", *TINY,
                  "--measure-epochs", "1", "--out", fresh],
        "bench": ["--lanes", "1", "--repeats", "1", "--baseline-seconds", "0.01", "--rules", "1"],
        "broker": [*nolisten, "--data-dir", fresh],
        "router": [*nolisten],
        "worker": ["--behaviour", "tracking", *nobus, "--out", fresh]
        + ([] if flag == "--settings" else ["--run", "x", "--regime", "independent", *TINY]),
        "run": ([] if flag in ("--resume", "--settings") else ["--run", "sweep", *TINY, "--measure-epochs", "1"])
        + ([] if flag == "--resume" else ["--root", fresh]),
        "status": ["--run", "x", *nobus, "--duration", "1"],
        "dashboard": ["--run=x", *nobus],
        "compare": ["--out", fresh, "--runs", "1", *TINY],
        "study": ["--out", fresh, "--runs", "1", "--factor", "regime=independent", *TINY],
        "evolvability": ["--landscapes", "1", "--runs", "1", "--generations", "1", "--population", "2", "--classes",
                         "gradual", "--rates", "0.1", "--models", "fm", "--out", fresh],
        "earl": ["--runs", "1", "--generations", "0", "--out", fresh],
        "seeds": ["--task", "door", "--generations", "1", "--ga", "population=2", "--ga", "episodes=1", "--seeds", "1",
                  "--out", fresh],
        "td-baseline": ["--tasks", "door", "--seeds", "1", "--generations", "1", "--population", "2", "--episodes", "1",
                        "--trials", "1", "--out", fresh],
        "keygen": ["--run", "x", "--out", f"{fresh}.key"],
        "show": ["--default", "tracking", "--episodes", "1", "--rules"],
        "chaos": ["--run", "sweep", "--root", fresh, *TINY, "--faults", "0"],
        "cel": ([] if flag in ("--resume", "--settings") else ["--run", "sweep", "--generations", "2", "--population",
                                                               "2", "--episodes", "1", "--fail", "1:front"])
        + ([] if flag == "--resume" else ["--root", fresh]),
        "cel-experiment": ["--runs", "1", "--generations", "2", "--population", "2", "--episodes", "1",
                           "--trials-per-generation", "2", "--out", fresh],
        "execution": ["--settings", str(places["broken-run"] / "run.json"), *nobus, "--out", fresh],
        "replay": [str(places["broken-worker"])],
        "dynamics": [str(places["broken-run"])],
        "check": [str(places["broken-worker"]), "--no-replay"],
        "plugins": [],
    }
    base = bases[command]
    if flag in base:  # the value under test replaces the base's
        i = base.index(flag)
        j = i + 1
        while j < len(base) and not base[j].startswith("--"):
            j += 1
        base = base[:i] + base[j:]
    if flag in ("--connect", "--listen") and "--connect-timeout" in base:  # as a user gives it: zenoh's own timeout
        i = base.index("--connect-timeout")
        base = base[:i] + base[i + 2:]
    return base


def _values(action: argparse.Action, places: dict[str, Path]) -> list[str]:
    flag = action.option_strings[0] if action.option_strings else ""
    if flag in ("--connect", "--listen"):
        return ENDPOINTS
    if flag == "--cluster":
        return CLUSTERS
    if action.choices is not None:
        return NAMES
    if action.metavar == "NAME=VALUE":  # --ga, --world
        return ["population=nan", "nosuch=1", "a=b=c", ""]
    if action.type is not None and action.type not in (str, Path) and _numeric(action):
        return NUMBERS
    if flag in OUTPUTS:
        return [str(places["file"]), "/proc/x/y", ""]
    reads = [str(places["missing"]), str(places["file"]), str(places["dir"]), str(places["random"]),
             str(places["broken-run"]), ""]
    if flag in ("--resume", "--settings", "--history", "--cases-from") or not action.option_strings:
        return reads
    if action.type is Path or any(w in flag for w in ("file", "config", "policy", "tls", "robot", "auth")):
        return reads
    return NAMES


def _numeric(action: argparse.Action) -> bool:
    try:
        return isinstance(action.type("1"), (int, float))  # type: ignore[misc]
    except (argparse.ArgumentTypeError, ValueError, TypeError):
        return False


def _lines(places: dict[str, Path], only: set[str] | None) -> Iterator[list[str]]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices
    n = 0
    for command in sorted(sub):
        if only and command not in only:
            continue
        actions = [a for a in sub[command]._actions if not isinstance(a, argparse._HelpAction) and a.nargs != 0]
        if not actions:
            yield [command]
        for action in actions:
            flag = action.option_strings[0] if action.option_strings else None
            for value in _values(action, places):
                n += 1
                base = _base(command, flag or "", str(places["fresh"] / f"f{n}"), places)
                nargs = action.nargs if isinstance(action.nargs, int) else 1
                if flag:
                    yield [command, *base, flag, *[value] * nargs]
                else:  # a positional: the value in the base's first item's place
                    yield [command, value, *base[1:]]
    whole = [["run", "--resume", str(places["broken-worker"])], ["run", "--resume", str(places["empty-dir"])],
             ["cel", "--resume", str(places["empty-dir"])],
             ["compare", "--resume", "--out", str(places["bad-compare"])],
             ["compare", "--report-only", "--out", str(places["bad-compare"])],
             ["compare", "--resume", "--out", str(places["missing"])],
             ["study", "--resume", "--out", str(places["bad-study"])],
             ["study", "--report-only", "--out", str(places["empty-dir"])],
             ["seeds", "--resume", "--out", str(places["bad-seeds"])],
             ["cel-experiment", "--resume", "--out", str(places["empty-dir"])],
             ["evolvability", "--report-only", "--out", str(places["empty-dir"])],
             ["td-baseline", "--resume", "--out", str(places["random"])],
             ["learn", "--history", str(places["empty-dir"]), "--behaviour", "executive"],
             ["show", str(places["empty-dir"])], ["dashboard", str(places["random"])],
             ["check", str(places["missing"])], ["replay", str(places["empty-dir"])],
             ["dynamics", str(places["broken-worker"])]]
    for argv in whole:
        if not only or argv[0] in only:
            yield argv


def run_line(argv: list[str], cwd: Path, timeout: float) -> Result:
    """``python -m coevo ARGV`` as a process of its own, its pipes read as they arrive."""
    env = dict(os.environ, PYTHONUNBUFFERED="1", COLUMNS="120")
    start = time.monotonic()
    p = subprocess.Popen([sys.executable, "-m", "coevo", *argv], cwd=cwd, stdin=subprocess.DEVNULL,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True, env=env)
    sel = selectors.DefaultSelector()
    assert p.stdout is not None and p.stderr is not None
    sel.register(p.stdout, selectors.EVENT_READ, "out")
    sel.register(p.stderr, selectors.EVENT_READ, "err")
    err = bytearray()
    last = start
    first: float | None = None
    gap = 0.0
    killed = False
    open_pipes = 2
    while open_pipes:
        left = start + timeout - time.monotonic()
        if left <= 0:
            killed = True
            os.killpg(p.pid, signal.SIGKILL)
            break
        for key, _ in sel.select(timeout=min(left, 0.5)):
            chunk = os.read(key.fileobj.fileno(), 65536)  # type: ignore[union-attr]
            now = time.monotonic()
            if not chunk:
                sel.unregister(key.fileobj)
                open_pipes -= 1
                continue
            if first is None:
                first = now - start
            else:
                gap = max(gap, now - last)
            last = now
            if key.data == "err":
                err += chunk
    p.wait()
    end = time.monotonic()
    if first is None:
        first = end - start
    elif not killed:
        gap = max(gap, end - last)
    try:
        os.killpg(p.pid, signal.SIGKILL)  # anything it left behind
    except ProcessLookupError:
        pass
    text = err.decode("utf-8", "replace")
    lines = [x for x in text.splitlines() if x.strip()]
    return Result(argv=argv, status=None if killed else p.returncode, traceback="Traceback (most recent call" in text,
                  rs_path=".rs:" in text, first_s=round(first, 2), gap_s=round(gap, 2), wall_s=round(end - start, 2),
                  last_line=lines[-1][:200] if lines else "", serving=killed and argv[0] in SERVERS)


def silence(results: list[Result]) -> dict[str, float]:
    """Each line's silence beyond an interpreter's start-up: its longest gap after its first byte, or its wait for that
    first byte less its command's start-up, the median wait of that command's lines refused by the parser (measured in
    the same sweep, so under the same load).  Returns the start-up of each command."""
    startup: dict[str, list[float]] = {}
    for r in results:
        if r.status == 2 and r.last_line.startswith(f"ConfigError: coevo {r.argv[0]}:"):
            startup.setdefault(r.argv[0], []).append(r.first_s)
    every = sorted(x for v in startup.values() for x in v) or [0.0]
    base = {c: sorted(v)[len(v) // 2] for c, v in startup.items()}
    for r in results:
        b = base.get(r.argv[0], every[len(every) // 2])
        r.silent_s = round(max(r.gap_s, r.first_s - b if not r.serving else 0.0), 2)
    return base


def shown(argv: list[str]) -> str:
    return "coevo " + " ".join(repr(a) if a == "" or " " in a else a for a in argv)


def _at_least(low: float, kind: type) -> Callable[[str], float]:
    """An argparse type: a ``kind`` number not below ``low`` (nan and -1 are one line from argparse, not a traceback)."""
    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not value >= low:
            raise argparse.ArgumentTypeError(f"{text!r}: give a number from {low}")
        return value
    return parse


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=_at_least(1, int), default=2, help="lines run at once (default 2)")
    ap.add_argument("--timeout", type=_at_least(0.1, float), default=60.0, help="seconds before a line is killed (default 60)")
    ap.add_argument("--only", default="", help="comma-separated commands (default: every command)")
    ap.add_argument("--show-all", action="store_true", help="list every line, not only those with a problem")
    ap.add_argument("--stream", action="store_true", help="print each line's result (JSON) as it ends")
    ap.add_argument("--json", type=Path, help="write every line's result to this file")
    args = ap.parse_args()
    only = set(args.only.split(",")) - {""} or None
    with tempfile.TemporaryDirectory(prefix="hostile-") as tmp:
        root = Path(tmp)
        places = _places(root)
        places["fresh"] = root / "fresh"
        places["fresh"].mkdir()
        lines = list(_lines(places, only))
        print(f"{len(lines)} command lines, {args.jobs} at once, each killed after {args.timeout:.0f} s", flush=True)
        cpu0 = os.times()
        with ThreadPoolExecutor(args.jobs) as pool:
            results = []
            for i, r in enumerate(pool.map(lambda a: run_line(a, root, SERVERS.get(a[0], args.timeout)), lines), 1):
                results.append(r)
                if args.stream:
                    print(json.dumps(asdict(r)), flush=True)
                elif i % 100 == 0:
                    print(f"{i} done", flush=True)
        cpu1 = os.times()
        shutil.rmtree(places["fresh"], ignore_errors=True)
    base = silence(results)
    for r in results:
        if r.problems or args.show_all:
            print(f"{shown(r.argv)}: status {r.status}, {', '.join(r.problems) or 'ok'}; first byte {r.first_s:.1f} s, "
                  f"longest gap {r.gap_s:.1f} s, {r.wall_s:.1f} s in all; {r.last_line}")
    print("\nstart-up (median seconds to a parser refusal's line): "
          + ", ".join(f"{c} {b:.1f}" for c, b in sorted(base.items())))
    cpu = (cpu1.children_user - cpu0.children_user) + (cpu1.children_system - cpu0.children_system)
    count = {k: sum(1 for r in results if any(p.startswith(k) for p in r.problems))
             for k in ("timeout", "traceback", ".rs:", "silent")}
    statuses: dict[str, int] = {}
    for r in results:
        statuses[str(r.status)] = statuses.get(str(r.status), 0) + 1
    print(f"\n{len(results)} command lines ({cpu:.0f} CPU-s): {count['traceback']} tracebacks, {count['.rs:']} with a "
          f"zenoh source path, {count['silent']} silent for more than {SILENT_S:.0f} s beyond start-up, {count['timeout']} killed at "
          f"{args.timeout:.0f} s; exit statuses {dict(sorted(statuses.items()))}")
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in results], indent=1))
    return 1 if any(r.problems for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
