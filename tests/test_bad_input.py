"""Bad input: every flag of every command, with hostile values, ends in an exit status, never a traceback.

The flags are read from :func:`coevo.cli.build_parser`, so a new flag is tried without
touching this file.  Each command runs in this process through :func:`coevo.cli.main`
with a base command line that stops quickly: tiny settings, an unreachable router
(``--connect-timeout 0``), a listen address this host does not have, and, for the
commands that would start processes or long experiments, the function doing that work
replaced by one that raises (everything the flags are read and checked by happens before
it).  An alarm turns a command that would still run into Ctrl-C (status 130).

For every value: the exit status is 0, 1, 2 or 130 and nothing escapes ``main``.  For a
value that is clearly bad for a number (nan, inf, 1e308, empty) the status is 2 and stderr
is one line ``Type: message`` naming the value.
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import importlib
import io
import itertools
import re
import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from coevo.cli import build_parser, main
from coevo.config import Bounded
from coevo.errors import CoevoError
from coevo.rundir.settings import RunSettings

NUMBERS = ["nan", "inf", "-1", "0", "1e308", ""]
CLEARLY_BAD = {"nan", "inf", "1e308", ""}  # for a flag that takes a number
NO_ROUTER = ["--connect", "tcp/127.0.0.1:9", "--connect-timeout", "0"]
NO_LISTEN = ["--listen", "tcp/192.0.2.1:7447"]  # TEST-NET-1: not an address of this host, so binding fails at once
TINY = ["--generations", "1", "--population", "2", "--episodes", "1", "--ga", "best_episodes=1"]
# A command of the sweeps is stopped (KeyboardInterrupt, status 130) after ALARM_S seconds of CPU time, which a busy
# machine does not stretch (a wall-clock alarm of 5 s stopped a tiny coevo learn at load 10), or after ALARM_WALL_S
# seconds of wall time, for one that waits instead of spinning.
ALARM_S = 5.0
ALARM_WALL_S = 60.0
_count = itertools.count()


class Reached(CoevoError):
    """Raised in place of a command's long work: every flag was read and checked before it."""


@pytest.fixture
def places(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, Path]:
    """Hostile places: a file where a directory is expected, a directory where a file is, broken JSON files."""
    monkeypatch.chdir(tmp_path)  # relative names ('nan', '-1') land here
    p = {"file": tmp_path / "a-file", "dir": tmp_path / "a-dir", "broken_json": tmp_path / "broken.json",
         "full": tmp_path / "full"}
    p["file"].write_text("not what you expected\n")
    p["dir"].mkdir()
    p["broken_json"].write_text('{"run": "x", ')
    p["full"].mkdir()
    (p["full"] / "x").write_text("x")
    for what in ("broken-run", "broken-worker"):  # run directories with a broken run.json / worker.json
        d = tmp_path / what
        (d / "workers" / "tracking").mkdir(parents=True)
        (d / "run.json").write_text('{"run": ' if what == "broken-run" else '{"run": "broken-worker", "regime": "mutual"}')
        (d / "workers" / "tracking" / "worker.json").write_text("[1, 2" if what == "broken-worker" else "{}")
        p[what] = d
    cel = tmp_path / "cel-run"  # a CEL run's run.json, for coevo execution
    cel.mkdir()
    RunSettings.make(run="cel-run", task="door", regime="independent", cel={}).save(cel / "run.json")
    p["cel-run"] = cel
    for mod, name in (("coevo.runs.local", "run_local"), ("coevo.runs.chaos", "run_chaos"),
                      ("coevo.experiments.compare.experiment", "run_all"), ("coevo.experiments.earl.experiment", "run_grid"),
                      ("coevo.experiments.earl.td.runs", "run_task"), ("coevo.replicates.runner", "run_replicates")):
        _stand_in(monkeypatch, mod, name)
    return p


def _stand_in(monkeypatch: pytest.MonkeyPatch, mod: str, name: str) -> None:
    """``mod.name`` replaced by :func:`_reached`'s stand-in, and so is every copy a loaded coevo module took with
    ``from mod import name``: another test module's imports (test_study's, test_evolvability's) load
    ``coevo.experiments.study.experiment`` before this fixture runs, and that module's own ``run_replicates`` then
    ran real studies in the sweep until the CPU alarm stopped them (26 CPU-s instead of 1)."""
    real = getattr(importlib.import_module(mod), name)
    stand_in = _reached(name)
    for module in [m for n, m in sys.modules.items() if n == "coevo" or n.startswith("coevo.")]:
        if getattr(module, name, None) is real:
            monkeypatch.setattr(module, name, stand_in)


