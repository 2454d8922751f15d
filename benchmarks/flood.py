"""How much a flood of bad messages slows a worker's GA, against a baseline measured in the same run.

    python benchmarks/flood.py                    (5,000 bad messages/s; about 2 minutes on 2 cores)
    python benchmarks/flood.py --rate 20000 --json

Starts ``coevo broker`` and one unpaced ``coevo worker`` (the executive, independent
regime, so nothing it does waits on the bus).  This process watches the worker's
``curve.jsonl`` and, after ``--warmup`` generations (dropped), alternates phases of
``--per-phase`` generations: quiet, flood, quiet, flood, ... (``--phases`` of them,
odd by default so drift over the run hits both kinds alike).  During a flood phase
a thread puts garbage at ``--rate`` messages/s, spread over the executive's partner
policy keys, its control key and a status key nobody subscribes to while unpaced:
random bytes and msgpack maps that are not messages.  The worker's rings keep only
the newest few per key, so the GA should be slowed by little more than the CPU the
flood's traffic costs the machine (router, Zenoh's threads in the worker, this
process); the CPU use of each process per phase is reported so that can be seen.

Reported: mean and median generation seconds (the curve's ``seconds``) of quiet and
flood generations and the slowdown in per cent, overall and paired (each flood phase
against the quiet phases either side; "clean": only where the CPU used by processes
outside this benchmark stayed under ``--max-other``); the flood rate achieved
(messages put, not necessarily delivered: Zenoh drops puts under congestion); the CPU
per process and of the whole machine; the rejection counts of the worker (its
``done.json``) and of the broker (its last BrokerStatus).  With ``--out DIR`` the
broker's and worker's files and logs stay in DIR, with ``result.json``.  Linux only
(CPU is read from /proc).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import msgpack

from coevo.bus import keys
from coevo.bus.messages import BrokerStatus, Control, decode, encode
from coevo.bus.session import drain, make_config, open_session, ring_subscriber
from coevo.errors import MessageError
from coevo.runs.local import end_processes, free_port

RUN = "flood"
FLOOD_KEYS = [keys.policy(RUN, "tracking"), keys.policy(RUN, "docking"), keys.control(RUN), keys.status(RUN, "tracking", "x")]
TICKS = os.sysconf("SC_CLK_TCK")


def garbage(n: int, size: int, seed: int = 0) -> list[bytes]:
    """``n`` bad payloads: 3 in 4 random bytes of ``size``, the rest msgpack maps that are not messages."""
    rnd = random.Random(seed)
    out: list[bytes] = []
    for i in range(n):
        junk = rnd.randbytes(max(8, size - 120))
        if i % 4 != 3:
            out.append(rnd.randbytes(size))
        elif i % 8 == 3:  # right version, missing fields
            out.append(msgpack.packb({"kind": "policy", "schema_version": 1, "run": RUN, "behaviour": "tracking",
                                      "junk": junk}, use_bin_type=True))
        else:  # another schema version
            out.append(msgpack.packb({"kind": "control", "schema_version": 99, "run": RUN, "junk": junk}, use_bin_type=True))
    for p in out:  # never, by accident, a message (least of all a stop)
        try:
            decode(p)
        except MessageError:
            continue
        raise AssertionError("a garbage payload decoded as a message")
    return out


class Flooder:
    """A thread putting garbage at ``rate`` messages/s round-robin over FLOOD_KEYS, between start() and stop()."""

    def __init__(self, session: Any, rate: float, payloads: list[bytes]) -> None:
        self.pubs = [session.declare_publisher(k) for k in FLOOD_KEYS]
        self.rate = rate
        self.payloads = payloads
        self._halt = threading.Event()
        self._thread: threading.Thread | None = None
        self.sent = 0
        self.seconds = 0.0

    def _loop(self) -> None:
        pubs, payloads, rate = self.pubs, self.payloads, self.rate
        np_, nk = len(payloads), len(pubs)
        t0 = time.perf_counter()
        i = 0
        while not self._halt.is_set():
            due = int(rate * (time.perf_counter() - t0))
            if i >= due:
                time.sleep(0.001)
                continue
            for _ in range(min(due - i, 1000)):  # catch up in bursts, checking the halt flag between them
                pubs[i % nk].put(payloads[(i // nk) % np_])  # every key gets every kind of garbage
                i += 1
        self.sent += i
        self.seconds += time.perf_counter() - t0

    def start(self) -> None:
        self._halt.clear()
        self._thread = threading.Thread(target=self._loop, name="flood", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        if self._thread is not None:
            self._halt.set()
            self._thread.join()
            self._thread = None

    def close(self) -> None:
        self.stop()
        for p in self.pubs:
            p.undeclare()


def cpu_seconds(pid: int | None = None) -> float:
    """User + system CPU seconds of a process (all its threads); this process if ``pid`` is None."""
    if pid is None:
        t = os.times()
        return t.user + t.system
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / TICKS
    except (OSError, IndexError, ValueError):
        return float("nan")


def machine_busy() -> tuple[float, float]:
    """(busy, total) jiffies of all CPUs, from /proc/stat."""
    try:
        v = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    except (OSError, ValueError):
        return float("nan"), float("nan")
    idle = v[3] + (v[4] if len(v) > 4 else 0)
    return float(sum(v[:8]) - idle), float(sum(v[:8]))


def curve_rows(path: Path) -> list[dict[str, Any]]:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return []
    rows = []
    for line in text.splitlines():
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:  # a line being written
            break
    return rows


class CurveCount:
    """How many complete lines ``curve.jsonl`` holds, reading only what was appended since the last look."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0
        self.lines = 0

    def __call__(self) -> int:
        try:
            with open(self.path, "rb") as f:
                f.seek(self.offset)
                new = f.read()
        except FileNotFoundError:
            return 0
        end = new.rfind(b"\n") + 1
        self.lines += new.count(b"\n", 0, end)
        self.offset += end
        return self.lines


