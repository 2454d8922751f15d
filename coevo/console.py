"""What the commands share on the terminal: one progress display, the argument types, the settings flags.

Progress goes to stderr (stdout is for results a script may read); ``quiet`` turns it
off.  Every long command shows the same bar: a label, the bar, done/total, what is
happening, the time spent and the time left.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any

from coevo.config import Bounded, GAConfig, pairs, settings_listing
from coevo.errors import ConfigError

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

__all__ = ["Bounded", "Lead", "max_lead_of", "ProgressBar", "seed_arg", "count_arg", "positive_float_arg", "task_arg", "pairs",
           "accept_task_flags", "task_flags",
           "given_settings", "ga_settings", "world_settings", "add_settings", "add_max_lead", "max_lead_arg"]


class ProgressBar:
    """A progress display with one or more stages (rich), or nothing when ``quiet``."""

    def __init__(self, label: str, *, total: int | None = None, unit: str = "", quiet: bool = False) -> None:
        self.label, self.unit, self.quiet = label, unit, quiet
        self._first_total = total
        self._bar: Progress | None = None
        self._tasks: dict[str, TaskID] = {}

    def __enter__(self) -> ProgressBar:
        if not self.quiet:
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            done = "{task.completed}/{task.total}" + (f" {self.unit}" if self.unit else "")
            self._bar = Progress(TextColumn("[bold]{task.description}[/]"), BarColumn(), TextColumn(done),
                                 TextColumn("{task.fields[info]}"), TimeElapsedColumn(), TextColumn("left"),
                                 TimeRemainingColumn(), console=Console(file=sys.stderr))
            self._bar.start()
            if self._first_total is not None:
                self.stage(self.label, 0, self._first_total)
        return self

    def stage(self, name: str, done: int, total: int, info: str = "") -> None:
        """Show stage ``name`` at ``done`` of ``total`` (a new stage gets its own line)."""
        if self._bar is None:
            return
        if name not in self._tasks:
            self._tasks[name] = self._bar.add_task(name, total=total, info="")
        self._bar.update(self._tasks[name], completed=done, total=total, info=info)

    def update(self, done: int, total: int | None = None, info: str = "") -> None:
        """The main stage (the label's) at ``done`` of ``total`` (unchanged if None)."""
        if self._bar is None:
            return
        task = self._tasks.get(self.label)
        current = self._bar.tasks[self._bar.task_ids.index(task)].total if task is not None else None
        self.stage(self.label, done, int(total if total is not None else (current or 1)), info)

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if self._bar is not None:
            if exc_type is not None:  # an error says it in one line: no half-drawn bar left above it
                self._bar.live.transient = True
            self._bar.stop()
            self._bar = None


def count_arg(minimum: int, maximum: int) -> Bounded:
    """An argument type: a whole number in [minimum, maximum] (the bound is always stated)."""
    return Bounded(minimum, maximum)


def positive_float_arg(*, maximum: float, allow_zero: bool = False) -> Bounded:
    """An argument type: a finite number above 0 (or at least 0), at most ``maximum``."""
    return Bounded(0, maximum, whole=False, above=not allow_zero)


#: A seed: a whole number from 0 to 2**63 - 1 (numpy's generators refuse negative seeds).
seed_arg = Bounded(0, 2**63 - 1, what="seed")


# ---------------------------------------------------------------- run settings from flags
def task_arg(value: str) -> str:
    """A task's name, as installed or registered (``coevo plugins`` lists them); nothing is imported to check it."""
    from coevo.tasks import task_names

    if value not in task_names():
        raise argparse.ArgumentTypeError(f"unknown task {value!r} (installed: {', '.join(task_names())})")
    return value


def accept_task_flags(p: argparse.ArgumentParser) -> None:
    """Let a command take its task's own flags, which no parser knows before the task is: a partner's rule file as
    ``--BEHAVIOUR FILE`` and a world setting by the task's name for it (``Task.flags``); read by
    :func:`task_flags` once the command knows its task."""
    p.set_defaults(task_flags=[])


def task_flags(args: argparse.Namespace, task: Any = None) -> tuple[dict[str, str], dict[str, Any]]:
    """The task's own flags given (``--NAME VALUE`` or ``--NAME=VALUE``): (partner behaviour -> rule file, world
    setting -> value).  A flag the task does not know is one usage line naming it and what the task takes.  With
    no task (not known yet), a flag naming any behaviour is a partner's rule file and there are no world flags."""
    from coevo.policy.schema import known as known_behaviour

    raw: list[str] = list(getattr(args, "task_flags", None) or [])
    partners: dict[str, str] = {}
    world: dict[str, Any] = {}
    own = [] if task is None else [f"--{b}" for b in task.behaviours] + [f"--{f}" for f in task.flags]
    while raw:
        item = raw.pop(0)
        name, eq, value = item.partition("=")
        ok = name in own if task is not None else name.startswith("--") and known_behaviour(name[2:])
        if not name.startswith("--") or not ok:
            where = f", nor of task {task.name!r}" + (f" (its own: {', '.join(own)})" if own else "") if task else ""
            raise ConfigError(f"{item!r}: not a flag of this command{where} (see --help)")
        if not eq:
            if not raw or raw[0].startswith("--"):
                raise ConfigError(f"{name} needs a value")
            value = raw.pop(0)
        if not value.strip():
            raise ConfigError(f"{name} {value!r} is {'empty' if not value else 'blank'}: give a value")
        key = name[2:]
        if task is not None and key in task.flags:
            world[task.flags[key]] = value
        else:
            partners[key] = value
    return partners, world


def given_settings(args: argparse.Namespace, task: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The world and GA values the flags give (``--world``, ``--ga``, ``--generations``, ``--population``,
    ``--episodes``) for ``task``, unchecked; a ``--ga`` value that names a setting of the task's world is one
    (``--ga docking_sensors=polar`` of the fuel task: :func:`coevo.tasks.split_settings`)."""
    from coevo.tasks import get_task, split_settings

    for which, model in (("ga", lambda: GAConfig), ("world", lambda: get_task(task).world_settings)):
        if "help" in (getattr(args, which, None) or []):  # --ga help, --world help: the names, then nothing else
            print(settings_listing(model(), which))
            raise SystemExit(0)
    over = pairs(args.ga, "ga")
    for name in ("generations", "population", "episodes"):
        flag = getattr(args, name, None)
        if flag is None:
            continue
        if name in over and over[name] != flag:  # one setting given two ways: neither silently wins
            given = [i.partition("=")[2] for i in args.ga or [] if i.partition("=")[0].strip() == name][-1]
            raise ConfigError(f"--{name} {flag} and --ga {name}={given} disagree: give {name} once")
        over[name] = flag
    the_task = get_task(task)
    world = pairs(getattr(args, "world", None), "world")
    for name, value in task_flags(args, the_task)[1].items():
        if name in world:
            raise ConfigError(f"{name} given twice: by a flag of task {task!r} and by --world {name}=...: give it once")
        world[name] = value
    return split_settings(the_task, world, over)


def ga_settings(args: argparse.Namespace, task: str) -> GAConfig:
    """The GA settings given for ``task``, checked (:func:`given_settings`)."""
    from coevo.config import build

    return build(GAConfig, given_settings(args, task)[1])


def world_settings(args: argparse.Namespace, task: str) -> dict[str, Any]:
    """The world settings given, checked against the task's model (stored in full by whoever keeps them)."""
    from coevo.config import build
    from coevo.tasks import get_task

    return build(get_task(task).world_settings, given_settings(args, task)[0]).model_dump(mode="json")


#: What ``--initial`` means in each command that offers it, for any task (a behaviour its task ships no rules for,
#: the fuel task's Executive for one, always starts random).
INITIAL = ("how the behaviours start: the rule sets their task ships (default; a behaviour it ships none for starts "
           "random) or random rule sets (the same as --ga initial=...)")


def add_settings(p: argparse.ArgumentParser, *, generations: int = 50, initial: str | None = INITIAL) -> None:
    """The GA and world settings flags, declared once for every command that takes them: ``generations`` is the
    command's own default (shown in its help); ``initial`` is what ``--initial`` means there (None: not offered,
    the command's task decides)."""
    # Bounded by GAConfig's own ranges (one place), refused at parse time.
    p.add_argument("--generations", type=Bounded.setting(GAConfig, "generations"), help=f"generations (default {generations})")
    p.add_argument("--population", type=Bounded.setting(GAConfig, "population"), help="population size (default 50)")
    p.add_argument("--episodes", type=Bounded.setting(GAConfig, "episodes"),
                   help="evaluation episodes per individual (default 90)")
    p.add_argument("--world", action="append", metavar="NAME=VALUE", help="world setting, e.g. target_speed=3 (repeatable; --world help lists them)")
    p.add_argument("--ga", action="append", metavar="NAME=VALUE", help="GA setting, e.g. mutation_rate=0.05 (repeatable; --ga help lists them)")
    if initial is not None:
        p.add_argument("--initial", dest="ga", action="append", type=lambda v: f"initial={v}", metavar="default|random",
                       help=initial)
    p.add_argument("--mutation-model", dest="ga", action="append", type=lambda v: f"mutation_model={v}", metavar="fm|gm|fh|gh",
                   help="mutation model (default fm; the same as --ga mutation_model=...; parameters: docs/evolvability.md)")


@dataclass(frozen=True)
class Lead:
    """A ``--max-lead`` that was given: ``value`` generations, or None for ``off`` (so "off" and "not given", which
    falls back to the command's default, stay apart)."""

    value: int | None


@dataclass(frozen=True)
class _LeadArg(Bounded):
    def __call__(self, text: str) -> Lead:
        v = super().__call__(text)
        return v if isinstance(v, Lead) else Lead(v)


#: ``--max-lead N|off``: a lead beyond the most generations a GA runs (100,000) would mean nothing.
max_lead_arg = _LeadArg(0, 100_000, words=(("off", Lead(None)), ("none", Lead(None))), what="max lead")


def max_lead_of(given: Lead | None, default: int | None) -> int | None:
    """The lead a command runs with: the flag's (None: off), else ``default``."""
    return default if given is None else given.value


def add_max_lead(p: argparse.ArgumentParser, *, default: int | None = 1) -> None:
    """``--max-lead N|off``; not given, it is None, and the command uses ``max_lead_of(args.max_lead, default)``."""
    p.add_argument("--max-lead", type=max_lead_arg, metavar="N|off",
                   help="pacing: start a generation only when every partner is at most N generations behind "
                        f"(default {'off' if default is None else default}; off = unpaced)")
