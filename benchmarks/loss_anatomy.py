"""Where the combined robot loses the Executive's payoff: every lost epoch and episode classified, causes ranked by payoff.

    python benchmarks/loss_anatomy.py RUN_DIR [RUN_DIR ...] [--epochs 300] [--seed 5]
        [--lineups own,learned,learned hand,learned,learned hand,hand,hand] [--diagnostics DIR] [--per-run]
        [--json FILE]

For each finished ``coevo compare`` / ``coevo run`` directory (its ``run.json`` and ``workers/*/best.rules``) it plays
``--epochs`` fresh epochs of the robot under each line-up (Executive, Tracking, Docking: ``own`` / ``hand`` for the
Executive, ``learned`` / ``hand`` for the others; ``hand`` is the yardstick rule set of ``--diagnostics``, never a
start, see diagnostics/README.md) and classifies, pooled over the runs:

- the payoff lost, per cause.  An epoch's payoff is t / (600 + p): its 10 episode slots of 60 steps, less the
  steps not in tracking range, plus the towing penalty p.  Every slot-step not tracked is charged to one cause
  (out of range in a Tracking episode, by what the episode started from; a Docking episode's steps and the rest of
  its slot once docked; the rest of the epoch after a collision, by behaviour and object; after running dry, with
  the penalty), so the causes' shares add up to 1 - payoff exactly.  "If played" prices the slots a collision or
  running dry cut off at the line-up's mean yield per played slot: what the epoch would likely have earned;
- every collision: the behaviour in control, what it hit (the Target by the world's distance test, a wall or the
  dock by the world's own contacts, ``BatchWorld.last_contacts``), whether its episode started right after a
  docking (the robot just in front of the dock), the step, the commanded speed, the fuel;
- every Docking call: the Target's range, the angle between the Target's and the dock's bearings from the robot,
  the dock's range, and how it ended (docked, hit what, time up, dry);
- the epochs that ended dry, by the behaviour in control;
- Tracking's episodes by what they started from (an epoch start, right after a docking, after Tracking) and the
  Target's range then (the share right after a docking is how often Tracking starts where no Independent training
  puts it; docs/docking-learning.md, Round 10, C).

``--json FILE`` writes each run's figures per line-up (payoff, AEL, loss per cause, episodes and collisions by
behaviour and start), to pair runs of two configurations.

Run ``i`` of the list plays its epochs from seed ``--seed + i`` under every line-up (the same starts and Target
noise for each line-up of a run).  Nothing is learned or written; the world's numbers are those of ``coevo``'s own
measures (a recorded play has exactly the outcome of an unrecorded one).
"""

from __future__ import annotations

import argparse
import itertools
import json
import statistics
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from coevo.errors import CoevoError
from coevo.experiments.common import plural
from coevo.policy.rules import RuleSet
from coevo.policy.text import parse_ruleset
from coevo.rundir.settings import RunSettings
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK, Behaviour
from coevo.tasks.fuel.recorder import Recorder
from coevo.tasks.fuel.robot import controllers
from coevo.tasks.fuel.runner import Outcome, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import DOCK_HEADING, BatchWorld, signed_deg

HAND = {"executive": "executive-dock-below-40.rules", "tracking": "tracking-handwritten.rules",
        "docking": "docking-handwritten.rules"}
DEFAULT_LINEUPS = ("own,learned,learned", "hand,learned,learned", "hand,learned,hand", "hand,hand,learned",
                   "hand,hand,hand")
TASK_NAME = {TASK_TRACK: "Tracking", TASK_DOCK: "Docking"}
ANGLE_BINS = (0, 15, 30, 60, 90, 181)  # degrees between the Target's and the dock's bearings at a Docking call


