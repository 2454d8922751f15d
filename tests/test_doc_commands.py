"""Every ``coevo`` command the documentation quotes is one the command line takes (issue 55: commands the product
suggested ended with status 2).

The commands are read from README.md and docs/**/*.md: inline code spans and the lines of fenced blocks that begin
with ``coevo`` (a ``\\`` continues one).  Each is parsed by coevo's own parser as ``coevo`` parses it (a command that
takes its task's own flags keeps them for later, as :func:`coevo.cli.main` does), its placeholders (``RUN_DIR``,
``SEED``, ...) given a value of their kind; the commands that only read a finished run (``check``, ``replay``,
``show``) are run as written against a copy of the session's small finished run.

Left out, on purpose (the only skip list): a command's bare name in prose (``coevo check``) or a flag named by its
command (``coevo compare --out``); synopses (``[--seed N]``, ``a|b``, ``...``: docs/commands.md, checked against the
parsers by tests/test_docs.py); lines that need a shell (``$(...)``); the outside task's commands (docs/own-task.md:
tests/test_own_task.py installs its package and runs them); and :data:`REFUSED`, the pages' examples of what is
refused, which must be refused in one line.
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest
from procs import coevo_main, copy_of

ROOT = Path(__file__).resolve().parent.parent
CODE_SPAN = re.compile(r"(`+)(coevo [^`]+?)\1")
FENCE = re.compile(r"^\s*(`{3,}|~{3,})")

#: What a placeholder stands for, by its kind: a value the parser takes (a path is any text to it).
PLACEHOLDERS = {"N": "2", "S": "7", "SEED": "7", "CELL_SEED": "7", "R": "0.5", "B": "docking", "NAME": "cel", "ID": "r1",
                "PORT": "7447"}
#: The pages' examples of bad input: refused, with one line naming the bad value (docs/faults.md, docs/trust.md,
#: docs/commands.md).
REFUSED = {"coevo run --resume ''", "coevo learn --out ''", "coevo td-baseline --seeds 99999999999999999999999",
           "coevo bench --lanes 10000000"}


def quoted_commands() -> list[tuple[str, str]]:
    """(where, command) for every ``coevo ...`` the pages quote, comments, explanations and a trailing ``&`` cut."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    out = []
    for page in pages:
        fence, pending = None, ""
        for n, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            where = f"{page.relative_to(ROOT)}:{n}"
            if m := FENCE.match(line):
                fence = None if fence else m.group(1)
                continue
            if fence is None:
                out += [(where, m.group(2)) for m in CODE_SPAN.finditer(line)]
                continue
            text = re.sub(r"^(\$ |\.venv/bin/|next: +)", "", line.strip())
            if pending or text.startswith("coevo "):
                pending += " " + text.rstrip("\\")
                if not text.endswith("\\"):
                    out.append((where, pending.strip()))
                    pending = ""
    return [(where, _trimmed(c)) for where, c in out]


def _trimmed(command: str) -> str:
    command = re.split(r"\s+#|\s{2,}\(", command)[0].strip()  # '# a comment', '  (what it does)'
    return re.sub(r"\s*&$", "", command)


def _skipped(command: str) -> bool:
    return (len(command.split()) < 3 or bool(re.search(r"[\[|]|\.\.\.|…|\$\(|/--|^coevo \w+,", command))
            or "pursuit" in command or command.endswith("--help"))


def _argv(command: str) -> list[str]:
    words = shlex.split(command)[1:]
    return [re.sub(r"\b[A-Z][A-Z_]*\b", lambda m: PLACEHOLDERS.get(m.group(0), m.group(0)), w) for w in words]


def _parse(argv: list[str]) -> str:
    """'' if ``coevo ARGV`` parses as coevo.cli.main parses it; else what the parser said."""
    from coevo.cli import _command_in, build_parser

    parser = build_parser(only=_command_in(argv) or "")
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            args, extra = parser.parse_known_args(argv)
    except SystemExit as exc:
        return err.getvalue().strip() or f"exit {exc.code}"
    return f"unrecognized arguments: {' '.join(extra)}" if extra and getattr(args, "task_flags", None) is None else ""


def _a_flag_named(argv: list[str], said: str) -> bool:
    """``coevo compare --out`` in prose names the flag: its value is missing, and nothing follows it."""
    return argv[-1].startswith("--") and "expected" in said and "argument" in said


def test_the_pages_quote_many_commands_and_the_extraction_finds_fenced_and_inline_ones() -> None:
    commands = quoted_commands()
    assert len([c for _, c in commands if not _skipped(c)]) > 60
    assert ("docs/running.md", "coevo run --regime independent") not in commands  # a fenced line is whole
    assert any(c.startswith("coevo worker --run r1 --regime mutual --behaviour tracking") for _, c in commands)
    assert any(c == "coevo check runs/r1" for _, c in commands)


def test_every_quoted_command_parses_as_coevo_parses_it() -> None:
    bad = {}
    for where, command in quoted_commands():
        if _skipped(command) or command in REFUSED:
            continue
        argv = _argv(command)
        said = _parse(argv)
        if said and not _a_flag_named(argv, said):
            bad[where] = f"{command}: {said}"
    assert bad == {}, "\n".join(f"{w}: {b}" for w, b in bad.items())


@pytest.mark.parametrize("command", sorted(REFUSED))
def test_the_pages_examples_of_bad_input_are_refused_in_one_line(command: str) -> None:
    assert any(c == command for _, c in quoted_commands()), f"no page quotes {command!r} any more: drop it here"
    r = coevo_main(*shlex.split(command)[1:])
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and not r.stdout, r.stdout + r.stderr


RUN_PLACEHOLDER = re.compile(r"^(RUN_DIR|RUN|runs/(?:ID|RUN|r1))$")


def test_the_quoted_commands_that_read_a_finished_run_run_as_written(finished_mutual: Path, tmp_path: Path) -> None:
    """``coevo check|replay|show RUN ...`` as the pages write them, RUN a copy of the session's small finished run."""
    run_dir = copy_of(finished_mutual, tmp_path)
    forms = sorted({c for _, c in quoted_commands() if not _skipped(c)
                    and re.match(r"coevo (check|replay|show) ", c) and RUN_PLACEHOLDER.match(c.split()[2])})
    assert {c.split()[1] for c in forms} == {"check", "replay", "show"}, forms
    for command in forms:
        argv = [str(run_dir) if i == 1 else w for i, w in enumerate(_argv(command))]
        r = coevo_main(*argv)
        assert r.returncode == 0, f"{command}: {r.stdout}{r.stderr}"
        assert "Traceback" not in r.stderr
