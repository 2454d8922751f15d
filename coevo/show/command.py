"""``coevo show``: pictures, animations and rule tables of a robot's episodes, for any registered task.

:func:`configure_show` adds the command's arguments to a parser (``coevo.cli`` builds one per
sub-command).  This module imports nothing heavy at its top: ``coevo --help`` builds every
sub-command's parser and must answer at once; numpy, matplotlib and the tasks are imported when
the command runs (and the task names when ``--task`` is checked or its help shown).

Every input is checked before anything is played or written, and errors are
:class:`~coevo.errors.CoevoError` subclasses that ``coevo.cli.main`` prints as one
line with exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from coevo.console import count_arg, seed_arg
from coevo.errors import ConfigError

__all__ = ["configure_show", "cmd_show", "DEFAULT_EPISODES", "MAX_EPISODES"]

DEFAULT_EPISODES = 3  # for a Tracking or Docking rule set alone (the task says: TaskDisplay.show_episodes)
MAX_EPISODES = 1000  # one lane records (episodes x steps) states; beyond this a picture is unreadable anyway


class _TaskNames:
    """``--task``'s choices: the installed tasks (coevo.tasks.task_names), looked up only when the help lists them.

    argparse lets every name in: :func:`cmd_show` checks it (``find_task``) and raises a ConfigError, so that
    a bad name is the command's one-line error (and ``coevo.cli.main`` returns 2) like every other bad input.
    """

    def __contains__(self, name: object) -> bool:
        return True

    def __iter__(self) -> Iterator[str]:
        from coevo.tasks import task_names

        return iter(task_names())


def _shown(args: argparse.Namespace, world_over: dict[str, Any]) -> Any:
    from coevo.console import task_flags
    from coevo.policy.text import read_rule_file
    from coevo.show.source import find_task, from_default, from_path

    wanted = find_task(args.task) if args.task is not None else None
    partners = {b: read_rule_file(Path(f), b) for b, f in task_flags(args)[0].items()}
    if args.source and args.default is not None:
        raise ConfigError(f"give a rule file or run directory ({args.source!r}) or --default, not both")
    if args.default is not None:
        if partners:
            raise ConfigError(f"{', '.join('--' + b for b in partners)}: partners' rule files are for a rule file that "
                              "learns with them; --default shows one behaviour")
        return from_default(args.default, world_over, wanted=wanted)
    if args.source:
        return from_path(Path(args.source), world_over=world_over, partners=partners, wanted=wanted)
    raise ConfigError("nothing to show: give a rule file, a run directory, or --default BEHAVIOUR (e.g. tracking)")


def _episodes(args: argparse.Namespace, default: int | None) -> int | None:
    """Episodes to play in a row, or None for one epoch."""
    if args.episodes is not None:
        if args.epoch:
            raise ConfigError(f"give --episodes {args.episodes} or --epoch, not both")
        return int(args.episodes)
    return None if args.epoch else default


def _out_path(args: argparse.Namespace, name: str, episodes: int | None, animated: bool, seed: int) -> Path:
    what = "epoch" if episodes is None else f"episodes{episodes}"
    suffix = ".gif" if animated else ".png"
    if args.out is not None:
        return Path(args.out)
    file = f"{name}-{what}-seed{seed}{suffix}"
    if args.source and Path(args.source).is_dir():
        return Path(args.source) / f"show-{what}-seed{seed}{suffix}"
    if args.source:
        return Path(args.source).parent / file
    return Path(file)


def cmd_show(args: argparse.Namespace) -> int:
    from coevo.console import pairs
    from coevo.scene import ANIMATION_FORMATS, FORMATS, animate, check_out_path, draw_png
    from coevo.show.source import check_world, find_task

    if args.task is not None:
        find_task(args.task)
    shown = _shown(args, check_world(pairs(args.world, "world")))
    display, robot = shown.display, shown.robot
    episodes = _episodes(args, display.show_episodes(robot))
    animated = args.animate or (args.out is not None and Path(args.out).suffix.lower() in ANIMATION_FORMATS)
    draw = not args.rules or args.out is not None or args.animate
    if args.out is not None:  # a bad --out is said before anything is played
        check_out_path(Path(args.out), ANIMATION_FORMATS if animated else FORMATS)
    seed, played = args.seed or 0, None
    if args.seed is None and episodes is None:  # one epoch of a whole robot: a typical one, if its task scores epochs
        seed, played, said = _typical(display, robot)
        if said:
            print(said)
    if played is None:
        played = display.show_play(robot, seed=seed, episodes=episodes)
    out = _out_path(args, robot.name, episodes, animated, seed) if draw else None
    if out is not None:
        check_out_path(out, ANIMATION_FORMATS if animated else FORMATS)
    if args.rules:
        from coevo.show.rules_view import print_tables

        print_tables(display.show_rules(played))
        if args.trace:
            print("\n".join(display.show_trace(played)))
    if out is not None:
        scene = display.show_scene(played)
        if animated:
            frames = animate(scene, out, fps=args.fps)
            print(f"wrote {out} ({frames} frames of {scene.frames} steps, {played.episodes} episodes)")
        else:
            draw_png(scene, out, trace=args.trace)
            print(f"wrote {out} ({played.episodes} episodes)")
    sys.stdout.flush()
    return 0


#: Epochs ``coevo show`` plays to pick a typical one to draw (odd: the median is one of them).
SAMPLES = 9


def _typical(display: Any, robot: Any) -> tuple[int, Any, str]:
    """(seed, its play, a line saying which it is and that it is one sample): the epoch of median score among those
    of seeds 0..SAMPLES-1 (ties: the lower seed); (0, seed 0's play, '') when the task scores no epoch."""
    first = display.show_play(robot, seed=0, episodes=None)
    if display.show_score(first) is None:
        return 0, first, ""
    plays = [first, *(display.show_play(robot, seed=s, episodes=None) for s in range(1, SAMPLES))]
    scores = [display.show_score(p) for p in plays]
    ranked = sorted((score[1], s) for s, score in enumerate(scores))
    value, seed = ranked[SAMPLES // 2]
    return seed, plays[seed], (f"drawing seed {seed}: the median of {SAMPLES} epochs (seeds 0-{SAMPLES - 1}) by "
                               f"{scores[0][0]}, {value:.3f} (they range {ranked[0][0]:.3f} to {ranked[-1][0]:.3f}); "
                               "one sample of the robot: --seed N draws another")


DESCRIPTION = (
    "Play a robot from a seed and draw its episodes as its task draws them (what each task draws:\n"
    "docs/show.md; coevo plugins lists the installed tasks and their behaviours): the world, the robot's\n"
    "path, where each episode began and how it ended. A rule set of a behaviour that learns with partners\n"
    "is played with the partners given (--BEHAVIOUR FILE) or those of its run directory; one that learns\n"
    "alone, with its task's trivial stand-ins. The task is the one the run directory (run.json,\n"
    "config.json) or rule file names. Bad input (a missing or unreadable file, a run directory without\n"
    "policies or of another task or version, a bad option) prints one line 'ErrorType: message' and exits\n"
    "with status 2, writing nothing.")
EPILOG = (
    "examples:\n"
    "  coevo show --default tracking                 # default-tracking-episodes3-seed0.png\n"
    "  coevo show runs/ID                            # a coevo run's combined robot, its median epoch\n"
    "  coevo show runs/learn-docking-... --episodes 5 --trace\n"
    "  coevo show runs/learn-door-...                # a door trial\n"
    "  coevo show best.rules --rules                 # rules by strength, with fire counts\n"
    "  coevo show runs/ID --animate --out epoch.gif\n"
    "  coevo show exec.rules --tracking t.rules --docking d.rules --epoch\n"
    "\n"
    "a partner's rule file is --BEHAVIOUR FILE, for any behaviour of the rule file's task (e.g. the fuel\n"
    "task's Executive's partners: --tracking and --docking).")


def configure_show(p: argparse.ArgumentParser) -> None:
    """Add ``coevo show``'s arguments to ``p`` and make :func:`cmd_show` its function."""
    p.description = DESCRIPTION
    p.epilog = EPILOG
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.add_argument("source", nargs="?", metavar="RULES_OR_RUN_DIR",
                   help="a rule file, a 'coevo run' or 'coevo cel' directory (its workers' final best.rules: the "
                        "whole robot) or a 'coevo learn' directory (its best.rules)")
    p.add_argument("--default", metavar="BEHAVIOUR",
                   help="show a behaviour's shipped default rules instead (any behaviour whose task ships them, e.g. "
                        "tracking; coevo plugins lists the behaviours)")
    p.add_argument("--episodes", type=count_arg(1, MAX_EPISODES), metavar="N",
                   help=f"play N episodes (or trials, as the task calls them) in a row, starting a new epoch when one "
                        f"ends (default: the task's; {DEFAULT_EPISODES} for a rule set of a behaviour that learns "
                        "alone)")
    p.add_argument("--epoch", action="store_true", help="play one epoch (default for a whole robot of a task that scores epochs)")
    p.add_argument("--seed", type=seed_arg,
                   help="where the robot and Target start, the Target's walk (default: for one epoch of a whole "
                        "robot whose task scores epochs, the median of 9 epochs by that score, its seed said; else 0)")
    p.add_argument("--task", default=None, choices=_TaskNames(), metavar="TASK",
                   help="the task to draw, one of %(choices)s (default: the one the run directory, rule file or "
                        "behaviour names; another is an error)")
    p.add_argument("--out", metavar="FILE",
                   help="picture to write: .png, or .gif/.mp4 for an animation (MP4 needs ffmpeg); default: next to "
                        "the rule file, inside the run directory, or here, named after the robot, episodes and seed")
    p.add_argument("--animate", action="store_true", help="write an animated GIF (or MP4 with --out FILE.mp4)")
    p.add_argument("--fps", type=count_arg(1, 60), default=12, help="animation frames per second (default 12; at most 150 frames)")
    p.add_argument("--trace", action="store_true",
                   help="show which rule fired at each step: a panel under the picture, and per episode with --rules")
    p.add_argument("--rules", action="store_true",
                   help="print the rule sets sorted by strength with how often each rule fired (a table on a "
                        "terminal, plain lines otherwise); draws nothing unless --out or --animate is given too")
    p.add_argument("--world", action="append", metavar="NAME=VALUE",
                   help="world setting of the robot's task, e.g. target_speed=3 (repeatable)")
    p.set_defaults(func=cmd_show, task_flags=[])  # --BEHAVIOUR FILE: a partner's rule file (coevo.console.task_flags)