class Probe(Recorder):
    """A :class:`Recorder` that also keeps, after every step, what each robot began touching (a wall, the dock)
    and the speed and turn rate it was commanded: read from the world, nothing changed."""

    wall: np.ndarray
    dock: np.ndarray
    speed: np.ndarray
    turn: np.ndarray

    def open(self, lanes: int, episodes: int, steps: int) -> None:
        super().open(lanes, episodes, steps)
        shape = (episodes, steps + 1, lanes)
        self.wall, self.dock = np.zeros(shape, bool), np.zeros(shape, bool)
        self.speed, self.turn = np.full(shape, np.nan), np.full(shape, np.nan)

    def state(self, world: BatchWorld, k: int, t: int, lanes: np.ndarray) -> None:
        super().state(world, k, t, lanes)
        if t > 0:
            wall, dock = world.last_contacts()
            self.wall[k, t, wall] = True
            self.dock[k, t, dock] = True
            self.speed[k, t, lanes] = world.speed[lanes]
            self.turn[k, t, lanes] = world.turn[lanes]


@dataclass
class Tally:
    """One line-up's records, pooled over runs."""

    epochs: int = 0
    episodes: Counter[str] = field(default_factory=Counter)  # per behaviour, and per behaviour x start kind
    loss: defaultdict[str, float] = field(default_factory=lambda: defaultdict(float))  # cause -> sum over epochs of its share of (600 + p)
    events: Counter[str] = field(default_factory=Counter)  # cause -> how many episodes/epochs it was charged for
    cut_slots: Counter[str] = field(default_factory=Counter)  # cause -> slot-steps a collision/dry cut off
    tracked: int = 0
    played_steps: int = 0  # 60 per played episode
    payoffs: list[float] = field(default_factory=list)  # per run
    lengths: list[float] = field(default_factory=list)  # per run
    collisions: list[dict] = field(default_factory=list)
    calls: list[dict] = field(default_factory=list)
    dry: Counter[str] = field(default_factory=Counter)
    unclassified: int = 0
    target_range: defaultdict[str, list[float]] = field(default_factory=lambda: defaultdict(list))  # Tracking's start kind -> Target ranges at its start

    def add(self, other: Tally) -> None:
        """Pool ``other`` (one run's records) into this one."""
        self.epochs += other.epochs
        self.tracked += other.tracked
        self.played_steps += other.played_steps
        self.unclassified += other.unclassified
        for mine, theirs in ((self.episodes, other.episodes), (self.events, other.events),
                             (self.cut_slots, other.cut_slots), (self.dry, other.dry)):
            mine.update(theirs)
        for cause, v in other.loss.items():
            self.loss[cause] += v
        for kind, rs in other.target_range.items():
            self.target_range[kind] += rs
        self.payoffs += other.payoffs
        self.lengths += other.lengths
        self.collisions += other.collisions
        self.calls += other.calls

    def summary(self) -> dict:
        """One run's figures for ``--json``: payoff, AEL, the payoff lost per cause, episodes and collisions by
        behaviour and what the episode started from."""
        return {"payoff": float(np.mean(self.payoffs)), "ael": float(np.mean(self.lengths)), "epochs": self.epochs,
                "loss": {c: v / self.epochs for c, v in self.loss.items()}, "episodes": dict(self.episodes),
                "collisions": dict(Counter(f"{c['behaviour']} | {c['kind']} | {c['object']}" for c in self.collisions)),
                "dry epochs": sum(self.dry.values())}


def start_kind(out: Outcome, lane: int, k: int) -> str:
    """What episode ``k`` of a lane started from."""
    if k == 0:
        return "epoch start"
    if out.docked[lane, k - 1]:
        return "after docking"
    if out.task[lane, k - 1] == TASK_DOCK:
        return "after a failed docking"
    return "after tracking"