def _reached(name: str):
    def stand_in(*args: object, **kwargs: object) -> None:
        raise Reached(f"{name} would start here")
    return stand_in


def _base(command: str, flag: str, places: dict[str, Path]) -> list[str]:
    """A command line for ``command`` that stops quickly, leaving ``flag`` to the value under test."""
    n = next(_count)
    fresh = f"fresh-{n}"
    full = str(places["full"])
    bases: dict[str, list[str]] = {
        "learn": ["--behaviour", "executive" if flag in ("--history", "--rate", "--tracking", "--docking") else "tracking",
                  *TINY, "--measure-epochs", "1", "--quiet",
                  "--out", fresh if flag == "--out" else full],
        "bench": ["--lanes", "1", "--repeats", "1", "--baseline-seconds", "0.01", "--rules", "1"],
        "broker": [*NO_LISTEN, "--data-dir", fresh],
        "router": [*NO_LISTEN],
        "worker": ["--behaviour", "tracking", *NO_ROUTER, "--out", fresh]
        + ([] if flag == "--settings" else ["--run", "x", "--regime", "independent", *TINY]),
        "run": ([] if flag in ("--resume", "--settings") else ["--run", "sweep", *TINY, "--measure-epochs", "1"])
        + ([] if flag == "--resume" else ["--root", fresh]) + ["--quiet"],
        "status": ["--run", "x", *NO_ROUTER, "--duration", "1"],
        "dashboard": ["--run=x", *NO_ROUTER],  # the first item is dropped when the positional directory is swept
        "compare": ["--out", fresh, "--runs", "1", *TINY, "--quiet"],
        "study": ["--out", fresh, "--runs", "1", "--factor", "regime=independent", *TINY, "--quiet"],
        "evolvability": ["--landscapes", "1", "--runs", "1", "--generations", "1", "--population", "2", "--classes",
                         "gradual", "--rates", "0.1", "--models", "fm", "--quiet", "--out", fresh],
        "earl": ["--runs", "1", "--generations", "0", "--quiet", "--out", fresh],
        "seeds": (["--task", "door", "--generations", "1", "--ga", "population=2", "--ga", "episodes=1"]
                  if flag in ("--generations", "--fail", "--world", "--ga") else ["--behaviours", "docking"])
        + ["--seeds", "1", "--quiet", "--out", fresh],
        "td-baseline": ["--tasks", "door", "--seeds", "1", "--generations", "1", "--population", "2", "--episodes", "1",
                        "--trials", "1", "--quiet", "--out", fresh],
        "keygen": ["--run", "x", "--out", f"{fresh}.key"],
        "show": ["--default", "tracking", "--episodes", "1", "--rules"],
        "chaos": ["--run", "sweep", "--root", fresh, *TINY, "--faults", "0", "--quiet"],
        "cel": ([] if flag in ("--resume", "--settings") else ["--run", "sweep", "--generations", "2", "--population", "2",
                                                "--episodes", "1", "--fail", "1:front"])
        + ([] if flag == "--resume" else ["--root", fresh]) + ["--quiet"],
        "cel-experiment": ["--runs", "1", "--generations", "2", "--population", "2", "--episodes", "1",
                           "--trials-per-generation", "2", "--quiet", "--out", fresh],
        "execution": ([] if flag == "--settings" else ["--settings", str(places["cel-run"] / "run.json")])
        + [*NO_ROUTER, "--out", fresh],
        "replay": [str(places["broken-worker"])],
        "dynamics": [str(places["broken-run"]), "--quiet"],
        "check": [str(places["broken-worker"]), "--no-replay"],
    }
    base = bases[command]
    if flag in base:  # the value under test replaces the base's
        i = base.index(flag)
        j = i + 1
        while j < len(base) and not base[j].startswith("--"):
            j += 1
        base = base[:i] + base[j:]
    return base


def _flags(sub: argparse.ArgumentParser) -> Iterator[argparse.Action]:
    for a in sub._actions:
        if isinstance(a, (argparse._HelpAction, argparse._StoreTrueAction, argparse._StoreFalseAction,
                          argparse._StoreConstAction)):
            continue
        yield a