def tail(path: Path, n: int = 15) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-n:])
    except OSError:
        return ""


def end(p: subprocess.Popen[bytes] | None) -> None:
    """SIGTERM, then SIGKILL after 10 s."""
    if p is not None:
        end_processes([p])


def pct(a: float, b: float) -> float:
    return 100.0 * (a / b - 1.0) if b else float("nan")


def bench(args: argparse.Namespace, tmp: Path) -> dict[str, Any]:
    wdir = tmp / "w"
    with open(tmp / "broker.log", "wb") as broker_log, open(tmp / "worker.log", "wb") as worker_log:
        phases, broker_acct = run_phases(args, tmp, broker_log, worker_log)
    done_json = json.loads((wdir / "done.json").read_text()) if (wdir / "done.json").exists() else None
    return summarise(args, curve_rows(wdir / "curve.jsonl"), phases, done_json, broker_acct)


def run_phases(args: argparse.Namespace, tmp: Path, broker_log: Any, worker_log: Any) -> tuple[list[dict[str, Any]], BrokerStatus | None]:
    """Broker, worker, then the phases; returns each phase's account and the broker's last BrokerStatus."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    wdir = tmp / "w"
    total = args.warmup + args.phases * args.per_phase
    broker = worker = None
    phases: list[dict[str, Any]] = []
    try:
        broker = subprocess.Popen([sys.executable, "-m", "coevo", "broker", "--listen", endpoint, "--data-dir", str(tmp / "data"), "--open"],
                                  stdout=broker_log, stderr=subprocess.STDOUT)
        with open_session(make_config(mode="client", connect=[endpoint], connect_timeout=20)) as s:
            deadline = time.monotonic() + 30
            while not any(r.ok is not None for r in s.liveliness().get(keys.BROKER, timeout=1.0)):
                if broker.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"the broker did not come up:\n{tail(tmp / 'broker.log')}")
                time.sleep(0.2)
            broker_status = ring_subscriber(s, keys.broker_status(RUN), 1)
            worker = subprocess.Popen(
                [sys.executable, "-m", "coevo", "worker", "--behaviour", "executive", "--regime", "independent", "--run", RUN,
                 "--connect", endpoint, "--max-lead", "off", "--generations", str(total), "--population", str(args.population),
                 "--episodes", str(args.episodes), "--ga", f"best_episodes={args.best_episodes}", "--seed", str(args.seed),
                 "--out", str(wdir)],
                stdout=worker_log, stderr=subprocess.STDOUT)
            flooder = Flooder(s, args.rate, garbage(256, args.size, args.seed))
            procs = {"worker": worker.pid, "broker": broker.pid, "bench": None}
            try:
                cur: dict[str, Any] | None = None
                done = 0
                count = CurveCount(wdir / "curve.jsonl")
                while done < total:
                    if worker.poll() is not None:
                        raise RuntimeError(f"the worker ended early (exit {worker.returncode}):\n{tail(tmp / 'worker.log')}")
                    done = count()
                    k = (done - args.warmup) // args.per_phase  # the phase generation done+1 runs in
                    if done >= args.warmup and (cur is None or cur["index"] != k) and k < args.phases:
                        if cur is not None:
                            close_phase(cur, flooder, procs)
                        cur = {"index": k, "kind": "flood" if k % 2 else "quiet",
                               "first": args.warmup + k * args.per_phase + 1, "wall": time.perf_counter(),
                               "cpu": {n: cpu_seconds(p) for n, p in procs.items()}, "machine": machine_busy(),
                               "sent0": flooder.sent, "fs0": flooder.seconds}
                        phases.append(cur)
                        if cur["kind"] == "flood":
                            flooder.start()
                    time.sleep(args.poll)
                if cur is not None:
                    close_phase(cur, flooder, procs)
            finally:
                flooder.close()
            # The worker has finished its generations (or is about to): ask it to stop, so done.json is written either way.
            if worker.poll() is None:
                s.put(keys.control(RUN), encode(Control(run=RUN, command="stop", sent_at=time.time())))
            try:
                worker.wait(args.stop_wait)
            except subprocess.TimeoutExpired:
                pass
            time.sleep(2.5)  # one more BrokerStatus (every 2 s) with everything counted
            bs = [decode(p) for _, p in drain(broker_status, 8)]
            broker_acct = bs[-1] if bs and isinstance(bs[-1], BrokerStatus) else None
    finally:
        end(worker)
        end(broker)
    return phases, broker_acct


def close_phase(ph: dict[str, Any], flooder: Flooder, procs: dict[str, int | None]) -> None:
    flooder.stop()
    wall = time.perf_counter() - ph["wall"]
    ph["seconds"] = wall
    ph["cpu_pct"] = {n: 100.0 * (cpu_seconds(p) - ph["cpu"][n]) / wall for n, p in procs.items()}
    b1, t1 = machine_busy()
    b0, t0 = ph["machine"]
    ph["machine_pct"] = 100.0 * (b1 - b0) / (t1 - t0) * (os.cpu_count() or 1) if t1 > t0 else float("nan")
    ph["other_pct"] = ph["machine_pct"] - sum(ph["cpu_pct"].values())  # processes not of this benchmark
    ph["sent"] = flooder.sent - ph["sent0"]
    ph["rate"] = ph["sent"] / (flooder.seconds - ph["fs0"]) if flooder.seconds > ph["fs0"] else 0.0
    for k in ("cpu", "machine", "sent0", "fs0", "wall"):
        del ph[k]


def summarise(args: argparse.Namespace, rows: list[dict[str, Any]], phases: list[dict[str, Any]], done: dict[str, Any] | None,
              broker: BrokerStatus | None) -> dict[str, Any]:
    secs = {int(r["generation"]): float(r["seconds"]) for r in rows}
    by_kind: dict[str, list[float]] = {"quiet": [], "flood": []}
    for ph in phases:
        ph["wall_per_gen_s"] = ph["seconds"] / args.per_phase
        gens = range(ph["first"] + args.settle, ph["first"] + args.per_phase)
        kept = [g for g in gens if g in secs]
        ph["generations"] = [kept[0], kept[-1]] if kept else None  # first and last counted
        ph["mean_s"] = statistics.fmean([secs[g] for g in kept]) if kept else float("nan")
        by_kind[ph["kind"]] += [secs[g] for g in kept]
    q, f = by_kind["quiet"], by_kind["flood"]
    floods = [ph for ph in phases if ph["kind"] == "flood"]
    sent, fsec = sum(ph["sent"] for ph in floods), sum(ph["sent"] / ph["rate"] for ph in floods if ph["rate"])

    def wall(kind: str) -> float | None:
        v = [ph["wall_per_gen_s"] for ph in phases if ph["kind"] == kind]
        return statistics.fmean(v) if v else None

    def mean_cpu(kind: str, name: str) -> float:
        v = [ph[f"{name}_pct"] if name in ("machine", "other") else ph["cpu_pct"][name] for ph in phases if ph["kind"] == kind]
        return statistics.fmean(v) if v else float("nan")

    res: dict[str, Any] = {
        "settings": {"rate": args.rate, "size": args.size, "population": args.population, "episodes": args.episodes,
                     "best_episodes": args.best_episodes, "warmup": args.warmup, "per_phase": args.per_phase,
                     "phases": args.phases, "settle": args.settle, "max_other": args.max_other, "seed": args.seed, "cpus": os.cpu_count()},
        "quiet": {"generations": len(q), "mean_s": statistics.fmean(q) if q else None, "median_s": statistics.median(q) if q else None,
                  "wall_per_gen_s": wall("quiet")},
        "flood": {"generations": len(f), "mean_s": statistics.fmean(f) if f else None, "median_s": statistics.median(f) if f else None,
                  "wall_per_gen_s": wall("flood")},
        "flood_rate_target": args.rate,
        "flood_rate_achieved": sent / fsec if fsec else 0.0,
        "flood_messages": sent,
        "cpu_pct": {kind: {n: mean_cpu(kind, n) for n in ("worker", "broker", "bench", "other", "machine")} for kind in ("quiet", "flood")},
        "phases": phases,
        "worker_rejected": done.get("rejected") if done else None,
        "worker_done": {k: done[k] for k in ("generations", "finished", "gen_seconds", "net_seconds")} if done else None,
        "broker_rejected": dict(broker.rejected) if broker else None,
        "broker_dropped": broker.dropped if broker else None,
    }
    if q and f:
        res["slowdown_pct"] = {"mean": pct(res["flood"]["mean_s"], res["quiet"]["mean_s"]),
                               "median": pct(res["flood"]["median_s"], res["quiet"]["median_s"]),
                               "wall": pct(res["flood"]["wall_per_gen_s"], res["quiet"]["wall_per_gen_s"])}
        # Each flood phase against the quiet phases either side of it: less sensitive to drift over the run.
        # "clean": only the triples in which no phase saw more than --max-other % of a CPU of outside load.
        paired: list[float] = []
        clean: list[float] = []
        for i, ph in enumerate(phases):
            near = [phases[j] for j in (i - 1, i + 1) if 0 <= j < len(phases) and phases[j]["kind"] == "quiet"]
            if ph["kind"] == "flood" and near:
                paired.append(pct(ph["mean_s"], statistics.fmean(n["mean_s"] for n in near)))
                if max(n["other_pct"] for n in (ph, *near)) <= args.max_other:
                    clean.append(paired[-1])
        for name, v in (("paired", paired), ("clean", clean)):
            res["slowdown_pct"][name] = {"pairs": len(v), "mean": statistics.fmean(v) if v else None,
                                         "median": statistics.median(v) if v else None,
                                         "se": statistics.stdev(v) / len(v) ** 0.5 if len(v) > 1 else None}
    return res


def show(r: dict[str, Any], *, per_phase: bool = False) -> None:
    s = r["settings"]
    print(f"executive worker, population {s['population']}, {s['episodes']} episodes; {s['warmup']} warm-up generations dropped, "
          f"then {s['phases']} phases of {s['per_phase']} generations (the first {s['settle']} of each dropped); {s['cpus']} CPUs")
    print(f"flood: target {r['flood_rate_target']:.0f} msg/s of {s['size']} bytes, achieved {r['flood_rate_achieved']:.0f} msg/s "
          f"({r['flood_messages']} messages put)")
    print()
    print(f"{'':6} {'gens':>5} {'mean s':>8} {'median s':>9} {'wall s/gen':>11}   CPU %: {'worker':>6} {'broker':>6} {'bench':>6} "
          f"{'other':>6} {'machine':>7}")
    for kind in ("quiet", "flood"):
        k, c = r[kind], r["cpu_pct"][kind]
        if not k["generations"]:
            continue
        print(f"{kind:6} {k['generations']:>5} {k['mean_s']:>8.4f} {k['median_s']:>9.4f} {k['wall_per_gen_s']:>11.4f}   "
              f"       {c['worker']:>6.0f} {c['broker']:>6.0f} {c['bench']:>6.0f} {c['other']:>6.0f} {c['machine']:>7.0f}")
    if "slowdown_pct" in r:
        sd = r["slowdown_pct"]
        print(f"slowdown of the GA under flood: mean {sd['mean']:+.1f}%, median {sd['median']:+.1f}%; "
              f"wall time per generation {sd['wall']:+.1f}%")
        for name, what in (("paired", "all"), ("clean", f"outside load <= {r['settings']['max_other']:g}% of a CPU")):
            p = sd[name]
            if p["pairs"]:
                se = f" (standard error {p['se']:.1f})" if p["se"] is not None else ""
                print(f"each flood phase against the quiet phases either side, {what}: {p['pairs']} flood phases, "
                      f"mean {p['mean']:+.1f}%{se}, median {p['median']:+.1f}%")
            else:
                print(f"each flood phase against the quiet phases either side, {what}: none")
    print("(mean/median s: the curve's GA seconds; wall s/gen: all of a generation, with the worker's own reading of its inbox;\n"
          " CPU % of one CPU; machine: every process on it, from /proc/stat; other: machine less this benchmark's three:\n"
          " load from outside, which makes the figures noisy when it is well above 0)")
    if per_phase:
        print_phases(r)
    print()
    d = r["worker_done"]
    if d:
        print(f"worker: {d['generations']} generations (finished {d['finished']}), rejected {r['worker_rejected']}")
    else:
        print("worker: no done.json (it did not stop cleanly)")
    if r["broker_rejected"] is not None:
        print(f"broker: rejected {r['broker_rejected']}, of which dropped unread {r['broker_dropped']}")


def print_phases(r: dict[str, Any]) -> None:
    print()
    print(f"{'phase':>5} {'kind':5} {'generations':>11} {'mean s':>7} {'wall s/gen':>10} {'msg/s':>6}   CPU %: {'worker':>6} "
          f"{'broker':>6} {'bench':>6} {'other':>6} {'machine':>7}")
    for ph in r["phases"]:
        g = ph["generations"]
        span = f"{g[0]}-{g[1]}" if g else "-"
        c = ph["cpu_pct"]
        print(f"{ph['index']:>5} {ph['kind']:5} {span:>11} {ph['mean_s']:>7.4f} {ph['wall_per_gen_s']:>10.4f} {ph['rate']:>6.0f}   "
              f"       {c['worker']:>6.0f} {c['broker']:>6.0f} {c['bench']:>6.0f} {ph['other_pct']:>6.0f} {ph['machine_pct']:>7.0f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rate", type=float, default=5000, help="bad messages per second during a flood phase (default 5000)")
    ap.add_argument("--size", type=int, default=200, help="bytes per bad message (default 200)")
    ap.add_argument("--per-phase", type=int, default=20, metavar="K",
                    help="generations per phase (default 20: about 1.5 s; short phases keep the GA's own drift out of the pairs)")
    ap.add_argument("--phases", type=int, default=75, help="quiet, flood, quiet, ... phases (default 75: 38 quiet, 37 flood)")
    ap.add_argument("--warmup", type=int, default=2, help="first generations, dropped (default 2)")
    ap.add_argument("--settle", type=int, default=1,
                    help="generations dropped at the start of every phase: the one the switch happened in (default 1)")
    ap.add_argument("--max-other", type=float, default=20, metavar="PCT",
                    help="outside CPU load (%% of a CPU) above which a phase counts as disturbed in the 'clean' figure (default 20)")
    ap.add_argument("--population", type=int, default=20)
    ap.add_argument("--episodes", type=int, default=45)
    ap.add_argument("--best-episodes", type=int, default=45)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--poll", type=float, default=0.005, help="seconds between looks at curve.jsonl (default 0.005)")
    ap.add_argument("--stop-wait", type=float, default=60, help="seconds to wait for the worker to stop at the end (default 60)")
    ap.add_argument("--out", help="keep the broker's and worker's files and logs here, and result.json (default: a temporary directory)")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    ap.add_argument("--per-phase-table", action="store_true", help="also print a row per phase")
    args = ap.parse_args()
    if args.phases < 2 or args.warmup < 0 or not 0 <= args.settle < args.per_phase or args.rate <= 0:
        ap.error("need --phases >= 2, --warmup >= 0, 0 <= --settle < --per-phase and --rate > 0")
    if args.out:
        tmp = Path(args.out)
        tmp.mkdir(parents=True, exist_ok=True)
        for old in ("w", "data"):  # a fresh worker and store, not a resumed run
            shutil.rmtree(tmp / old, ignore_errors=True)
        res = bench(args, tmp)
        (tmp / "result.json").write_text(json.dumps(res, indent=1))
    else:
        with tempfile.TemporaryDirectory(prefix="coevo-flood-") as d:
            res = bench(args, Path(d))
    if args.json:
        print(json.dumps(res))
    else:
        show(res, per_phase=args.per_phase_table)


if __name__ == "__main__":
    main()
