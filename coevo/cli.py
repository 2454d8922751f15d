"""The ``coevo`` command line: it only gathers the commands, each declared beside what it runs.

A command is a ``configure_NAME(parser)`` (its arguments, setting ``func``) in the module that
:data:`COMMANDS` names.  Only the command being run is configured (its module imported), so
``coevo --help`` and ``coevo status --help`` answer at once and a worker starts without loading
the plotting and statistics libraries.  Every command's :class:`~coevo.errors.CoevoError` is
printed as one line ``ErrorType: message`` with exit status 2; a bad flag or value is one such
line too; a bug still shows its traceback.  Logging handlers are configured here and nowhere else.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys

__all__ = ["main", "build_parser", "COMMANDS"]

EXIT_ERROR = 2

#: name -> (the module that declares and runs it, what it does).  The order is ``coevo --help``'s.
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("coevo.runs.command", "broker + one worker per behaviour on this machine, with a live status"),
    "learn": ("coevo.runs.learn_command", "one behaviour learns offline (no network)"),
    "compare": ("coevo.experiments.compare.command",
                "many real runs per regime: Table 1, learning curves, rank tests, verdict"),
    "study": ("coevo.experiments.study.command",
              "factors × seeds, each cell a regime comparison: Table 1 with intervals, effect plots, tests, verdict"),
    "show": ("coevo.show.command", "draw a robot's episodes (PNG, GIF) and print its rules with how often they fired"),
    "status": ("coevo.runs.command", "follow a run's workers"),
    "dashboard": ("coevo.dashboard.command",
                  "a read-only web page of the runs on the bus, or of a run or comparison directory: workers, curves, "
                  "Table 1 so far"),
    "check": ("coevo.runs.check_command",
              "is a finished run directory complete? (every generation, every version stored, replay)"),
    "replay": ("coevo.runs.check_command", "re-run a finished run in one process from its adoption log"),
    "worker": ("coevo.runs.command", "one behaviour's GA as its own process on the bus"),
    "broker": ("coevo.broker.command", "the Zenoh router workers meet at, plus the policy store"),
    "router": ("coevo.broker.command",
               "a plain Zenoh router, no store: another site's meeting point (--connect to the broker)"),
    "keygen": ("coevo.runs.command", "make a run's secret key file (mode 0600), for a run spread over hosts by hand"),
    "chaos": ("coevo.runs.command", "a whole run while random processes are killed and restarted; then check it"),
    "cel": ("coevo.cel_service.command",
            "Appendix B: a live CEL run (broker, learning module, execution module) with a failure schedule"),
    "execution": ("coevo.cel_service.command",
                  "a CEL run's execution module (the robot, with its monitor) as its own process"),
    "seeds": ("coevo.experiments.seeds.command",
              "Tracking and Docking learned over seeds, against the learning targets, with a report"),
    "cel-experiment": ("coevo.experiments.cel.command",
                       "Appendix B: Figure 3 over live coevo cel runs (default 10), beside the report's numbers"),
    "evolvability": ("coevo.experiments.evolvability.command",
                     "Appendix D: FM/GM/FH/GH mutation models on dynamic landscapes, with a report"),
    "earl": ("coevo.experiments.earl.command",
             "Appendix C: the EA-vs-TD grid world and hidden-state experiments, with a report"),
    "td-baseline": ("coevo.experiments.earl.td.command",
                    "Appendix C: Q-learning against the GA on the robot tasks, at equal experience"),
    "dynamics": ("coevo.experiments.dynamics.command",
                 "a finished run's CIAO matrices and master tournaments: every version against every partner version"),
    "plugins": ("coevo.runs.plugins_command", "the tasks and kinds of learner installed, and the package of each"),
    "bench": ("coevo.tasks.fuel.bench_command", "robot-steps/s of the batched world vs a plain one-episode pymunk loop"),
}


class _Parser(argparse.ArgumentParser):
    """argparse, but a bad flag or value is one line ``ConfigError: ...`` naming it (status 2), like every other
    bad input, instead of the usage followed by the error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_ERROR, f"ConfigError: {self.prog}: {message} (see {self.prog} --help)\n")

    def _get_value(self, action: argparse.Action, arg_string: str) -> object:
        """One rule for every flag and argument of every command (the subcommands' parsers are this class too): an
        empty or blank value is refused, never read as "the default" (``--resume ''``) or as a name (``--out ' '``)."""
        blank = isinstance(arg_string, str) and not arg_string.strip()
        if blank and not isinstance(action, argparse._SubParsersAction):  # a command's values: its own parser's
            name = "/".join(action.option_strings) or action.metavar or action.dest
            self.error(f"{name} {arg_string!r} is {'empty' if not arg_string else 'blank'}: give a value")
        return super()._get_value(action, arg_string)


def configure(name: str, p: argparse.ArgumentParser) -> None:
    """Give ``p`` command ``name``'s arguments, from the module that declares it."""
    module = importlib.import_module(COMMANDS[name][0])
    getattr(module, "configure_" + name.replace("-", "_"))(p)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The whole command line; with ``only``, every command listed but only that one configured."""
    parser = _Parser(prog="coevo", description="Co-evolve robot behaviours with SAMUEL-style rule GAs.")
    parser.add_argument("--log-level", default="WARNING", choices=["DEBUG", "INFO", "WARNING", "ERROR"],
                        help="what the command logs on stderr (default WARNING)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (_, what) in COMMANDS.items():
        p = sub.add_parser(name, help=what, description=what)
        if only is None or only == name:
            configure(name, p)
    return parser


def _command_in(argv: list[str]) -> str | None:
    """The command named in ``argv`` (skipping ``--log-level``'s value), or None."""
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--log-level":
            skip = True
        elif not arg.startswith("-"):
            return arg if arg in COMMANDS else None
    return None


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except BrokenPipeError:  # its reader went away (coevo run --ga help | head): no one is left to tell
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nor at the interpreter's exit flush
        return 141  # as a shell says a pipe's writer ended: 128 + SIGPIPE


def _main(argv: list[str] | None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = _command_in(argv)
    parser = build_parser(only=command or "")
    args, extra = parser.parse_known_args(argv)
    if extra:  # a command that takes its task's own flags (coevo.console.take_task_flags) reads them once it knows it
        if getattr(args, "task_flags", None) is None:
            parser.error(f"unrecognized arguments: {' '.join(extra)}")
        args.task_flags = extra
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    from coevo.errors import CoevoError

    try:
        return int(args.func(args))
    except CoevoError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
