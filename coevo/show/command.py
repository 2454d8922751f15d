"""``coevo show``: pictures, animations and rule tables of a robot's episodes (registered by :mod:`coevo.cli`).

Every input is checked before anything is played or written, and errors are
:class:`~coevo.errors.CoevoError` subclasses that ``coevo.cli.main`` prints as one
line with exit status 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

from coevo.config import build
from coevo.errors import ConfigError
from coevo.policy.text import read_rule_file
from coevo.show.draw import ANIMATION_FORMATS, FORMATS, check_out_path
from coevo.show.source import Robot, robot_from_default, robot_from_path
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["configure_show", "cmd_show", "DEFAULT_EPISODES", "MAX_EPISODES"]

DEFAULT_EPISODES = 3  # for a Tracking or Docking rule set alone
MAX_EPISODES = 1000  # one lane records (episodes x steps) states; beyond this a picture is unreadable anyway


def _robot(args: argparse.Namespace, world_over: dict[str, Any]) -> Robot:
    partners = {b: read_rule_file(Path(f), b) for b, f in ((Behaviour.TRACKING, args.tracking),
                                                          (Behaviour.DOCKING, args.docking)) if f}
    if args.source and args.default is not None:
        raise ConfigError(f"give a rule file or run directory ({args.source!r}) or --default, not both")
    if args.default is not None:
        if partners:
            raise ConfigError("--tracking/--docking are partners for an Executive; --default shows one behaviour")
        robot = robot_from_default(args.default, build(WorldConfig, world_over))
    elif args.source:
        robot = robot_from_path(Path(args.source), world=build(WorldConfig, world_over), partners=partners)
    else:
        raise ConfigError("nothing to show: give a rule file, a run directory, or --default tracking|docking")
    if world_over and args.source and Path(args.source).is_dir():
        robot = dataclasses.replace(robot, world=build(WorldConfig, {**robot.world.model_dump(), **world_over}))
    return robot


def _episodes(args: argparse.Namespace, robot: Robot) -> int | None:
    """Episodes to play in a row, or None for one epoch."""
    if args.episodes is not None:
        if args.epoch:
            raise ConfigError(f"give --episodes {args.episodes} or --epoch, not both")
        if not 1 <= args.episodes <= MAX_EPISODES:
            raise ConfigError(f"--episodes must be between 1 and {MAX_EPISODES}, got {args.episodes}")
        return int(args.episodes)
    return None if args.epoch or robot.combined else DEFAULT_EPISODES


def _out_path(args: argparse.Namespace, robot: Robot, episodes: int | None, animated: bool) -> Path:
    what = "epoch" if episodes is None else f"episodes{episodes}"
    suffix = ".gif" if animated else ".png"
    if args.out is not None:
        return Path(args.out)
    name = f"{robot.name}-{what}-seed{args.seed}{suffix}"
    if args.source and Path(args.source).is_dir():
        return Path(args.source) / f"show-{what}-seed{args.seed}{suffix}"
    if args.source:
        return Path(args.source).parent / name
    return Path(name)


def cmd_show(args: argparse.Namespace) -> int:
    from coevo.console import pairs
    from coevo.show import TASKS

    if args.task not in TASKS:
        raise ConfigError(f"--task {args.task!r}: unknown task (known: {', '.join(TASKS)})")
    if args.seed < 0:
        raise ConfigError(f"--seed must be 0 or more, got {args.seed}")
    if not 1 <= args.fps <= 60:
        raise ConfigError(f"--fps must be between 1 and 60, got {args.fps}")
    if args.out is not None and not args.out.strip():
        raise ConfigError(f"--out {args.out!r}: expected a file name (.png, or .gif/.mp4 with --animate)")
    robot = _robot(args, pairs(args.world, "world"))
    episodes = _episodes(args, robot)
    animated = args.animate or (args.out is not None and Path(args.out).suffix.lower() in ANIMATION_FORMATS)
    draw = not args.rules or args.out is not None or args.animate
    out = _out_path(args, robot, episodes, animated) if draw else None
    if out is not None:
        check_out_path(out, ANIMATION_FORMATS if animated else FORMATS)

    from coevo.show import animate, draw_png, play, scene_for

    played = play(robot, seed=args.seed, episodes=episodes)
    if args.rules:
        from coevo.show.rules_view import print_rules, trace_lines

        print_rules(played)
        if args.trace:
            print("\n".join(trace_lines(played)))
    if out is not None:
        scene = scene_for(played, args.task)
        if animated:
            frames = animate(scene, out, fps=args.fps)
            print(f"wrote {out} ({frames} frames of {scene.frames} steps, {played.episodes} episodes)")
        else:
            draw_png(scene, out, trace=args.trace)
            print(f"wrote {out} ({played.episodes} episodes)")
    sys.stdout.flush()
    return 0


def configure_show(p: argparse.ArgumentParser) -> None:
    """``coevo show``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    p.description = ("Play a robot from a seed and draw its episodes: the arena, walls and dock, the robot's\n"
                     "path coloured by the Executive's choice (Track/Dock), the Target's path, the tracking\n"
                     'range around the Target, where each episode began and how it ended (tracking, docked,\n'
                     'collided, ran dry, time up). A Tracking or Docking rule set alone is driven by the\n'
                     'trivial Executive that always picks it. Bad input (a missing or unreadable file, a run\n'
                     "directory without policies, a bad option) prints one line 'ErrorType: message' and exits\n"
                     'with status 2, writing nothing.')
    p.epilog = ("examples:\n"
                "  coevo show --default tracking                 # default-tracking-episodes3-seed0.png\n"
                "  coevo show runs/ID                            # a coevo run's combined robot, one epoch\n"
                "  coevo show runs/learn-docking-... --episodes 5 --trace\n"
                "  coevo show best.rules --rules                 # rules by strength, with fire counts\n"
                "  coevo show runs/ID --animate --out epoch.gif\n"
                "  coevo show exec.rules --tracking t.rules --docking d.rules --epoch")
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.add_argument("source", nargs="?", metavar="RULES_OR_RUN_DIR",
                   help="a rule file, a 'coevo run' directory (its workers' final best.rules: the combined robot) "
                        "or a 'coevo learn' directory (its best.rules)")
    p.add_argument("--default", metavar="tracking|docking", help="show a behaviour's shipped default rules instead")
    p.add_argument("--tracking", metavar="FILE", help="Tracking rule file: a partner for an Executive rule file")
    p.add_argument("--docking", metavar="FILE", help="Docking rule file: a partner for an Executive rule file")
    p.add_argument("--episodes", type=int, metavar="N",
                   help=f"play N episodes in a row, starting a new epoch when one ends (default {DEFAULT_EPISODES} "
                        "for a Tracking or Docking rule set)")
    p.add_argument("--epoch", action="store_true", help="play one epoch (default for a combined robot)")
    p.add_argument("--seed", type=int, default=0, help="where the robot and Target start, the Target's walk (default 0)")
    p.add_argument("--task", default="tracking-fuel", help="the task to draw (default tracking-fuel, the only one so far)")
    p.add_argument("--out", metavar="FILE",
                   help="picture to write: .png, or .gif/.mp4 for an animation (MP4 needs ffmpeg); default: next to "
                        "the rule file, inside the run directory, or here, named after the robot, episodes and seed")
    p.add_argument("--animate", action="store_true", help="write an animated GIF (or MP4 with --out FILE.mp4)")
    p.add_argument("--fps", type=int, default=12, help="animation frames per second (default 12; at most 150 frames)")
    p.add_argument("--trace", action="store_true",
                   help="show which rule fired at each step: a panel under the picture, and per episode with --rules")
    p.add_argument("--rules", action="store_true",
                   help="print the rule sets sorted by strength with how often each rule fired (a table on a "
                        "terminal, plain lines otherwise); draws nothing unless --out or --animate is given too")
    p.add_argument("--world", action="append", metavar="NAME=VALUE", help="world setting, e.g. target_speed=3 (repeatable)")
    p.set_defaults(func=cmd_show)