def hit(world: BatchWorld, rec: Probe, k: int, s: int, lane: int) -> tuple[str, str]:
    """What a collision at step ``s`` hit, and a detail (which wall; why the dock refused the robot)."""
    c = world.cfg
    x, y, h = rec.rx[k, s, lane], rec.ry[k, s, lane], np.degrees(rec.rh[k, s, lane])
    dx, dy = rec.tx[k, s, lane] - x, rec.ty[k, s, lane] - y
    objects = []
    if np.sqrt(dx * dx + dy * dy) < c.robot_radius + c.target_radius:  # the world's test, the same arithmetic
        objects.append("Target")
    if rec.wall[k, s, lane]:
        objects.append("wall")
    if rec.dock[k, s, lane]:
        objects.append("dock")
    detail = ""
    if objects == ["wall"]:
        A = c.arena
        gaps = {"west": x, "east": A - x, "south": y, "north": A - y}
        detail = min(gaps, key=gaps.__getitem__)
        if detail == "south" and abs(x - A / 2) < c.dock_width / 2 + 2 * c.robot_radius:
            detail = "south, beside the dock"
    elif objects == ["dock"]:
        sp = rec.speed[k, s, lane]
        why = []
        if not (y >= c.dock_depth and world.dock_x0 <= x <= world.dock_x1):
            why.append("off the front face")
        if sp < 0:
            why.append("reversing")
        elif sp > c.dock_max_speed:
            why.append("too fast")
        if abs((h - DOCK_HEADING + 180) % 360 - 180) > c.dock_max_angle:
            why.append("off-angle")
        detail = " + ".join(why) or "?"
    return "+".join(objects) or "?", detail


def bearing_gap(x: float, y: float, tx: float, ty: float, dock: np.ndarray) -> float:
    """Degrees between the Target's and the dock's bearings as the robot at (x, y) sees them, 0-180."""
    a = np.degrees(np.arctan2(ty - y, tx - x) - np.arctan2(dock[1] - y, dock[0] - x))
    return float(abs(signed_deg(a)))


