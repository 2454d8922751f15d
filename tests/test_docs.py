"""The documentation: the site builds with ``mkdocs build --strict``, and every relative link and image
of README.md, deploy/README.md, benchmarks/README.md and docs/**/*.md points at a file that exists (and a ``#anchor`` at a heading there).

mkdocs checks docs/ itself (strict: any warning fails, and mkdocs.yml makes broken links, anchors and pages
left out of the nav warnings); README.md lies outside the site, so its links are checked here, and docs/ is
checked the same way too, so a broken link is named by this test even when mkdocs is not the one to see it.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from string import Template
from typing import Any

import pytest
from markdown.extensions.toc import slugify

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"

LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")  # [text](target), ![alt](target)
HTML_SRC = re.compile(r"<(?:img|a)\s[^>]*?(?:src|href)=\"([^\"]+)\"", re.I)
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
EXTERNAL = re.compile(r"^[a-z][a-z0-9+.-]*:", re.I)  # http:, https:, mailto:, ...
ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _markdown_files() -> list[Path]:
    beside = [ROOT / "README.md", ROOT / "deploy" / "README.md", ROOT / "benchmarks" / "README.md"]
    return [p for p in beside if p.exists()] + sorted(DOCS.rglob("*.md"))


def _prose_lines(text: str, blank_code: bool = True) -> list[str]:
    """The lines outside fenced code blocks, with inline code spans blanked (links in code are not links)."""
    out, fence = [], None
    for line in text.splitlines():
        m = re.match(r"^\s*(`{3,}|~{3,})", line)
        if m:
            if fence is None:
                fence = m.group(1)
            elif m.group(1).startswith(fence):
                fence = None
            continue
        if fence is None:
            out.append(re.sub(r"(`+)(?:(?!\1).)+?\1", "``", line) if blank_code else line)
    return out


def _anchors(path: Path) -> set[str]:
    """The ids Python-Markdown's toc extension (mkdocs' default) gives the headings of a page."""
    ids: set[str] = set()
    for line in _prose_lines(path.read_text(encoding="utf-8"), blank_code=False):
        m = HEADING.match(line)
        if not m:
            continue
        text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", m.group(2))  # a link's text only
        text = re.sub(r"<[^>]+>", "", text).replace("`", "")
        text = re.sub(r"(\*\*|__|\*|_)(.+?)\1", r"\2", text)
        base = slugify(text, "-")
        slug, n = base, 0
        while slug in ids:  # toc's unique(): a repeated heading gets _1, _2, ...
            n += 1
            slug = f"{base}_{n}"
        ids.add(slug)
    return ids


def _links(path: Path) -> list[tuple[int, str]]:
    found = []
    for i, line in enumerate(_prose_lines(path.read_text(encoding="utf-8")), 1):
        for m in (*LINK.finditer(line), *HTML_SRC.finditer(line)):
            found.append((i, m.group(1)))
    return found


def test_every_relative_link_and_image_points_at_a_file_and_heading_that_exist() -> None:
    broken = []
    checked = 0
    for md in _markdown_files():
        for line, target in _links(md):
            if EXTERNAL.match(target) or target.startswith("//"):
                continue
            file_part, _, anchor = target.partition("#")
            dest = (md.parent / file_part).resolve() if file_part else md
            where = f"{md.relative_to(ROOT)}: {target}"
            checked += 1
            if not dest.exists():
                broken.append(f"{where}: no such file")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                broken.append(f"{where}: no heading #{anchor} in {dest.relative_to(ROOT)}")
    assert checked > 50, f"only {checked} links found: is the link pattern still right?"
    assert not broken, "broken links:\n" + "\n".join(broken)


def test_the_anchor_rule_matches_mkdocs() -> None:
    """The slugs computed here are the ones the site's headings get (checked on known headings)."""
    assert "trust-who-can-steer-a-run" in _anchors(DOCS / "faults.md")
    assert "table-1-reproduced-two-full-comparisons" in _anchors(DOCS / "compare.md")
    assert "the-live-service-coevo-cel" in _anchors(DOCS / "cel.md")


def test_the_site_builds_in_strict_mode_without_a_warning(tmp_path: Path) -> None:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "NO_COLOR": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(tmp_path / "site")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
    )
    log = ANSI.sub("", proc.stdout + proc.stderr)
    problems = [ln for ln in log.splitlines() if re.match(r"\s*(WARNING|ERROR)\b", ln)]
    assert proc.returncode == 0 and not problems, f"mkdocs build --strict failed:\n{log}"
    site = tmp_path / "site"
    assert (site / "index.html").exists()
    home = (site / "index.html").read_text(encoding="utf-8")
    assert "Quick start" in home and "--8&lt;--" not in home and "--8<--" not in home  # the README's part came in
    # Nothing is loaded from the internet when a page is viewed: no remote scripts, styles, fonts or images.
    remote = re.compile(r"<(?:script|link|img|iframe)\b[^>]*\b(?:src|href)=\"(?:https?:)?//", re.I)
    fetched = [f"{p.relative_to(site)}: {m.group(0)}" for p in site.rglob("*.html")
               for m in remote.finditer(p.read_text(encoding="utf-8"))]
    assert not fetched, "pages load remote assets:\n" + "\n".join(fetched[:10])



# ----------------------------------------------------------------- recipes run as written
def _fenced_block(page: Path, containing: str) -> list[str]:
    """The commands of the first fenced block of ``page`` that contains ``containing``: continuation lines joined,
    comments and blank lines dropped."""
    blocks = re.findall(r"^```[a-z]*\n(.*?)^```", page.read_text(encoding="utf-8"), re.M | re.S)
    block = next(b for b in blocks if containing in b)
    commands = []
    for line in block.replace("\\\n", " ").splitlines():
        line = re.sub(r"\s#.*$", "", line).strip()
        if line and not line.startswith("#"):
            commands.append(line)
    return commands


