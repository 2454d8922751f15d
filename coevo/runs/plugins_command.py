"""``coevo plugins``: the tasks and kinds of learner installed, each with the package it comes from.

Tasks and kinds are plugins found by name (:mod:`coevo.plugins`): coevo's own and any other package's are listed
alike.  Each is imported to list it, so one that cannot be used shows its one-line reason here (and the command
ends with status 1) while the others list as usual.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

__all__ = ["configure_plugins"]


def configure_plugins(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the listing as JSON (one object: tasks, kinds)")
    p.set_defaults(func=cmd_plugins)


def _rows() -> dict[str, list[dict[str, Any]]]:
    from coevo.rundir.kinds import KINDS
    from coevo.tasks import TASKS

    tasks = []
    for name, package, target, problem in TASKS.listing():
        row: dict[str, Any] = {"name": name, "package": package, "target": target, "problem": problem}
        if problem is None:
            t = TASKS.get(name)
            row |= {"behaviours": list(t.behaviours), "regimes": list(t.regimes)}
        tasks.append(row)
    kinds = []
    for name, package, target, problem in KINDS.listing():
        row = {"name": name, "package": package, "target": target, "problem": problem}
        if problem is None:
            row["label"] = KINDS.get(name).label
        kinds.append(row)
    return {"tasks": tasks, "kinds": kinds}


def cmd_plugins(args: argparse.Namespace) -> int:
    from coevo.plugins import KINDS_GROUP, TASKS_GROUP

    rows = _rows()
    bad = [r for group in rows.values() for r in group if r["problem"] is not None]
    if args.json:
        print(json.dumps(rows, indent=2))
    else:
        for title, group, key in (("tasks", TASKS_GROUP, "tasks"), ("kinds of learner", KINDS_GROUP, "kinds")):
            print(f"{title} (entry points {group!r}):")
            width = max((len(r["name"]) for r in rows[key]), default=4)
            pw = max((len(r["package"]) for r in rows[key]), default=7)
            tw = max((len(r["target"]) for r in rows[key]), default=6)
            for r in rows[key]:
                if r["problem"] is not None:
                    what = f"UNUSABLE: {r['problem']}"
                elif key == "tasks":
                    what = f"behaviours {', '.join(r['behaviours'])}; regimes {', '.join(r['regimes'])}"
                else:
                    what = r["label"]
                print(f"  {r['name']:<{width}}  {r['package']:<{pw}}  {r['target']:<{tw}}  {what}")
    if bad:
        print(f"{len(bad)} plugin{'s' if len(bad) > 1 else ''} cannot be used (see above); the others work",
              file=sys.stderr)
    return 1 if bad else 0