def play(cfg: WorldConfig, ex: RuleSet, tr: RuleSet, dk: RuleSet, epochs: int, seed: int, tally: Tally,
         per_run: list[str] | None, name: str) -> None:
    """Play ``epochs`` fresh epochs of one robot and add what it lost to ``tally``."""
    world = BatchWorld(cfg, epochs)
    e, t, d = controllers(ex, tr, dk, epochs)
    rec = Probe()
    out = run_lanes(world, lane_episodes=cfg.epoch_episodes, executive=e, tracking=t, docking=d,
                    restart_epochs=False, rng=np.random.default_rng(seed), record=rec)
    T, K = cfg.episode_steps, cfg.epoch_episodes
    if not out.epoch_complete.all() or len(out.epoch_lane) != epochs:
        raise CoevoError("an epoch did not end by its own rules")  # cannot happen: one epoch per lane
    run_loss: defaultdict[str, float] = defaultdict(float)
    for ep in range(len(out.epoch_lane)):
        lane = int(out.epoch_lane[ep])
        pen = int(out.epoch_penalty[ep])
        denom = T * K + pen
        charged: Counter[str] = Counter()  # slot-steps per cause in this epoch
        end_cause = ""
        n = int(out.epoch_episodes[ep])
        for k in range(n):
            task = int(out.task[lane, k])
            beh = TASK_NAME[task]
            kind = start_kind(out, lane, k)
            s, tracked = int(out.steps[lane, k]), int(out.tracked[lane, k])
            tally.episodes[beh] += 1
            tally.episodes[f"{beh} | {kind}"] += 1
            if task == TASK_TRACK:
                tally.target_range[kind].append(float(np.hypot(rec.tx[k, 0, lane] - rec.rx[k, 0, lane],
                                                               rec.ty[k, 0, lane] - rec.ry[k, 0, lane])))
            tally.tracked += tracked
            tally.played_steps += T
            cause = f"Tracking, out of range ({kind})" if task == TASK_TRACK else "Docking episodes: steps"
            charged[cause] += s - tracked
            tally.events[cause] += 1
            rest = T - s
            if out.collided[lane, k]:
                obj, detail = hit(world, rec, k, s, lane)
                if obj == "?":
                    tally.unclassified += 1
                end_cause = f"collision: {beh} hit {obj}" + (" (right after docking)" if kind == "after docking" else "")
                tally.collisions.append({
                    "behaviour": beh, "object": obj, "detail": detail, "kind": kind,
                    "after docking": kind == "after docking", "step": s, "speed": float(rec.speed[k, s, lane]),
                    "fuel": 100 * float(rec.fuel[k, s, lane]),
                    "dock range": float(np.hypot(rec.rx[k, s, lane] - world.dock_point[0],
                                                 rec.ry[k, s, lane] - world.dock_point[1]))})
            elif out.dry[lane, k]:
                end_cause = f"ran dry: {beh}"
                tally.dry[f"{beh} ({kind})"] += 1
            elif out.docked[lane, k]:
                charged["Docking episodes: rest of the slot after docking" if task == TASK_DOCK
                        else "Tracking docked by chance: rest of the slot"] += rest
                rest = 0
            if task == TASK_DOCK:
                x0, y0 = rec.rx[k, 0, lane], rec.ry[k, 0, lane]
                tx0, ty0 = rec.tx[k, 0, lane], rec.ty[k, 0, lane]
                how = ("docked" if out.docked[lane, k] else "dry" if out.dry[lane, k]
                       else f"hit {hit(world, rec, k, s, lane)[0]}" if out.collided[lane, k] else "time up")
                tally.calls.append({
                    "kind": kind, "how": how, "step": s, "fuel": 100 * float(rec.fuel[k, 0, lane]),
                    "target range": float(np.hypot(tx0 - x0, ty0 - y0)),
                    "dock range": float(np.hypot(world.dock_point[0] - x0, world.dock_point[1] - y0)),
                    "angle": bearing_gap(x0, y0, tx0, ty0, world.dock_point)})
            if rest and end_cause:
                charged[end_cause] += rest
                tally.cut_slots[end_cause] += rest
        if end_cause:
            charged[end_cause] += (K - n) * T
            tally.cut_slots[end_cause] += (K - n) * T
            tally.events[end_cause] += 1
            if pen:
                charged["ran dry: towing penalty"] += pen
                tally.events["ran dry: towing penalty"] += 1
        tracked = int(out.epoch_tracked[ep])
        if sum(charged.values()) + tracked != denom:
            raise CoevoError(f"epoch {ep}: the charged steps do not add up")  # a bug in this script
        for cause, steps in charged.items():
            tally.loss[cause] += steps / denom
            run_loss[cause] += steps / denom
    tally.epochs += len(out.epoch_lane)
    pay = float(out.epoch_payoff.mean())
    tally.payoffs.append(pay)
    tally.lengths.append(float(out.epoch_episodes.mean()))
    if per_run is not None:
        top = sorted(run_loss.items(), key=lambda kv: -kv[1])[:4]
        per_run.append(f"{name}: payoff {pay:.3f}, AEL {out.epoch_episodes.mean():.2f}; largest losses "
                       + ", ".join(f"{c} {v / epochs:.3f}" for c, v in top))


def _med(xs: list[float]) -> str:
    return f"{statistics.median(xs):.0f}" if xs else "-"