@pytest.mark.service
def test_the_hand_started_recipe_of_running_md_runs_as_written_and_passes_check(tmp_path: Path) -> None:
    """docs/running.md's run by hand, command by command from the page: ``NAME=value`` sets a variable, a command
    ending in ``&`` runs in the background (ended at the end), any other runs to its end and must succeed.  What the
    test changes: a free port for 7447 (other runs on this machine), small GA settings on each worker, and it lets a
    command that follows the run start once the workers have written their run.json, as a person typing would."""
    from coevo.runs.local import end_processes, free_port, wait_until

    commands = _fenced_block(DOCS / "running.md", "coevo keygen")
    assert [c.split()[1] for c in commands if c.startswith("coevo ")] == \
        ["keygen", "broker", "worker", "worker", "worker", "status", "check"], commands
    port, small = str(free_port()), ["--generations", "3", "--population", "6", "--episodes", "10", "--ga",
                                     "best_episodes=10", "--ga", "initial_rules=8", "--final-sync", "5"]
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    background: list[subprocess.Popen] = []
    logs = []
    try:
        for i, command in enumerate(commands):
            name, eq, value = command.partition("=")
            if eq and re.fullmatch(r"[A-Z_]+", name):
                env[name] = value
                continue
            argv = [Template(a).substitute(env).replace(":7447", f":{port}") for a in command.rstrip("&").split()]
            if argv[1] == "worker":
                argv += small
            if argv[1] in ("status", "check"):
                wait_until(lambda: (tmp_path / "runs" / "r1" / "run.json").exists(), 60, "the workers' run.json")
            log = tmp_path / f"{i}-{argv[1]}.log"
            logs.append(log)
            with open(log, "wb") as f:
                p = subprocess.Popen(argv, cwd=tmp_path, env=env, stdout=f, stderr=subprocess.STDOUT)
            if command.endswith("&"):
                background.append(p)
            else:
                assert p.wait(timeout=120) == 0, f"{command}: {log.read_text()}"
    finally:
        end_processes(background)
    out = {log.name.split("-", 1)[1]: log.read_text() for log in logs}
    assert "Traceback" not in "".join(out.values()), out
    assert "run r1: done (docking 3/3, executive 3/3, tracking 3/3)" in out["status.log"], out["status.log"]
    assert "unverified" not in out["status.log"]  # it found the key in the run's directory
    assert "Traceback" not in out["check.log"] and "complete" in out["check.log"].lower(), out["check.log"]
    settings = json.loads((tmp_path / "runs" / "r1" / "run.json").read_text())
    assert settings["regime"] == "mutual" and settings["key_file"] == "secret.key", settings


# ----------------------------------------------------------------- the command synopses, against the parsers
def _flags(parser: argparse.ArgumentParser) -> set[str]:
    """A parser's flags (each by its first long name) and positional arguments (by their metavar)."""
    out = set()
    for a in parser._actions:
        if isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        longs = [o for o in a.option_strings if o.startswith("--")]
        out.add(longs[0] if longs else str(a.metavar or a.dest).upper())
    return out


def _group(add: Any, **kw: Any) -> set[str]:
    p = argparse.ArgumentParser()
    add(p, **kw)
    return _flags(p)


def test_docs_commands_md_has_every_command_and_every_flag_of_the_parsers() -> None:
    """docs/commands.md's synopses are checked against coevo.cli's parsers: every command has one, and every flag of
    a command is in one of its synopses, or in a shared group (``[connection flags]``, ``[GA settings]``, ``[cluster
    flags]``) that its synopsis names and that the page spells out in full."""
    from coevo.bus.flags import add_connection_args
    from coevo.cli import build_parser
    from coevo.console import add_settings
    from coevo.replicates.flags import add_backend_flags

    text = (DOCS / "commands.md").read_text(encoding="utf-8")
    block = re.search(r"^```\n(.*?)^```", text, re.M | re.S).group(1)
    synopses: dict[str, str] = {}
    name = None
    for line in block.splitlines():
        m = re.match(r"coevo ([a-z-]+)", line)
        if m:
            name = m.group(1)
        if name is not None:
            synopses[name] = synopses.get(name, "") + " " + line.split(" #")[0]
    groups = {"connection flags": _group(add_connection_args, default_mode="router"), "GA settings": _group(add_settings),
              "cluster flags": _group(add_backend_flags, jobs_help="")}
    for group, flags in groups.items():
        spelled = re.search(rf"^\[{group}\]:(.*(?:\n[ \t]+.*)*)", block, re.M)  # its line and the indented ones
        assert spelled is not None, f"docs/commands.md does not spell out [{group}]"
        assert {f for f in flags if not re.search(rf"{re.escape(f)}\b", spelled.group(1))} == set(), group
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = {}
    for command, parser in sub.choices.items():
        flags = _flags(parser)
        synopsis = synopses.get(command)
        if synopsis is None:
            missing[command] = "no synopsis"
            continue
        for group, members in groups.items():
            if f"[{group}]" in synopsis:
                flags -= members
        absent = sorted(f for f in flags if not re.search(rf"(?<![\w-]){re.escape(f)}(?![\w-])", synopsis))
        if absent:
            missing[command] = absent
    assert missing == {}, f"docs/commands.md lacks: {missing}"
