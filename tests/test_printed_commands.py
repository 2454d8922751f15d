"""Every ``coevo`` command a generated report.md or a dashboard page prints runs as written (issue 55: the comparison
page's and the study page's ``coevo compare --report-only --out ...`` ended with status 2).  The sibling of
tests/test_doc_commands.py, which does the same for docs/.

A tiny comparison and a tiny study of comparisons are made once for the module; the commands are read from their
report.md files (code spans) and from the dashboard's pages of them as the server builds them (their ``<code>``
elements and the "coevo ... writes it again" sentences), each run from the directory the text is read in (a report's
paths are relative to its folder), its placeholders (``RUN``, ``SEED``, ``CELL``) given a value of the report's own.
A command that only opens a page (``coevo dashboard``) is parsed, not served.  The pages print their commands where a
report is missing (a comparison or study stopped before it wrote one; a study's cell, which has none of its own), so
each test removes the report's results.json after reading its report.md."""

from __future__ import annotations

import html as html_lib
import json
import re
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from procs import coevo_main
from test_doc_commands import _parse, _skipped

pytestmark = pytest.mark.service  # a comparison and a study, as processes

TINY = ["--runs", "1", "--generations", "2", "--population", "4", "--episodes", "4", "--ga", "best_episodes=4",
        "--ga", "initial_rules=8", "--measure-epochs", "1", "--quiet"]
CODE_SPAN = re.compile(r"`(coevo [^`]+)`")
CODE_ELEMENT = re.compile(r"<code>(coevo [^<]+)</code>|\b(coevo (?:compare|study) --report-only --out \S+?)\)? writes")


def _made(args: list[str], where: Path) -> Path:
    r = subprocess.run([sys.executable, "-m", "coevo", *args, "--out", str(where), *TINY], capture_output=True,
                       text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    return where


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("printed")
    return {"comparison": _made(["compare", "--regimes", "independent"], tmp / "cmp"),
            "study": _made(["study", "--factor", "max_lead=1,off", "--factor", "regime=independent", "--jobs", "2"],
                           tmp / "study")}


def _page_commands(target: Path) -> list[str]:
    """The commands the dashboard's page of ``target`` prints, as the server builds it (every Div's text)."""
    from bokeh.document import Document

    from coevo.dashboard.model import Dashboard
    from coevo.dashboard.server import make_document

    dash = Dashboard(target=target, stale=60)
    dash.refresh()
    doc = Document()
    make_document(dash, [])(doc)
    texts = [str(getattr(m, "text", "")) for m in doc.models if type(m).__name__ == "Div"]
    found = [html_lib.unescape(a or b) for t in texts for a, b in CODE_ELEMENT.findall(t)]
    return list(dict.fromkeys(c.strip() for c in found))


def _filled(command: str, values: dict[str, str]) -> list[str]:
    return [re.sub(r"\b[A-Z][A-Z_]*\b", lambda m: values.get(m.group(0), m.group(0)), w)
            for w in shlex.split(command)[1:]]


def _runs(command: str, values: dict[str, str], cwd: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    if _skipped(command):  # a command's bare name in prose ("each cell a `coevo compare` folder"), as in docs/
        return
    argv = _filled(command, values)
    if argv[0] == "dashboard":  # it would serve a page until stopped: what it takes is checked instead
        assert _parse(argv) == "", command
        return
    monkeypatch.chdir(cwd)
    r = coevo_main(*argv)
    assert r.returncode == 0, f"{command} (in {cwd}): {r.stdout}{r.stderr}"
    assert "Traceback" not in r.stderr


def test_the_comparisons_report_and_page_commands_run_as_written(made: dict[str, Path],
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    out = made["comparison"]
    results: dict[str, Any] = json.loads((out / "results.json").read_text())
    run = results["runs"][0] if "runs" in results else None
    values = {"RUN": str(run["run"]) if run else "independent-00", "SEED": str(run["seed"]) if run else "0"}
    report = CODE_SPAN.findall((out / "report.md").read_text())
    assert any(c.startswith("coevo show runs/") for c in report), report
    (out / "results.json").unlink()  # as a comparison stopped before its report: the page says how to write one
    page = _page_commands(out)
    assert f"coevo compare --report-only --out {out}" in page, page
    for command in dict.fromkeys(report + page):
        _runs(command, values, out, monkeypatch)


def test_the_studys_report_and_page_commands_run_as_written(made: dict[str, Path],
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    out = made["study"]
    cells = sorted(p.name for p in (out / "cells").iterdir())
    report = CODE_SPAN.findall((out / "report.md").read_text())
    (out / "results.json").unlink()  # as a study stopped before its report: the page says how to write one
    page = _page_commands(out)
    assert "coevo compare --report-only --out cells/CELL" in report, report
    assert f"coevo study --report-only --out {out}" in page, page
    assert any(c.startswith("coevo compare --report-only --out ") and cells[0] in c for c in page), page
    for command in dict.fromkeys(report + page):
        _runs(command, {"CELL": cells[0]}, out, monkeypatch)