def _numeric(action: argparse.Action) -> bool:
    """A flag that takes a number: its type turns "1" into one (not ``--initial``, whose type makes text)."""
    if action.choices is not None or action.type is None:
        return False
    try:
        return isinstance(action.type("1"), (int, float))
    except (argparse.ArgumentTypeError, ValueError, TypeError):
        return False


def _values(action: argparse.Action, places: dict[str, Path]) -> list[str]:
    if action.choices is not None:
        return ["nan", ""]
    if action.metavar == "NAME=VALUE":  # --ga, --world: hostile numbers inside settings (population is the flag's)
        names = ["mutation_rate", "initial_rules"] if "--ga" in action.option_strings else ["target_speed"]
        return [f"{n}={v}" for n in names for v in NUMBERS] + ["", "nan", "=1", "a=b=c"]
    if "--connect-timeout" in action.option_strings:
        return [v for v in NUMBERS if v != "-1"]  # -1 is "wait for the router for ever", inside zenoh: not a bug
    if action.type is not None and action.type is not str:
        return NUMBERS
    return ["", "nan", "-1", str(places["file"]), str(places["dir"]), "/proc/x/y", str(places["broken_json"]),
            str(places["broken-run"]), str(places["broken-worker"])]


def _run(argv: list[str]) -> tuple[int | None, str, BaseException | None]:
    """``coevo ARGV`` in this process: (exit status, stderr, what escaped main)."""
    err = io.StringIO()
    old_term = signal.getsignal(signal.SIGTERM)
    modules, fired = set(sys.modules), []

    def alarm(signum: int, frame: object) -> None:
        fired.append(signum)
        raise KeyboardInterrupt("the sweep's alarm")

    old_alarm = signal.signal(signal.SIGALRM, alarm)
    old_prof = signal.signal(signal.SIGPROF, alarm)
    signal.setitimer(signal.ITIMER_PROF, ALARM_S)
    signal.setitimer(signal.ITIMER_REAL, ALARM_WALL_S)
    code: int | None = None
    escaped: BaseException | None = None
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["--log-level", "ERROR", *argv])
    except SystemExit as exc:  # argparse
        code = exc.code if isinstance(exc.code, int) else 2
    except BaseException as exc:  # noqa: BLE001 - the point of the sweep: report what escaped, with its argv
        escaped = exc
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGALRM, old_alarm)
        signal.signal(signal.SIGPROF, old_prof)
        signal.signal(signal.SIGTERM, old_term)
        if fired:
            # The alarm may have struck inside an import (matplotlib's, at a tiny learn's pictures, when a loaded
            # machine stretched its CPU-seconds): Python drops the module that failed, but its submodules already
            # imported stay and hold the half-made parent, so every later test of this process that imports it failed
            # ("module 'matplotlib' has no attribute 'get_data_path'", seen at load 40).  What the interrupted command
            # imported is forgotten, to be imported whole by whoever needs it next.
            for name in set(sys.modules) - modules:
                del sys.modules[name]
    return code, err.getvalue(), escaped


