"""``coevo bench``: robot-steps per second of the fuel task's batched world against a plain one-episode pymunk loop.

A command of the fuel task's own, declared beside its work (:mod:`coevo.tasks.fuel.bench`) and gathered by
:mod:`coevo.cli`; its top imports only what a parser needs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from coevo.config import Bounded, pairs

__all__ = ["configure_bench"]


def configure_bench(p: argparse.ArgumentParser) -> None:
    """``coevo bench``'s arguments."""
    p.add_argument("--behaviour", default="tracking", choices=["tracking", "docking"],
                   help="whose rule layout the policies have (default tracking)")
    p.add_argument("--lanes", type=Bounded(1, 100_000), default=4500, help="episodes run at once (default 50 x 90)")
    p.add_argument("--rules", type=Bounded(1, 64), default=32, help="rules per policy (evolved size)")
    p.add_argument("--policy", help="a rule file to drive every lane instead of random rule sets")
    p.add_argument("--repeats", type=Bounded(1, 1000), default=3, help="times the batched run is timed, the best kept (default 3)")
    p.add_argument("--baseline-seconds", type=Bounded(0, 3600, whole=False, above=True), default=3.0,
                   help="seconds the plain one-episode loop runs (default 3)")
    p.add_argument("--seed", type=Bounded(0, 2**63 - 1, what="seed"), default=0, help="seeds the policies and starts (default 0)")
    p.add_argument("--world", action="append", metavar="NAME=VALUE", help="world setting, e.g. target_speed=3 (repeatable)")
    p.add_argument("--json", action="store_true", help="print both figures and their ratio as JSON")
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    from coevo.config import build
    from coevo.policy.text import read_rule_file
    from coevo.tasks.fuel.bench import bench
    from coevo.tasks.fuel.settings import WorldConfig

    world = build(WorldConfig, pairs(args.world, "world"))
    res = bench(world=world, behaviour=args.behaviour, lanes=args.lanes, rules=args.rules, repeats=args.repeats,
                baseline_seconds=args.baseline_seconds, seed=args.seed, policy=None if args.policy is None else read_rule_file(Path(args.policy), args.behaviour))
    if args.json:
        print(json.dumps(res.as_dict(), indent=2))
    else:
        print(f"batched ({res.lanes} lanes, {res.rules_per_policy} rules): {res.batched_steps_per_s / 1e6:.3f} M robot-steps/s")
        print(f"plain one-episode loop:                {res.baseline_steps_per_s / 1e6:.3f} M robot-steps/s")
        print(f"ratio {res.ratio:.1f}x; batch peak {res.batch_peak_mb:.0f} MB (tracemalloc), process max RSS {res.max_rss_mb:.0f} MB")
    return 0