def report(lineup: str, t: Tally, runs: int) -> None:
    n_ep = t.epochs
    pay = np.mean(t.payoffs)
    print(f"\n### {lineup.replace(',', ', ')} ({plural(runs, 'run')}, {n_ep} epochs)\n")
    print(f"Executive payoff {pay:.3f} (median over runs {statistics.median(t.payoffs):.3f}), "
          f"loss {1 - pay:.3f}; AEL {np.mean(t.lengths):.2f}; episodes: Tracking {t.episodes['Tracking']}, "
          f"Docking {t.episodes['Docking']}.")
    if t.unclassified:
        print(f"**{t.unclassified} collisions matched no object** (a bug in the classification).")
    yld = t.tracked / max(1, t.played_steps)
    print(f"\nPayoff lost, per cause (mean over epochs; the shares add up to the loss). Yield per played slot-step "
          f"{yld:.3f}.\n")
    print("| cause | payoff lost | % of the loss | epochs/episodes | if played at the mean yield |")
    print("|---|---|---|---|---|")
    for cause, v in sorted(t.loss.items(), key=lambda kv: -kv[1]):
        share = v / n_ep
        cut = t.cut_slots.get(cause, 0)
        if_played = f"{yld * cut / (n_ep * 600):.3f}" if cut else ""
        count = t.events.get(cause, "")
        print(f"| {cause} | {share:.3f} | {100 * share / (1 - pay):.1f} | {count} | {if_played} |")

    print("\nCollisions (% of that behaviour's episodes; speed is the commanded speed at the collision).\n")
    print("| behaviour | hit | episode started | n | % of its episodes | median step | median speed ips "
          "| at 16 ips % | reversing % | median fuel % | median dock range in |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    groups: dict[tuple[str, str, str], list[dict]] = defaultdict(list)
    for c in t.collisions:
        groups[(c["behaviour"], c["object"], "after docking" if c["after docking"] else "otherwise")].append(c)
    for key in sorted(groups, key=lambda g: -len(groups[g])):
        cs = groups[key]
        sp = [c["speed"] for c in cs]
        print(f"| {key[0]} | {key[1]} | {key[2]} | {len(cs)} | {100 * len(cs) / max(1, t.episodes[key[0]]):.2f} | "
              f"{_med([c['step'] for c in cs])} | {statistics.median(sp):.0f} | "
              f"{100 * sum(s >= 16 for s in sp) / len(cs):.0f} | {100 * sum(s < 0 for s in sp) / len(cs):.0f} | "
              f"{_med([c['fuel'] for c in cs])} | {_med([c['dock range'] for c in cs])} |")
    details = Counter(f"{c['behaviour']} hit {c['object']}: {c['detail']}" for c in t.collisions if c["detail"])
    if details:
        print("\nWalls and dock, in detail: " + "; ".join(f"{k} {v}" for k, v in details.most_common()) + ".")
    n_tr = t.episodes["Tracking"]
    print("\nTracking's episodes by what they started from (the Target's range at the start, median and quartiles): "
          + "; ".join(f"{kd} {len(rs)} ({100 * len(rs) / max(1, n_tr):.1f} %, {np.median(rs):.0f} in, "
                      f"{np.percentile(rs, 25):.0f}-{np.percentile(rs, 75):.0f})"
                      for kd, rs in sorted(t.target_range.items(), key=lambda kv: -len(kv[1]))) + ".")
    kinds = Counter((c["behaviour"], c["kind"]) for c in t.collisions)
    print("\nCollisions per episode by what the episode started from: " + "; ".join(
        f"{b} {kd}: {v} of {t.episodes[f'{b} | {kd}']} ({100 * v / max(1, t.episodes[f'{b} | {kd}']):.2f} %)"
        for (b, kd), v in sorted(kinds.items())) + ".")

    calls = t.calls
    if calls:
        hows = ["docked", "hit Target", "hit wall", "hit dock", "time up", "dry"]
        others = sorted({c["how"] for c in calls} - set(hows))
        print("\nDocking calls by the angle between the Target's and the dock's bearings at the call "
              "(% of the calls in the row).\n")
        print("| angle | calls | " + " | ".join(hows + others) + " | median Target range in | median dock range in |")
        print("|---|---|" + "---|" * (len(hows) + len(others)) + "---|---|")
        rows = [(f"{lo}-{hi if hi < 181 else 180}°", [c for c in calls if lo <= c["angle"] < hi])
                for lo, hi in itertools.pairwise(ANGLE_BINS)]
        near = [c for c in calls if c["angle"] < 30 and c["target range"] < c["dock range"]]
        rows += [("< 30° and the Target nearer than the dock", near), ("all", calls)]
        for label, cs in rows:
            if not cs:
                continue
            hc = Counter(c["how"] for c in cs)
            print(f"| {label} | {len(cs)} | " + " | ".join(f"{100 * hc[h] / len(cs):.1f}" for h in hows + others)
                  + f" | {_med([c['target range'] for c in cs])} | {_med([c['dock range'] for c in cs])} |")
        kinds_d = Counter(c["kind"] for c in calls)
        failed = [c for c in calls if c["how"] != "docked"]
        print("\nDocking calls by what they started from: " + ", ".join(
            f"{k} {v} ({100 * sum(c['kind'] == k and c['how'] == 'docked' for c in calls) / v:.0f} % docked)"
            for k, v in kinds_d.most_common()) + f"; fuel at the call: median {_med([c['fuel'] for c in calls])} %; "
              f"failed calls' median step {_med([c['step'] for c in failed])}.")
    if t.dry:
        print("\nEpochs that ended dry: " + ", ".join(f"{k} {v}" for k, v in t.dry.most_common())
              + f" ({100 * sum(t.dry.values()) / n_ep:.2f} % of the epochs).")
    else:
        print("\nNo epoch ended dry.")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="finished run directories (run.json, workers/*/best.rules)")
    ap.add_argument("--epochs", type=int, default=300)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--lineups", nargs="+", default=list(DEFAULT_LINEUPS),
                    help="Executive,Tracking,Docking each: own|hand, learned|hand, learned|hand")
    ap.add_argument("--diagnostics", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "diagnostics",
                    help="the folder of the hand-written rule sets (default ../shared/diagnostics)")
    ap.add_argument("--per-run", action="store_true", help="also print one line per run and line-up")
    ap.add_argument("--json", type=Path, help="also write each run's figures per line-up to this file (for pairing runs)")
    a = ap.parse_args()
    if a.epochs < 1:
        ap.error(f"--epochs must be at least 1, got {a.epochs}")
    lineups = []
    for lu in a.lineups:
        parts = lu.split(",")
        if (len(parts) != 3 or parts[0] not in ("own", "hand") or parts[1] not in ("learned", "hand")
                or parts[2] not in ("learned", "hand")):
            ap.error(f"--lineups: {lu!r} is not EXECUTIVE,TRACKING,DOCKING with own|hand,learned|hand,learned|hand")
        lineups.append(parts)
    hand: dict[str, RuleSet] = {}
    if any("hand" in p for p in lineups):
        try:
            hand = {b: parse_ruleset((a.diagnostics / f).read_text(), Behaviour(b)) for b, f in HAND.items()}
        except (OSError, CoevoError) as exc:
            ap.error(f"--diagnostics {a.diagnostics}: {exc}")
    loaded = []
    for run in a.runs:
        try:
            cfg = RunSettings.load(run / "run.json").world_config()
            own = {b: parse_ruleset((run / "workers" / b / "best.rules").read_text(), Behaviour(b)) for b in HAND}
        except (OSError, CoevoError) as exc:
            ap.error(f"{run} is not a finished run with run.json and workers/*/best.rules ({exc})")
        if not isinstance(cfg, WorldConfig):
            ap.error(f"{run} is not a run of the fuel task")
        loaded.append((run, cfg, own))
    tallies = {",".join(p): Tally() for p in lineups}
    per_run: list[str] | None = [] if a.per_run else None
    figures: list[dict] = []
    for i, (run, cfg, own) in enumerate(loaded):
        for p in lineups:
            pick = [hand if w == "hand" else own for w in p]
            one = Tally()
            try:
                play(cfg, pick[0]["executive"], pick[1]["tracking"], pick[2]["docking"], a.epochs, a.seed + i,
                     one, per_run, f"{run.name} [{','.join(p)}]")
            except CoevoError as exc:
                raise SystemExit(f"{run}: {type(exc).__name__}: {exc}") from None
            tallies[",".join(p)].add(one)
            figures.append({"run": str(run), "lineup": ",".join(p), "seed": a.seed + i, **one.summary()})
    if a.json is not None:
        a.json.write_text(json.dumps(figures, indent=1) + "\n")
    print(f"Seeds {a.seed}..{a.seed + len(loaded) - 1}, {a.epochs} epochs per run and line-up.")
    for lu, t in tallies.items():
        report(lu, t, len(loaded))
    if per_run:
        print("\nPer run:\n" + "\n".join(per_run))


if __name__ == "__main__":
    main()
