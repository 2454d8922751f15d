"""The commands that look at a finished run: ``coevo check`` (is it complete?) and ``coevo replay`` (re-run it).

Gathered by :mod:`coevo.cli`; the work is :mod:`coevo.runs.check` and :mod:`coevo.runs.replay`.
"""

from __future__ import annotations

import argparse
import sys
from functools import partial
from pathlib import Path

from coevo.console import ProgressBar

__all__ = ["configure_check", "configure_replay"]


def configure_check(p: argparse.ArgumentParser) -> None:
    """``coevo check``'s arguments."""
    p.add_argument("run_dir", help="a finished run directory (coevo run, coevo cel or hand-started workers)")
    p.add_argument("--no-replay", action="store_true", help="skip re-running the GAs")
    p.set_defaults(func=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    from coevo.runs.check import check_run

    with ProgressBar("replay", unit="generations", quiet=not sys.stderr.isatty()) as bar:
        res = check_run(Path(args.run_dir), replay=not args.no_replay, progress=partial(_replayed, bar))
    for beh, facts in sorted((k, v) for k, v in res.facts.items() if isinstance(v, dict) and "published" in v):
        print(f"{beh}: {facts['generations']} generations, {facts['published']} versions published, "
              f"{facts['adoptions']} adoptions")
    ex = res.facts.get("execution")
    if ex:
        print(f"execution: {ex['generations']} generations of trials, {ex['policies_used']} rule sets used, "
              f"{ex['changes']} capability changes")
    if res.ok:
        print("complete" + (" (replay exact)" if res.facts.get("replayed") else ""))
        return 0
    for p in res.problems:
        print(f"PROBLEM: {p}")
    return 1


def configure_replay(p: argparse.ArgumentParser) -> None:
    """``coevo replay``'s arguments."""
    p.add_argument("run_dir", help="a finished run directory, re-run in this process from its adoption log")
    p.set_defaults(func=cmd_replay)


def cmd_replay(args: argparse.Namespace) -> int:
    from coevo.runs.replay import not_needed, replay

    ok = True
    with ProgressBar("replay", unit="generations", quiet=not sys.stderr.isatty()) as bar:
        results = replay(Path(args.run_dir), progress=partial(_replayed, bar))
    for r in results:
        ok &= r.reproduced
        verdict = "reproduced exactly" if r.reproduced else f"DIFFERS at generation {r.first_mismatch}: {r.detail}"
        print(f"{r.behaviour}: {r.generations} generations {verdict}")
    skipped = not_needed(Path(args.run_dir))
    if skipped:
        print(f"not read, so not vouched for: {', '.join(skipped)} (coevo check {args.run_dir} checks the whole run)")
    return 0 if ok else 1


def _replayed(bar: ProgressBar, behaviour: str, done: int, total: int) -> None:
    """A replay's progress on a terminal, a line per behaviour: it takes tens of seconds for a run of 50 generations."""
    bar.stage(f"replaying {behaviour}", done, total)