def _commands() -> list[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sorted(sub.choices)


def _named(value: str, stderr: str) -> bool:
    """The value appears as given, or as Python writes that number (1e+308)."""
    if not value:
        return "''" in stderr
    return value in stderr or str(float(value)) in stderr


@pytest.mark.parametrize("command", _commands())
def test_every_flag_with_hostile_values_ends_in_a_status_never_a_traceback(command: str, places: dict[str, Path]) -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[command]
    problems: list[str] = []
    faulthandler.dump_traceback_later(120, exit=True)  # a hang inside zenoh ignores the alarm: show where, and end
    try:
        tried = _sweep(command, sub, places, problems)
    finally:
        faulthandler.cancel_dump_traceback_later()
    assert tried, f"no flags found for {command}"
    assert not problems, f"{len(problems)} of {tried} command lines misbehave:\n" + "\n".join(problems)


def _sweep(command: str, sub: argparse.ArgumentParser, places: dict[str, Path], problems: list[str]) -> int:
    """Try every flag of ``command`` with its hostile values; note what misbehaves in ``problems``; how many tried."""
    tried = 0
    if not list(_flags(sub)):  # a command without values to give (coevo plugins): run as it is, it must end cleanly
        code, stderr, escaped = _run([command])
        if escaped is not None or code not in (0, 1) or "Traceback" in stderr:
            problems.append(f"coevo {command}: status {code}, escaped {escaped!r}, stderr {stderr[-300:]!r}")
        return 1
    for action in _flags(sub):
        flag = action.option_strings[0] if action.option_strings else None
        numeric = _numeric(action)
        for value in _values(action, places):
            nargs = action.nargs if isinstance(action.nargs, int) else 1
            base = _base(command, flag or "", places)
            argv = [command, *base, flag, *[value] * nargs] if flag else [command, value, *base[1:]]
            code, stderr, escaped = _run(argv)
            tried += 1
            shown = " ".join(repr(a) if a == "" or " " in a else a for a in argv)
            if escaped is not None:
                problems.append(f"coevo {shown}: {type(escaped).__name__}: {escaped}")
                continue
            if code not in (0, 1, 2, 130) or "Traceback" in stderr:
                problems.append(f"coevo {shown}: status {code}, stderr {stderr[-300:]!r}")
                continue
            if numeric and value in CLEARLY_BAD:
                lines = [x for x in stderr.splitlines() if x.strip()]
                if code != 2 or len(lines) != 1 or not re.match(r"^[A-Z]\w+: ", lines[0]) or not _named(value, lines[0]):
                    problems.append(f"coevo {shown}: status {code}, expected 2 and one 'Type: message' line naming "
                                    f"{value!r}; stderr {stderr[-300:]!r}")
    return tried


#: Flags no parser declares: a task's own (coevo.console.task_flags), a partner's rule file or a world setting by the
#: task's name for it, taken by learn and show once the task is known; and flags no task has.
TASK_FLAGS = [("learn", ["--behaviour", "executive"], "--tracking"), ("learn", ["--behaviour", "executive"], "--docking"),
              ("learn", ["--task", "door"], "--fail"), ("learn", ["--behaviour", "tracking"], "--nosuch"),
              ("learn", ["--behaviour", "tracking"], "--tracking"), ("learn", ["--behaviour", "tracking"], "--fail"),
              ("show", ["--default", "tracking", "--episodes", "1", "--rules"], "--docking"),
              ("show", ["--default", "tracking", "--episodes", "1", "--rules"], "--nosuch"),
              ("run", ["--run", "x"], "--tracking")]


@pytest.mark.parametrize(("command", "base", "flag"), TASK_FLAGS)
def test_a_tasks_own_flags_with_hostile_values_end_in_one_line(command: str, base: list[str], flag: str,
                                                                places: dict[str, Path]) -> None:
    """A task's own flag (``--tracking FILE``, the door task's ``--fail``) given a hostile value, given to a task
    that has no such flag, or given to a command that takes none: status 2 and one ``Type: message`` line."""
    problems = []
    for value in ["", "nan", "-1", str(places["file"]), str(places["dir"]), "/proc/x/y", str(places["broken_json"])]:
        argv = [command, *base, *(TINY if command == "learn" else []), "--measure-epochs", "1", "--quiet", "--out",
                str(places["full"]), flag, value] if command == "learn" else [command, *base, flag, value]
        code, stderr, escaped = _run(argv)
        lines = [x for x in stderr.splitlines() if x.strip()]
        if escaped is not None or "Traceback" in stderr:
            problems.append(f"{argv}: escaped {escaped!r}, stderr {stderr[-300:]!r}")
        elif code != 0 and (code != 2 or len(lines) != 1 or not re.match(r"^[A-Z]\w+: ", lines[0])):
            problems.append(f"{argv}: status {code}, stderr {stderr[-300:]!r}")
    assert not problems, "\n".join(problems)


def _numeric_fields(model: type) -> list[str]:
    """The settings of ``model`` that take a number (not booleans, choices or lists)."""
    return [name for name, f in model.model_fields.items() if f.annotation in (int, float, "int", "float")]


def _task_sweep() -> list[tuple[str, str, str]]:
    """(behaviour, flag, setting): every world setting of every task, every GA setting once (on the cheapest task)."""
    from coevo.config import GAConfig
    from coevo.tasks import get_task

    out = [("corridor", "--ga", n) for n in _numeric_fields(GAConfig)]
    for behaviour, task in (("tracking", "fuel"), ("door", "door"), ("corridor", "corridor")):
        out += [(behaviour, "--world", n) for n in _numeric_fields(get_task(task).world_settings)]
    return out


SETTINGS_SWEEP = _task_sweep()


@pytest.mark.parametrize("behaviour", sorted({b for b, _, _ in SETTINGS_SWEEP}))
def test_every_world_and_ga_setting_with_nan_inf_zero_and_negative_is_one_line_or_runs(behaviour: str,
                                                                                        tmp_path: Path) -> None:
    """nan and inf: status 2 and one ``ConfigError:`` line naming the setting and the value (``--world arena=inf``
    ended in an OverflowError traceback); 0 and -1: refused the same way, or a run that ends normally."""
    problems: list[str] = []
    tried = 0
    for b, flag, name in SETTINGS_SWEEP:
        if b != behaviour:
            continue
        for value in ("nan", "inf", "-inf", "0", "-1", "1e308"):
            tried += 1
            tiny = [x for n, v in (("generations", 1), ("population", 2), ("episodes", 1), ("best_episodes", 1))
                    if not (flag == "--ga" and n == name) for x in ("--ga", f"{n}={v}")]
            argv = ["learn", "--behaviour", b, *tiny, "--measure-epochs", "1", "--quiet",
                    "--out", str(tmp_path / f"o{tried}"), flag, f"{name}={value}"]
            code, stderr, escaped = _run(argv)
            shown = f"coevo {' '.join(argv)}"
            lines = [x for x in stderr.splitlines() if x.strip()]
            if escaped is not None:
                problems.append(f"{shown}: {type(escaped).__name__}: {escaped}")
            elif "Traceback" in stderr or code not in (0, 2):
                problems.append(f"{shown}: status {code}, stderr {stderr[-300:]!r}")
            elif code == 2 and (len(lines) != 1 or not lines[0].startswith("ConfigError: ") or name not in lines[0]
                                or not _named(value, lines[0])):
                problems.append(f"{shown}: expected one 'ConfigError: ...' line naming {name}={value}; got {stderr!r}")
            elif value in ("nan", "inf", "-inf", "1e308") and code != 2:
                problems.append(f"{shown}: a value that is not finite or not physical was accepted")
    assert tried
    assert not problems, f"{len(problems)} of {tried} command lines misbehave:\n" + "\n".join(problems)


@pytest.mark.parametrize("argv, needle", [
    (["router", "--connect", "tcp/127.0.0.1:99999", "--listen", "tcp/127.0.0.1:0"], "port 99999 cannot exist"),
    (["router", "--listen", "tcp/127.0.0.1:70000"], "port 70000 cannot exist"),
    (["worker", "--behaviour", "tracking", "--run", "x", "--regime", "independent", "--connect", "tcp/127.0.0.1:0",
      "--connect-timeout", "0"],
     "port 0 cannot exist"),
    (["status", "--run", "x", "--connect", "tcp/nohostport"], "no HOST:PORT"),
    (["broker", "--data-dir", "", "--listen", "tcp/127.0.0.1:0"], "--data-dir '' is empty"),
    (["learn", "--behaviour", "corridor", "--out", ""], "--out '' is empty"),
])
def test_an_endpoint_that_cannot_exist_and_an_empty_path_are_one_line_and_status_2(argv: list[str], needle: str,
                                                                                    tmp_path: Path,
                                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, stderr, escaped = _run(argv)
    lines = [x for x in stderr.splitlines() if x.strip()]
    assert escaped is None and code == 2, (code, stderr, escaped)
    assert len(lines) == 1 and lines[0].startswith("ConfigError: ") and needle in lines[0], stderr
    assert not list(tmp_path.iterdir())  # nothing written (no store in the current folder, no runs/)


# ---------------------------------------------------------------- bounds and blanks, property-based
# Every flag of every command, read from the parsers, so a new flag is covered without touching this file.  Most
# values are checked in this process through the parser alone (milliseconds each); a sample runs the real entry
# point as a process (marked service).

def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


SUBPARSERS = _subparsers()
#: (command, action) for every flag or argument that takes a value.
VALUED = [(c, a) for c, sub in sorted(SUBPARSERS.items()) for a in _flags(sub)]
BOUNDED = [(c, a) for c, a in VALUED if isinstance(a.type, Bounded)]


def _argv(command: str, action: argparse.Action, value: str) -> list[str]:
    """``--flag=VALUE`` (so that a value like ``-1e16`` is read as a value, as a user would write it)."""
    if not action.option_strings:
        return [command, value]
    if isinstance(action.nargs, int):
        return [command, action.option_strings[0], *[value] * action.nargs]
    return [command, f"{action.option_strings[0]}={value}"]


def _parse(argv: list[str]) -> tuple[int | None, str]:
    """``coevo ARGV`` through the parser only (no command runs): (exit status, or None if it parsed; stderr)."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            build_parser(only=argv[0]).parse_args(argv)
    except SystemExit as exc:
        return (exc.code if isinstance(exc.code, int) else 2), err.getvalue()
    return None, err.getvalue()


def _one_line(code: int | None, stderr: str) -> list[str]:
    lines = [x for x in stderr.splitlines() if x.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("ConfigError: ") and "Traceback" not in stderr, \
        (code, stderr)
    return lines


def test_every_flag_that_takes_a_number_has_a_stated_bound() -> None:
    """A count, size, time or rate flag is a :class:`Bounded` (its bound in one place, named when refused): a flag
    whose type turns "1" into a number and is not one is a flag somebody forgot to bound."""
    unbounded = [f"{c} {a.option_strings or a.dest}" for c, a in VALUED
                 if _numeric(a) and not isinstance(a.type, Bounded)]
    assert BOUNDED and not unbounded, unbounded


def test_docs_commands_md_lists_every_bound_as_the_parsers_have_it() -> None:
    rows: dict[tuple[str, str], list[str]] = {}
    for c, a in BOUNDED:
        rows.setdefault((a.option_strings[0], a.type.describe()), []).append(c)
    doc = (Path(__file__).parent.parent / "docs" / "commands.md").read_text()
    table = {line for line in doc.splitlines() if line.startswith("| `--")}
    mine = {f"| `{flag}` | {', '.join(cmds)} | {bound} |" for (flag, bound), cmds in rows.items()}
    assert table == mine, f"in the docs only: {sorted(table - mine)}; in the parsers only: {sorted(mine - table)}"


def _outside(b: Bounded) -> st.SearchStrategy[str]:
    """Text that ``b`` must refuse: beyond either end, huge, not finite, not a number (or not whole)."""
    below = (st.floats(max_value=b.lo, exclude_max=True, allow_nan=False) if not b.whole
             else st.integers(max_value=int(b.lo) - 1)).map(str)
    above = (st.floats(min_value=b.hi, exclude_min=True, allow_nan=False, allow_infinity=False) if not b.whole
             else st.integers(min_value=int(b.hi) + 1)).map(str)
    odd = st.sampled_from(["nan", "inf", "-inf", "1e400", "9" * 5000, "one", "0x10", "1,5", "- 1"])
    edge = st.just(repr(float(b.lo))) if b.above else st.nothing()
    whole = st.floats(min_value=max(b.lo, -1e9) + 0.25, max_value=min(b.hi, 1e9) - 0.25).filter(
        lambda v: not float(v).is_integer()).map(repr) if b.whole and b.hi - b.lo >= 1 else st.nothing()
    return st.one_of(below, above, odd, edge, whole)


@settings(max_examples=400, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_value_beyond_any_flags_bound_is_one_line_naming_the_flag_and_the_bound(data: st.DataObject) -> None:
    command, action = data.draw(st.sampled_from(BOUNDED), label="flag")
    value = data.draw(_outside(action.type), label="value")
    code, stderr = _parse(_argv(command, action, value))
    line = _one_line(code, stderr)[0]
    assert f"argument {action.option_strings[0] if action.option_strings else action.dest}" in line, line
    if isinstance(action.nargs, int) and value.startswith("-"):  # --gap -1e16 -1e16: argparse reads a flag
        assert f"expected {action.nargs} arguments" in line or action.type.describe() in line, line
    else:
        assert action.type.describe() in line, line  # the bound, in words


@settings(max_examples=300, deadline=2000)
@given(data=st.data())
def test_an_empty_or_blank_value_of_any_flag_is_one_line_naming_the_flag(data: st.DataObject) -> None:
    command, action = data.draw(st.sampled_from(VALUED), label="flag")
    value = data.draw(st.text(alphabet=" \t\n\r\x0b\x0c\u00a0\u2003", max_size=4), label="value")
    code, stderr = _parse(_argv(command, action, value))
    line = _one_line(code, stderr)[0]
    name = "/".join(action.option_strings) or action.metavar or action.dest
    assert f"{name} {value!r} is {'empty' if not value else 'blank'}" in line, line


#: Flags and arguments that name a file or directory to read: by metavar, or a positional.
READERS = [(c, a) for c, a in VALUED if not a.option_strings or re.search(r"FILE|DIR|JSON|RULES", str(a.metavar or ""))
           or a.dest in ("settings", "resume", "history", "tracking", "docking", "seed_policy", "cases_from", "lockstep")]


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_bytes_in_any_file_a_flag_names_end_in_a_status_never_a_traceback(
        data: st.DataObject, places: dict[str, Path]) -> None:
    """Each command runs in this process with the sweep's quick base command line; the file under test holds
    random bytes (or is a directory of them)."""
    command, action = data.draw(st.sampled_from(READERS), label="flag")
    blob = data.draw(st.binary(max_size=600), label="bytes")
    path = places["dir"] / f"blob-{next(_count)}"
    path.write_bytes(blob)
    flag = action.option_strings[0] if action.option_strings else None
    base = _base(command, flag or "", places)
    argv = [command, *base, flag, str(path)] if flag else [command, str(path), *base[1:]]
    t0 = time.process_time()
    code, stderr, escaped = _run(argv)
    assert escaped is None, f"coevo {argv}: {type(escaped).__name__}: {escaped}"
    assert code in (0, 1, 2, 130) and "Traceback" not in stderr, (argv, code, stderr[-500:])
    if code == 2:
        assert len([x for x in stderr.splitlines() if x.strip()]) == 1, (argv, stderr)
    assert time.process_time() - t0 < ALARM_S + 5  # the alarm stopped it


def _blob(tmp: Path) -> str:
    """A file of random bytes (seeded)."""
    import random

    p = tmp / "random.bin"
    p.write_bytes(random.Random(39).randbytes(700))
    return str(p)


HUGE = "9" * 30
#: The real entry point on a sample: the issue's command lines and random bytes in files of every kind.
SAMPLE: list[list[str]] = [
    ["td-baseline", "--out", "o", "--seeds", HUGE], ["td-baseline", "--out", "o", "--trials", HUGE],
    ["td-baseline", "--out", "o", "--lanes", HUGE], ["evolvability", "--runs", HUGE], ["evolvability", "--landscapes", HUGE],
    ["bench", "--lanes", "10000000"], ["earl", "--out", "o", "--generations", HUGE], ["earl", "--out", "o", "--runs", HUGE],
    ["run", "--max-lead", HUGE], ["run", "--resume", ""], ["run", "--regime", ""], ["compare", "--out", " "],
    ["dashboard", ".", "--host", ""], ["broker", "--auth-file", "BLOB", "--listen", "tcp/127.0.0.1:0", "--data-dir", "d"],
    ["compare", "--cluster", "local", "--shared-dir", "BLOB", "--runs", "1"], ["check", "BLOB"], ["show", "BLOB"],
    ["learn", "--behaviour", "tracking", "--seed-policy", "BLOB", "--generations", "1"], ["run", "--settings", "BLOB"],
    ["status", "--run", "x", "--key-file", "BLOB", *NO_ROUTER], ["status", "--run", "x", "--zenoh-config", "BLOB"],
    ["worker", "--behaviour", "tracking", "--settings", "BLOB"],
]


@pytest.mark.service
@pytest.mark.parametrize("argv", SAMPLE, ids=lambda a: " ".join(repr(x) if not x.strip() else x[:12] for x in a))
def test_the_real_entry_point_refuses_in_one_line_without_a_traceback(argv: list[str], tmp_path: Path) -> None:
    import subprocess
    import sys

    blob = _blob(tmp_path)
    argv = [blob if a == "BLOB" else a for a in argv]
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "coevo", *argv], capture_output=True, text=True, cwd=tmp_path, timeout=60)
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert r.returncode != 0 and len(lines) == 1 and re.match(r"^[A-Z]\w+: ", lines[0]), (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr + r.stdout
    assert time.monotonic() - t0 < 30
    assert not [p for p in tmp_path.iterdir() if p.name != "random.bin"], "something was written"
