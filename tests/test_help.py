"""Help and errors a newcomer meets first (issue 55): every flag of every command is described in its ``--help``;
``--ga help`` and ``--world help`` list the names those flags take; a run directory that is not there is said to be
missing, not "not a run directory"."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from procs import coevo_main

from coevo.cli import build_parser
from coevo.config import GAConfig
from coevo.tasks import get_task


def test_every_argument_of_every_command_has_a_description() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    parsers = {"coevo": parser, **{f"coevo {name}": p for name, p in sub.choices.items()}}
    bare = [f"{name} {'/'.join(a.option_strings) or a.dest}" for name, p in parsers.items() for a in p._actions
            if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)) and not (a.help or "").strip()]
    bare += [f"coevo {c.dest}" for c in sub._choices_actions if not (c.help or "").strip()]  # the command list's
    assert bare == [], f"arguments without a description in --help: {bare}"


@pytest.mark.parametrize(("argv", "model"), [
    (["run", "--ga", "help"], GAConfig),
    (["learn", "--behaviour", "docking", "--ga", "population=4", "--ga", "help"], GAConfig),
    (["run", "--world", "help"], get_task("fuel").world_settings),
    (["learn", "--task", "door", "--world", "help"], get_task("door").world_settings),
])
def test_ga_help_and_world_help_list_every_name_with_its_default(argv: list[str], model: type) -> None:
    r = coevo_main(*argv)
    assert r.returncode == 0 and not r.stderr, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    flag = argv[argv.index("help") - 1]
    assert lines[0] == f"{flag} NAME=VALUE takes ({model.__name__}):"
    assert [line.split(" = ")[0].strip() for line in lines[1:]] == list(model.model_fields)
    default = model.model_fields["episodes" if model is GAConfig else "arena" if "arena" in model.model_fields
                                 else "room_width"].default
    assert any(line.split(" = ")[1].startswith(str(default)) for line in lines[1:])


def test_a_misspelt_setting_still_gets_its_nearest_name_and_no_help_is_taken_for_a_value() -> None:
    r = coevo_main("run", "--ga", "mutation_rat=0.1")
    assert r.returncode == 2 and "did you mean mutation_rate?" in r.stderr, r.stderr
    r = coevo_main("run", "--ga", "helps")
    assert r.returncode == 2 and r.stderr.strip() == "ConfigError: --ga 'helps': expected name=value", r.stderr


@pytest.mark.parametrize("command", ["check", "replay"])
def test_check_and_replay_of_a_directory_that_is_not_there_say_so(command: str, tmp_path: Path) -> None:
    r = coevo_main(command, str(tmp_path / "nosuch"))
    assert r.returncode == 2 and r.stderr.strip() == f"RunDirError: no such directory: '{tmp_path / 'nosuch'}'"
    (tmp_path / "afile").write_text("x")
    r = coevo_main(command, str(tmp_path / "afile"))
    assert r.returncode == 2 and r.stderr.strip() == f"RunDirError: '{tmp_path / 'afile'}' is a file, not a run directory"
    (tmp_path / "empty").mkdir()
    r = coevo_main(command, str(tmp_path / "empty"))
    assert r.returncode == 2 and "not a coevo run directory" in r.stderr, r.stderr


def test_a_dashboard_on_a_taken_port_is_refused_before_anything_loads(tmp_path: Path) -> None:
    """One line, status 2, before the directory is read or Bokeh imported (it took 11.5 s to say so before)."""
    import socket
    import subprocess
    import sys

    code = ("import sys\nfrom coevo.cli import main\nstatus = main(sys.argv[1:])\n"
            "print('loaded:', sorted(m for m in ('bokeh', 'tornado', 'matplotlib') if m in sys.modules), status)")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        r = subprocess.run([sys.executable, "-c", code, "dashboard", str(tmp_path / "nosuch"), "--port", str(port)],
                           capture_output=True, text=True, timeout=120)
    assert r.stdout.strip() == "loaded: [] 2", r.stdout + r.stderr
    assert r.stderr.strip() == (f"ConfigError: cannot serve on 127.0.0.1:{port}: Address already in use (choose "
                                "another --port or --host)"), r.stderr
