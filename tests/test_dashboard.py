"""coevo dashboard: its data model (runs, workers, curves from heartbeats and from files, a comparison's replicates
and Table 1), its page pieces, its bad input; and, marked service, the page in a real headless Chromium following a
real run."""

from __future__ import annotations

import base64
import io
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from coevo.cli import main
from coevo.dashboard import render
from coevo.dashboard.model import BusSource, Curve, Dashboard, RunFiles, Tail, View, classify_dir
from coevo.errors import RunDirError


# ---------------------------------------------------------------- curves and logs
def test_a_curve_takes_each_generation_once_in_order_with_the_best_so_far_and_aligned_measures() -> None:
    c = Curve()
    assert c.add(1, 0.5, {"quality_tracking": 20.0})
    assert c.add(2, 0.3)  # no measures this time: a gap, not a shift
    assert not c.add(2, 0.9) and not c.add(1, 0.9) and not c.add(0, 1.0)  # repeated, older, generation 0
    assert c.add(4, 0.7, {"quality_tracking": 40.0, "dock_choice": 5.0})
    assert c.generation == [1, 2, 4] and c.best == [0.5, 0.3, 0.7] and c.best_so_far == [0.5, 0.5, 0.7]
    assert c.measures == {"quality_tracking": [20.0, None, 40.0], "dock_choice": [None, None, 5.0]}


def test_a_tail_reads_only_complete_new_lines_and_starts_again_when_the_log_is_cut_back(tmp_path: Path) -> None:
    f = tmp_path / "curve.jsonl"
    t = Tail(f)
    assert t.read() == []  # missing: nothing yet
    f.write_text('{"a": 1}\n{"a": 2}\n{"a": ')
    assert t.read() == [{"a": 1}, {"a": 2}]
    with open(f, "a") as fh:
        fh.write('3}\nnot json\n[1]\n')
    assert t.read() == [{"a": 3}] and t.bad == 2 and not t.reset
    f.write_text('{"a": 9}\n')  # a resumed worker cut its log back to its checkpoint
    assert t.read() == [{"a": 9}] and t.reset


def _row(g: int, best: float, qt: float = 10.0) -> str:
    return json.dumps({"generation": g, "best_fitness": best, "best_so_far": best, "quality_tracking": qt,
                       "dock_choice": 3.0, "docking_success_rate": 50.0, "docking_from_random": None}) + "\n"


def _run_dir(root: Path, run: str = "r1", generations: int = 3) -> Path:
    d = root / run
    (d / "store").mkdir(parents=True)
    (d / "run.json").write_text(json.dumps({"run": run, "task": "fuel", "regime": "mutual", "key_file": None}))
    for i, b in enumerate(("tracking", "docking", "executive")):
        w = d / "workers" / b
        w.mkdir(parents=True)
        (w / "worker.json").write_text(json.dumps({"behaviour": b, "worker": f"{b}-{i}", "regime": "mutual",
                                                   "ga": {"generations": 10}}))
        (w / "curve.jsonl").write_text("".join(_row(g, 0.1 * g) for g in range(1, generations + 1)))
    (d / "workers" / "executive" / "adoptions.jsonl").write_text(
        json.dumps({"partner": "tracking", "version": 2}) + "\n" + json.dumps({"partner": "docking", "version": 1}) + "\n")
    (d / "store" / "tracking.jsonl").write_text("{}\n{}\n")
    return d


def test_a_run_directory_gives_workers_curves_and_partners_and_grows_as_its_logs_do(tmp_path: Path) -> None:
    d = _run_dir(tmp_path)
    files = RunFiles(d)
    v = files.read()
    assert (v.run, v.task, v.regime, v.state, v.source) == ("r1", "fuel", "mutual", "running", "files")
    by = {w["worker"]: w for w in v.workers}
    assert set(by) == {"tracking-0", "docking-1", "executive-2"}
    assert by["executive-2"]["partner_versions"] == {"tracking": 2, "docking": 1}
    assert by["tracking-0"]["generation"] == 3 and by["tracking-0"]["generations"] == 10
    assert by["tracking-0"]["measures"] == {"quality_tracking": 10.0}  # the task's own measure of that behaviour
    assert by["executive-2"]["measures"] == {"dock_choice": 3.0, "docking_success_rate": 50.0}
    assert v.broker["stored"] == {"tracking": 2}
    assert v.curves["tracking-0"][0] == "tracking" and v.curves["tracking-0"][1].generation == [1, 2, 3]
    with open(d / "workers" / "tracking" / "curve.jsonl", "a") as fh:
        fh.write(_row(4, 0.9, qt=70.0))
    (d / "workers" / "docking" / "done.json").write_text(json.dumps({"rejected": {"wrong_key": 2}, "unconfirmed": []}))
    v = files.read()
    by = {w["worker"]: w for w in v.workers}
    assert v.curves["tracking-0"][1].best_so_far[-1] == 0.9 and by["tracking-0"]["measures"] == {"quality_tracking": 70.0}
    assert by["docking-1"]["state"] == "done" and by["docking-1"]["rejected_by_reason"] == {"wrong_key": 2}
    (d / "summary.json").write_text(json.dumps({"interrupted": False, "measures": {"quality_tracking": 55.0}}))
    v = files.read()
    assert v.state == "done" and v.final == {"quality_tracking": 55.0}


def test_a_run_quiet_for_longer_than_stale_counts_as_stopped(tmp_path: Path) -> None:
    d = _run_dir(tmp_path)
    old = time.time() - 1000
    for f in d.rglob("*"):
        os.utime(f, (old, old))
    v = RunFiles(d, stale=60).read()
    assert v.state == "stopped" and {w["state"] for w in v.workers} == {"stopped"}


def test_what_is_not_a_run_is_one_clear_error(tmp_path: Path) -> None:
    (tmp_path / "a-file").write_text("x")
    (tmp_path / "empty").mkdir()
    for p, needle in ((tmp_path / "a-file", "not a directory"), (tmp_path / "empty", "not a coevo run directory"),
                      (tmp_path / "missing", "not a directory")):
        with pytest.raises(RunDirError, match=needle):
            classify_dir(p)
    _run_dir(tmp_path / "root")
    assert classify_dir(tmp_path / "root") == "runs" and classify_dir(tmp_path / "root" / "r1") == "run"


def test_the_dashboard_moves_its_version_only_when_the_page_would_change(tmp_path: Path) -> None:
    d = _run_dir(tmp_path / "root")
    _run_dir(tmp_path / "root", "r2")
    dash = Dashboard(target=tmp_path / "root")
    assert dash.refresh() and not dash.refresh()
    version, view = dash.current()
    assert [r.run for r in view.runs] == ["r1", "r2"] and version == 1
    with open(d / "workers" / "docking" / "curve.jsonl", "a") as fh:
        fh.write(_row(4, 0.2))
    assert dash.refresh() and dash.current()[0] == 2


# ---------------------------------------------------------------- the bus, through StatusBoard's model
class FakeBoard:
    """What BusSource reads of a StatusBoard (its public snapshot methods), driven by the test."""

    def __init__(self, session: Any, run: str, *, stall: float) -> None:
        self.run, self.rejected, self.open, self.closed = run, 0, True, False
        self.workers: list[dict[str, Any]] = []
        self.broker = {"state": "up", "open": True, "stored": {"tracking": 1}, "rejected": {"flood": 3}, "dropped": 0,
                       "degraded": ""}

    def snapshot(self) -> list[dict[str, Any]]:
        return [dict(w) for w in self.workers]

    def robots_view(self) -> list[dict[str, Any]]:
        return []

    def broker_view(self) -> dict[str, Any]:
        return dict(self.broker)

    def close(self) -> None:
        self.closed = True


def _worker(g: int, best: float, state: str = "alive") -> dict[str, Any]:
    return {"behaviour": "tracking", "worker": "tracking-0", "regime": "mutual", "generation": g, "generations": 6,
            "best_fitness": best, "measures": {"quality_tracking": 10.0 * g}, "partner_versions": {"docking": g},
            "rejected": 0, "rejected_by_reason": {}, "buffered": 0, "open": True, "state": state, "heartbeat_age": 0.1}


def test_curves_grow_from_heartbeats_and_the_page_says_what_is_wrong() -> None:
    src = BusSource(object(), run="r1")
    src._board_type = FakeBoard  # a board per run, as the real StatusBoard
    dash = Dashboard(bus=src)
    dash.refresh()
    board = src.boards["r1"]
    for g, best in ((1, 0.2), (1, 0.2), (2, 0.1), (3, 0.4)):
        board.workers = [_worker(g, best)]
        dash.refresh()
    v = dash.current()[1].runs[0]
    c = v.curves["tracking-0"][1]
    assert c.generation == [1, 2, 3] and c.best_so_far == [0.2, 0.2, 0.4] and c.measures["quality_tracking"][-1] == 30.0
    assert v.state == "running" and v.source == "bus" and v.regime == "mutual" and v.problems == []
    board.rejected = 4
    board.open = False
    board.broker = {**board.broker, "state": "down"}
    dash.refresh()
    text = render.problems_html(dash.current()[1])
    assert "4 messages on run r1" in text and "--key-file is not this run" in text and "no broker on the bus" in text
    src.close()
    assert board.closed


def test_a_run_seen_on_the_bus_takes_its_curves_from_its_directory_with_runs_dir(tmp_path: Path) -> None:
    _run_dir(tmp_path, "r1", generations=5)
    src = BusSource(object(), run="r1")
    src._board_type = FakeBoard
    dash = Dashboard(bus=src, runs_dir=tmp_path)
    dash.refresh()
    src.boards["r1"].workers = [_worker(5, 0.5)]
    dash.refresh()
    v = dash.current()[1].runs[0]
    assert v.source == "bus+files" and v.curves["tracking-0"][1].generation == [1, 2, 3, 4, 5]
    assert v.workers[0]["state"] == "alive" and v.broker["rejected"] == {"flood": 3}  # live state from the bus


# ---------------------------------------------------------------- the page's pieces
def test_the_tables_show_what_coevo_status_shows_escaped() -> None:
    from coevo.dashboard.model import RunView

    c = Curve()
    c.add(1, 0.25, {"quality_tracking": 12.0})
    w = {**_worker(1, 0.25), "worker": "<script>x</script>", "rejected_by_reason": {"wrong_key": 2}}
    view = View("t", runs=[RunView(run="r1", source="bus", state="running", workers=[w], broker={
        "state": "up", "stored": {"tracking": 1}, "rejected": {"flood": 3}}, curves={"tracking-0": ("tracking", c)})])
    html = render.workers_html(view)
    assert "<script>" not in html and "&lt;script&gt;" in html
    for text in ("1/6", "0.250", "QT=10%", "Dv1", "wrong_key 2", "alive"):
        assert text in html, text
    assert "flood 3" in render.runs_html(view) and "tracking:1" in render.runs_html(view)
    lines = render.curve_lines(view, "tracking")
    assert lines["xs"] == [[1], [1]] and lines["ys"] == [[0.25], [0.25]] and lines["run"] == ["r1", "r1"]
    assert render.curve_lines(view, "tracking", "measures")["ys"] == [[12.0]]


# ---------------------------------------------------------------- a comparison directory
def _comparison(tmp_path: Path) -> Path:
    from coevo.experiments.compare.experiment import CompareSpec

    out = tmp_path / "cmp"
    (out / "logs").mkdir(parents=True)
    spec = CompareSpec.make(regimes=("mutual", "independent"), runs=2)
    (out / "compare.json").write_text(json.dumps({"spec": json.loads(spec.model_dump_json()), "created": 0}))
    good = {"docking_success_rate": 40.0, "dock_choice": 20.0, "quality_tracking": 70.0}
    starved = {"docking_success_rate": 0.0, "dock_choice": 1.0, "quality_tracking": 40.0}
    for run, m in (("mutual-00", starved), ("independent-00", good)):
        d = _run_dir(out / "runs", run)
        (d / "summary.json").write_text(json.dumps({"interrupted": False, "measures": m}))
    _run_dir(out / "runs", "mutual-01", generations=2)  # running: its logs are fresh
    (out / "logs" / "independent-01.log").write_text("Traceback ...\n")
    old = time.time() - 1000
    os.utime(out / "logs" / "independent-01.log", (old, old))  # started, then nothing for long: failed
    return out


def test_a_comparison_shows_replicates_by_state_and_table_1_so_far(tmp_path: Path) -> None:
    out = _comparison(tmp_path)
    assert classify_dir(out) == "comparison"
    dash = Dashboard(target=out, stale=60)
    dash.refresh()
    view = dash.current()[1]
    c = view.comparison
    states = {r["run"]: r["state"] for r in c["replicates"]}
    assert states == {"mutual-00": "done", "independent-00": "done", "mutual-01": "running", "independent-01": "failed"}
    assert c["counts"] == {"done": 2, "running": 1, "failed": 1, "waiting": 0}
    assert c["table1"]["mutual"]["No Docking / Med"] == 1 and c["table1"]["independent"]["Good Docking / Hi"] == 1
    assert {r.run for r in view.runs} == {"mutual-00", "independent-00", "mutual-01"}  # their curves are on the page
    html = render.table1_html(view) + render.comparison_html(view)
    assert "Table 1" in html and "mutual so far" in html and "No Docking / Med" in html and "failed" in html
    # The Executive curve of the finished runs (each curve 0.1, 0.2, 0.3): its end and the mean of its last 10.
    ec = c["headline_curve"]
    assert set(ec) == {"mutual", "independent"} and ec["mutual"]["end"]["n"] == 1
    assert ec["mutual"]["end"]["mean"] == pytest.approx(0.3) and ec["mutual"]["last_generations"]["mean"] == pytest.approx(0.2)
    assert "Executive curve (finished runs)" in html and "0.30 (n = 1: too few runs for an interval)" in html


def test_a_comparison_page_has_table_1_beside_the_report_and_per_regime_lines_bands_and_a_run_selector(
        tmp_path: Path) -> None:
    from coevo.experiments.compare.table1 import REPORT_COUNTS

    out = _comparison(tmp_path)
    dash = Dashboard(target=out, stale=60)
    dash.refresh()
    executive = next(p for p in dash.current()[1].comparison["panels"] if p["behaviour"] == "executive")
    band, lines = render.regime_columns(executive, "mutual")
    # mutual-01 still going: drawn dotted, and one finished run makes no band yet
    assert lines["run"] == ["mutual-00", "mutual-01"] and lines["dash"] == ["solid", "dotted"]
    assert band["generation"] == []
    for run in ("mutual-01", "independent-01"):  # a second finished run per regime: a band
        d = out / "runs" / run
        if not d.exists():
            _run_dir(out / "runs", run)
        (d / "summary.json").write_text(json.dumps({"interrupted": False, "measures": {
            "docking_success_rate": 30.0, "dock_choice": 10.0, "quality_tracking": 65.0}}))
        with open(d / "workers" / "executive" / "curve.jsonl", "a") as f:
            f.write(_row(3, 0.6) if run == "mutual-01" else "")
    (out / "logs" / "independent-01.log").unlink()
    dash.refresh()
    view = dash.current()[1]
    c = view.comparison
    assert c["regimes"] == ["mutual", "independent"] and c["table1_report"] == REPORT_COUNTS
    head = render.table1_html(view)
    for g in ("mutual", "independent"):  # the report's count beside ours, in grey
        assert f'<span class="report">{sum(REPORT_COUNTS[g].values())}</span>' in head
    assert "No report yet" in render.verdict_html(view) and "below the report" in render.verdict_html(view)
    executive = next(p for p in c["panels"] if p["behaviour"] == "executive" and p["column"] == "best_fitness")
    band, lines = render.regime_columns(executive, "mutual", picked={"mutual-01"})
    # mutual-00's executive curve 0.1, 0.2, 0.3 and mutual-01's 0.1, 0.2, 0.6: their mean, and no interval from two runs
    assert band["generation"] == [1, 2, 3] and band["n"] == [2, 2, 2]
    assert band["mean"] == pytest.approx([0.1, 0.2, 0.45]) and all(math.isnan(v) for v in band["low"] + band["high"])
    assert band["regime"] == ["mutual"] * 3
    assert lines["run"] == ["mutual-00", "mutual-01"] and lines["dash"] == ["solid", "solid"]
    assert lines["width"] == [render.RUN_WIDTH, render.PICKED_WIDTH]  # the picked run thick, the other thin


def test_a_directory_claiming_to_be_a_comparison_but_broken_is_a_run_dir_error(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    out.mkdir()
    (out / "compare.json").write_text('{"spec": {"runs": "many"}}')
    with pytest.raises(RunDirError, match="not a comparison's settings"):
        Dashboard(target=out).refresh()


# ---------------------------------------------------------------- a study directory
def _finished(d: Path, measures: dict[str, float]) -> None:
    (d / "summary.json").write_text(json.dumps({"interrupted": False, "measures": measures}))


GOOD = {"docking_success_rate": 40.0, "dock_choice": 20.0, "quality_tracking": 70.0, "average_epoch_length": 7.0}
STARVED = {"docking_success_rate": 0.0, "dock_choice": 1.0, "quality_tracking": 40.0, "average_epoch_length": 3.0}


def test_a_half_written_study_shows_what_it_has_and_says_what_it_cannot_read(tmp_path: Path) -> None:
    """A study as a crash or a running runner leaves it: a cell not prepared yet, a cell with no runs, a run still
    going with a torn last line, a finished run whose curve is damaged; then a completion marker of another study."""
    from coevo.experiments.study.declaration import declare
    from coevo.experiments.study.experiment import COMPLETE, prepare_study, study_progress

    out = tmp_path / "study"
    spec = declare(factors=["max_lead=1,2,off", "regime=mutual"], settings={"runs": 2})
    prepare_study(out, spec, resume=False)
    assert classify_dir(out) == "study"
    dash = Dashboard(target=out, stale=60)
    dash.refresh()
    s = dash.current()[1].study
    assert (s["runs_done"], s["runs_total"], s["cells_done"], s["cells_total"]) == (0, 6, 0, 3)
    assert [c["state"] for c in s["cells"]] == ["not started"] * 3 and not s["complete"] and s["verdict"] is None
    assert s["default"] == "00-max_lead=1" and list(s["shown"]) == ["00-max_lead=1"]

    shutil.rmtree(out / "cells" / "02-max_lead=off")  # a crash before its folder was written: shown waiting
    runs = out / "cells" / "00-max_lead=1" / "runs"
    _finished(_run_dir(runs, "mutual-00"), STARVED)
    going = _run_dir(runs, "mutual-01", generations=2)
    with open(going / "workers" / "executive" / "curve.jsonl", "a") as f:
        f.write('{"generation": 3, "best_fi')  # a line being written
    damaged = _run_dir(out / "cells" / "01-max_lead=2" / "runs", "mutual-00")
    _finished(damaged, GOOD)
    with open(damaged / "workers" / "tracking" / "curve.jsonl", "a") as f:
        f.write('{"generation": 4, "best_fitness": 0.')  # a finished run's log cut short: the report cannot read it
    dash.want("01-max_lead=2")
    dash.refresh()
    view = dash.current()[1]
    s = view.study
    cells = {c["id"]: c for c in s["cells"]}
    assert s["runs_done"] == 2 == study_progress(out).runs_done and s["state"] == "running"
    assert cells["00-max_lead=1"]["state"] == "running" and cells["00-max_lead=1"]["counts"] == {
        "done": 1, "running": 1, "failed": 0, "waiting": 0}
    assert cells["02-max_lead=off"]["state"] == "not started" and cells["01-max_lead=2"]["state"] == "waiting"
    (row,) = cells["00-max_lead=1"]["rows"]  # the report's own row: 1 of 1 No Docking, Wilson's [21 %, 100 %]
    assert (row["n"], row["no_docking"]["k"]) == (1, 1) and row["no_docking"]["low"] == pytest.approx(0.2065, abs=1e-4)
    assert row["executive_end"]["mean"] == pytest.approx(0.3) and row["average_epoch_length"]["mean"] == 3.0
    assert [p for p in view.problems if "01-max_lead=2: a finished run cannot be read" in p], view.problems
    assert cells["01-max_lead=2"]["rows"][0]["n"] == 0
    assert set(s["shown"]) == {"00-max_lead=1", "01-max_lead=2"}  # the default and the cell a page asked for
    shown = s["shown"]["00-max_lead=1"]
    assert {r["run"]: r["state"] for r in shown["replicates"]} == {"mutual-00": "done", "mutual-01": "running"}
    page = (render.study_title_html(view) + render.study_progress_html(view) + render.study_verdict_html(view)
            + render.study_tables_html(view) + render.study_cell_note_html(view, "01-max_lead=2"))
    assert "2 of 6 runs finished" in page and "1/1 [21–100 %]" in page and "No report yet" in page
    assert "coevo compare --report-only --out" in page

    old = time.time() - 1000  # every file of it still for long: its running run failed, the study stopped
    for f in out.rglob("*"):
        os.utime(f, (old, old))
    dash.refresh()
    s = dash.current()[1].study
    assert s["state"] == "stopped" and "coevo study --resume --out" in s["why"]
    assert s["cells"][0]["state"] == "stopped" and "mutual-01: no progress" in s["cells"][0]["failed"][0]
    (out / COMPLETE).write_text(json.dumps({"spec_sha256": "another study's", "runs": 6}))
    dash.refresh()
    assert dash.current()[1].study["state"] != "finished"  # only a marker naming this very declaration says so


def test_a_study_of_learning_runs_shows_its_runs_and_measures_and_no_comparison(tmp_path: Path) -> None:
    """A study whose cells are coevo learn runs, part-way: a finished run, one under way (its log still empty: coevo
    learn --quiet writes it when it ends), one that failed, one not started; then everything still for long."""
    from bokeh.document import Document

    from coevo.dashboard.server import make_document
    from coevo.experiments.study.declaration import declare
    from coevo.experiments.study.experiment import prepare_study, study_jobs

    out = tmp_path / "study"
    spec = declare(factors=["world.target_speed=2,3"], settings={"learn": "tracking", "runs": 2})
    the_cells = prepare_study(out, spec, resume=False)
    done, going, failed, waiting = study_jobs(out, the_cells)  # run 0 of both cells, then run 1 of both
    (out / done.output).mkdir(parents=True)
    (out / done.output / "measures.json").write_text(json.dumps({"quality_tracking": 62.5, "collision_rate": 10.0,
                                                                 "best_fitness": 0.7}))
    (out / done.output / "timing.json").write_text(json.dumps({"seconds": 3.0}))
    (out / "logs").mkdir(exist_ok=True)
    (out / "logs" / f"{going.name}.log").write_text("")
    (out / "logs" / f"{failed.name}.log").write_text("ConfigError: something went wrong\n")
    dash = Dashboard(target=out, stale=60)
    dash.refresh()
    view = dash.current()[1]
    s = view.study
    assert s["kind"] == "learn" and s["behaviour"] == "tracking" and s["shown"] == {}
    assert (s["runs_done"], s["runs_total"], s["state"]) == (1, 4, "running")
    first, second = s["cells"]
    assert first["counts"] == {"done": 1, "running": 0, "failed": 1, "waiting": 0} and first["state"] == "stopped"
    assert "ConfigError: something went wrong" in first["failed"][0]
    assert second["counts"] == {"done": 0, "running": 1, "failed": 0, "waiting": 1} and second["state"] == "running"
    (row,) = first["rows"]
    assert row["n"] == 1 and row["measures"]["quality_tracking"]["mean"] == 62.5
    assert row["measures"]["quality_tracking"]["median"] == 62.5 and second["rows"][0]["n"] == 0
    page = render.study_progress_html(view) + render.study_tables_html(view)
    assert "Quality Tracking (%): mean [95 %] · median" in page and "62.50 (too few runs for an interval) · 62.50" in page
    assert "Table 1" not in page and "coevo compare" not in render.study_cell_note_html(view, first["id"])
    doc = Document()
    make_document(dash, [])(doc)  # the page as the server builds it: no cell selector, no comparison's panels
    assert doc.get_model_by_name("cell-selector") is None and doc.get_model_by_name("study") is not None
    assert "something went wrong" in doc.get_model_by_name("study-tables").text

    old = time.time() - 1000  # nothing moved for long: the run under way stopped with the study
    for f in out.rglob("*"):
        os.utime(f, (old, old))
    dash.refresh()
    s = dash.current()[1].study
    assert s["state"] == "stopped" and s["cells"][1]["state"] == "stopped"
    assert "no progress" in s["cells"][1]["failed"][0]


# ---------------------------------------------------------------- the command line's bad input
def _coevo(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["--log-level", "ERROR", *argv])
    return code, capsys.readouterr().err


def test_bad_input_is_one_line_and_status_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from coevo.runs.local import free_port

    (tmp_path / "empty").mkdir()
    key = tmp_path / "bad.key"
    key.write_text("not a key")
    key.chmod(0o600)
    cases = [
        (["dashboard", str(tmp_path / "empty")], "RunDirError: "),
        (["dashboard", "--key-file", str(key)], "ConfigError: --key-file is one run's key"),
        (["dashboard", "--run", "r1", "--key-file", str(key), "--connect", "tcp/127.0.0.1:9"], "ConfigError: key file"),
        (["dashboard", "--run", "r1", "--connect", f"tcp/127.0.0.1:{free_port()}", "--connect-timeout", "0"],
         "ServiceError: cannot open the zenoh dashboard session"),
        (["dashboard", "--runs-dir", str(tmp_path / "missing"), "--connect", "tcp/127.0.0.1:9"], "RunDirError: --runs-dir"),
        (["dashboard", str(tmp_path / "torn-study")], "RunDirError: "),
        (["dashboard", str(tmp_path / "not-a-study")], "RunDirError: "),
    ]
    (tmp_path / "torn-study").mkdir()
    (tmp_path / "torn-study" / "study.json").write_text('{"spec": {"na')
    (tmp_path / "not-a-study").mkdir()
    (tmp_path / "not-a-study" / "study.json").write_text('{"spec": {"name": "x", "seed": 0, "levels": []}}')
    for argv, start in cases:
        code, err = _coevo(argv, capsys)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith(start), (argv, err)


# ---------------------------------------------------------------- the page in a real browser
CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"

DEEP_TEXT = """
function deep(n) {
  let t = '';
  if (n.shadowRoot) t += deep(n.shadowRoot);
  for (const c of n.childNodes) t += c.nodeType === 3 ? c.textContent + ' ' : deep(c);
  return t;
}
return deep(document.body);
"""
# The points a curve's plot holds, as BokehJS has them (the plot itself is drawn on a canvas)
CURVE_POINTS = """
const doc = window.Bokeh && Bokeh.documents[0];
const src = doc && doc.get_model_by_name(arguments[0]);
if (!src) return -1;
const xs = src.data.xs;
let n = 0;
for (let i = 0; i < xs.length; i++) n += xs[i].length;
return n;
"""

# The robot's picture as the page holds it: its alt text and how many base64 characters its inline PNG has
ROBOT_IMAGE = """
function find(n) {
  if (n.shadowRoot) { const r = find(n.shadowRoot); if (r) return r; }
  for (const c of n.children || []) {
    if (c.tagName === 'IMG' && c.classList.contains('robot')) return c;
    const r = find(c); if (r) return r;
  }
  return null;
}
const img = find(document.body);
return img ? [img.alt, img.src.length, img.naturalWidth] : null;
"""


def _browser(tmp_path: Path) -> Any:
    if not (os.path.exists(CHROMIUM) and os.path.exists(CHROMEDRIVER)):
        pytest.skip(f"no headless browser: {CHROMIUM} and {CHROMEDRIVER} are Debian's chromium and chromium-driver "
                    "(.ci/run installs them; apt-get install -y chromium chromium-driver)")
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is in the test extra: pip install -e '.[test]'")
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1400,1200", f"--user-data-dir={tmp_path / 'chromium'}"):
        opts.add_argument(flag)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)  # the driver given: selenium downloads nothing


def _generations(text: str) -> dict[str, int]:
    """worker -> generation, from the workers' table as the page shows it ("tracking-0 tracking 3/30 ...")."""
    import re

    return {m.group(1): int(m.group(2)) for m in re.finditer(r"\b((?:tracking|docking|executive)-\d+) \S+ (\d+)/\d+", text)}


@pytest.mark.service
@pytest.mark.slow
def test_the_page_in_headless_chromium_follows_a_real_run(tmp_path: Path) -> None:
    from procs import coevo_proc, poll, stop

    from coevo.runs.discover import answers

    browser = _browser(tmp_path)
    procs: list[subprocess.Popen] = []
    try:
        run = coevo_proc("run", "--generations", "30", "--population", "6", "--episodes", "6", "--open", "--root",
                         str(tmp_path / "runs"), "--run", "watched", "--quiet", log=tmp_path / "run.log")
        procs.append(run)
        settings = tmp_path / "runs" / "watched" / "run.json"
        poll(settings.exists, 60, "the run's run.json")
        endpoint = json.loads(settings.read_text())["endpoint"]
        # its broker listening first: a broker that does not answer within 1 s sends the page to the files (tested
        # in test_a_run_is_followed_with_no_flags_and_a_gone_broker_is_said_at_once), which a loaded machine did here
        poll(lambda: answers(endpoint), 60, "the run's broker listening")
        dash, port = _dashboard_proc("--connect", endpoint, "--run", "watched", "--runs-dir", str(tmp_path / "runs"),
                                     log=tmp_path / "dashboard.log")
        procs.append(dash)
        browser.get(f"http://127.0.0.1:{port}/")
        text = lambda: browser.execute_script(DEEP_TEXT)  # noqa: E731
        first = poll(lambda: (g := _generations(text())) and len(g) == 3 and g, 60,
                     lambda: f"the three workers on the page: {text()[-600:]}")
        assert set(first) == {"tracking-0", "docking-1", "executive-2"}
        assert "coevo dashboard: run watched" in text() and "read-only" in text()
        points = poll(lambda: browser.execute_script(CURVE_POINTS, "curve-tracking") > 0 and
                      browser.execute_script(CURVE_POINTS, "curve-tracking"), 30, "a point on Tracking's curve")
        poll(lambda: any(_generations(text()).get(w, 0) > g for w, g in first.items()), 60,
             lambda: f"a generation moving on from {first}: {text()[-600:]}")
        poll(lambda: browser.execute_script(CURVE_POINTS, "curve-tracking") > points, 60, "Tracking's curve growing")
        # the robot, drawn from the run's newest policies once all three have published, with its rules
        img = poll(lambda: browser.execute_script(ROBOT_IMAGE), 60, lambda: f"the robot's picture: {text()[-600:]}")
        assert img[0] == "the robot of watched" and img[1] > 5_000 and img[2] > 100, img  # a decoded PNG
        # polled, not read once: a page caught while BokehJS re-renders the robot's Div (a newer policy) reads empty
        poll(lambda: re.search(r"Robot of watched: docking v\d+, executive v\d+, tracking v\d+", text()), 30,
             lambda: f"the robot's versions in its heading: {text()[-800:]}")
        poll(lambda: re.search(r"tracking: \d+ rules by strength.*?\d+ of \d+ rules fired", text()), 30,
             lambda: f"Tracking's rules with fire counts: {text()[-800:]}")
        time.sleep(1.5)
        shot = tmp_path / "dashboard.png"
        browser.save_screenshot(str(shot))
        assert shot.stat().st_size > 10_000
        if os.environ.get("COEVO_DASHBOARD_SCREENSHOT"):  # docs/dashboard.png is made this way
            shutil.copy(shot, os.environ["COEVO_DASHBOARD_SCREENSHOT"])
        from pages import check_page, open_page  # the page again at 1280 x 800, as every page (tests/pages.py)

        open_page(browser, port)
        title = "coevo dashboard: run watched (unverified: no --key-file)"
        check_page(browser, tmp_path / "live.png", picture="dashboard.png", title=title, heading=title,
                   headline=re.compile(r"executive-2 executive \d+/30"))
        page = browser.page_source
        assert "cdn.bokeh.org" not in page and "https://" not in page.split("<body")[0]  # nothing from the internet
    finally:
        browser.quit()
        for p in reversed(procs):
            stop(p)
    assert procs[1].returncode == 0, (tmp_path / "dashboard.log").read_text()


# A comparison's headline as the browser drew it: each element's box in the viewport's coordinates (the legend and
# the bands are drawn on a canvas: their boxes are BokehJS's, offset by their canvas's place on the page)
HEADLINE_BOXES = """
function find(n, pred) {
  if (n.shadowRoot) { const r = find(n.shadowRoot, pred); if (r) return r; }
  for (const c of n.children || []) { if (pred(c)) return c; const r = find(c, pred); if (r) return r; }
  return null;
}
const rect = (r) => [r.left, r.top, r.right, r.bottom];
const out = {viewport: [window.innerWidth, window.innerHeight], legends: [], bands: []};
const table = find(document.body, (e) => e.tagName === 'TABLE' && e.classList.contains('table1'));
if (table) {
  out.table1 = rect(table.getBoundingClientRect());
  out.table1_rows = [...table.rows].map((r) => [...r.cells].map((c) => c.textContent.trim()));
}
const verdict = find(document.body, (e) => e.classList && e.classList.contains('verdict'));
out.verdict = verdict ? verdict.textContent : null;
const doc = window.Bokeh && Bokeh.documents[0];
for (const m of doc ? doc.all_models : []) {
  if (m.type === 'ColumnDataSource' || !m.name) continue;
  const legend = m.name.startsWith('legend-'), band = m.name.startsWith('band-');
  if (!legend && !band) continue;
  const v = Bokeh.index.find_one(m);
  if (!v) continue;
  const c = v.plot_view.canvas_view.el.getBoundingClientRect();
  let b;
  if (legend) {
    b = [v.bbox.left, v.bbox.top, v.bbox.right, v.bbox.bottom];
    out.legends.push({name: m.name, box: [c.left + b[0], c.top + b[1], c.left + b[2], c.top + b[3]],
                      labels: m.items.map((i) => i.label.value)});
  } else {
    const g = v.glyph, xs = [...g.sx], ys = [...g.sy1, ...g.sy2];
    if (!xs.length) continue;
    out.bands.push({name: m.name, visible: m.visible, points: xs.length,
                    box: [c.left + Math.min(...xs), c.top + Math.min(...ys), c.left + Math.max(...xs), c.top + Math.max(...ys)]});
  }
}
return out;
"""

# The comparison opened is the session's (tests/procs.py: THREE_RUN_COMPARISON, which tests/test_compare.py reads too):
# 3 runs a regime, the fewest that draw a band (stats.MIN_RUNS), each as small as a run can be while its curves have 3
# points: the page's layout is what is tested, and nothing on the first screen grows with the runs (Table 1 has a row
# per class, the verdict scrolls in its box, the run selector starts empty).  Its cost is mostly start-ups: about
# 5 CPU-s a run, half of it its five processes starting; 10 a regime, as the report's Table 1, cost 14 runs more.
TINY_RUNS = 3


def _dashboard_proc(*args: str, log: Path) -> tuple[subprocess.Popen, int]:
    """``coevo dashboard ARGS --port P`` serving, and P: a free port, tried again if another process of the
    suite took it between its choice and the dashboard's bind (the test ran on, to a 60 s time-out, before)."""
    from procs import coevo_proc, poll

    from coevo.runs.local import free_port

    for _ in range(5):
        port = free_port()
        dash = coevo_proc("dashboard", *args, "--port", str(port), log=log)
        said = poll(lambda: (t := log.read_text()) and ("dashboard: http" in t or dash.poll() is not None) and t, 180,
                    "the dashboard's address")
        if "dashboard: http" in said:
            return dash, port
        if "Address already in use" not in said:
            raise AssertionError(f"the dashboard did not start: {said}")
    raise AssertionError("no free port for the dashboard after 5 tries")


def _first_screen(browser: Any, port: int, script: str, ready: Callable[[dict[str, Any]], Any], what: str,
                  shot: Path, env: str) -> dict[str, Any]:
    """The page at ``port`` on a 1280 x 800 screen once ``ready`` says it is drawn: ``script``'s boxes after the last
    layout pass.  A screenshot is kept at ``shot`` (and copied where ``env`` names, for the docs)."""
    from procs import poll

    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                            {"width": 1280, "height": 800, "deviceScaleFactor": 1, "mobile": False})
    browser.get(f"http://127.0.0.1:{port}/")
    poll(lambda: (b := browser.execute_script(script)) and ready(b) and b, 60,
         lambda: f"{what}: {browser.execute_script(script)}")
    time.sleep(1.0)  # the last layout pass
    page = browser.execute_script(script)
    assert page["viewport"] == [1280, 800], page["viewport"]
    browser.save_screenshot(str(shot))
    if os.environ.get(env):
        shutil.copy(shot, os.environ[env])
    return page


def _above_the_fold(box: list[float], viewport: list[int]) -> bool:
    left, top, right, bottom = box
    return 0 <= left < right <= viewport[0] and 0 <= top <= bottom <= viewport[1]


@pytest.mark.service
@pytest.mark.slow
def test_a_comparison_opens_with_its_headline_above_the_fold_in_headless_chromium(three_run_comparison: Path,
                                                                                  tmp_path: Path) -> None:
    """A real Table 1 comparison (the session's, tests/procs.py: 3 tiny runs a regime) opened at a laptop's
    1280 x 800: the legend, a band per regime and Table 1 with the report's counts are drawn inside the first screen,
    Table 1's counts are the report's (REPORT_COUNTS) and the runs' (results.json), and the verdict is the report's."""
    from procs import stop

    from coevo.experiments.compare.table1 import CLASSES, REPORT_COUNTS

    browser = _browser(tmp_path)
    dash = None
    try:
        out = three_run_comparison  # read-only: the dashboard only reads it
        results = json.loads((out / "results.json").read_text())
        assert results["runs_finished"] == 2 * TINY_RUNS
        dash, port = _dashboard_proc(str(out), log=tmp_path / "dashboard.log")
        shot = tmp_path / "comparison.png"
        page = _first_screen(browser, port, HEADLINE_BOXES,
                             lambda b: b.get("table1") and len({x["name"] for x in b["bands"]}) == 2 and b["legends"],
                             "Table 1, the legends and the bands drawn", shot,
                             "COEVO_DASHBOARD_COMPARE_SCREENSHOT")  # docs/dashboard-compare.png is made this way
        viewport = page["viewport"]
        from pages import check_page  # what a screenshot of every page is checked for (tests/pages.py)

        check_page(browser, shot, picture="dashboard-compare.png", title=f"coevo dashboard: comparison {out}",
                   heading=f"coevo dashboard: comparison {out}", headline="Table 1")

        # Table 1: inside the first screen, a column of the runs' counts and one of the report's per regime
        assert _above_the_fold(page["table1"], viewport), page["table1"]
        head, *rows = page["table1_rows"]
        assert head == ["Table 1", "mutual so far", "report", "independent so far", "report"], head
        assert [r[0] for r in rows] == [*CLASSES, "runs finished"]
        for j, g in ((1, "mutual"), (3, "independent")):
            assert [int(r[j]) for r in rows[:-1]] == [results["table1"][g][c] for c in CLASSES], (g, rows)
            assert [int(r[j + 1]) for r in rows[:-1]] == [REPORT_COUNTS[g].get(c, 0) for c in CLASSES], (g, rows)
            assert rows[-1][j:j + 2] == [str(TINY_RUNS), str(sum(REPORT_COUNTS[g].values()))]
        assert page["verdict"] and results["verdict"].split("\n\n")[-1][:200] in page["verdict"]

        # a legend naming both regimes, and a band per regime, inside the first screen
        first = [x for x in page["legends"] if _above_the_fold(x["box"], viewport)]
        labels = [f"mutual, {TINY_RUNS} runs", f"independent, {TINY_RUNS} runs"]
        assert first and all(x["labels"] == labels for x in first), page["legends"]
        for regime in ("mutual", "independent"):
            bands = [x for x in page["bands"] if x["name"] == f"band-{regime}" and x["visible"]]
            seen = [x for x in bands if _above_the_fold(x["box"], viewport) and x["box"][2] - x["box"][0] > 100
                    and x["box"][3] > x["box"][1]]
            assert len(seen) >= 1 and all(x["points"] == 3 for x in seen), (regime, bands)  # a point per generation
        assert shot.stat().st_size > 20_000
    finally:
        browser.quit()
        if dash is not None:
            stop(dash)
    assert dash.returncode == 0, (tmp_path / "dashboard.log").read_text()
    assert "Traceback" not in (tmp_path / "dashboard.log").read_text()


# ---------------------------------------------------------------- a real study, on the page
#: One run at a time: the same CPU as two, twice the wall time, so the study is still in progress when the
#: dashboard's first page is read (with two at a time the four tiny runs were done first in 2 of a day's runs, quiet
#: and under load: "the study ended before its page was read").
TINY_STUDY = ["--factor", "max_lead=1,off", "--factor", "regime=mutual", "--runs", "2", "--generations", "3",
              "--population", "6", "--episodes", "10", "--ga", "best_episodes=10", "--ga", "initial_rules=8",
              "--measure-epochs", "5", "--jobs", "1", "--seed", "3"]


def _served(port: int) -> Any:
    """The page's Bokeh document as the server sends it to a browser opening http://127.0.0.1:PORT/: a session of
    its own, opened with the token the server signed into the page (it signs its session ids); None when the server
    answers 503 (new pages come at most one per 2 s after a burst)."""
    import urllib.error
    import urllib.request

    from bokeh.client.session import ClientSession
    from bokeh.util.token import get_session_id

    class Served(ClientSession):
        def __init__(self, token: str) -> None:
            self.served_token = token
            super().__init__(session_id=get_session_id(token), websocket_url=f"ws://127.0.0.1:{port}/ws")

        @property
        def token(self) -> str:
            return self.served_token

    try:
        page = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=60).read().decode()
    except urllib.error.HTTPError as exc:
        if exc.code == 503:
            time.sleep(1.0)  # a token comes back in 2 s
            return None
        raise
    found = re.search(r'"token":"([^"]+)"', page)
    assert found, page[:2000]
    session = Served(found.group(1))
    try:
        session.pull()
        return session.document
    finally:
        session.close()


def _text(doc: Any, name: str) -> str:
    """What a Div of the served document says, without its markup."""
    import html as html_lib

    return " ".join(html_lib.unescape(re.sub(r"<style>.*?</style>|<[^>]+>", " ", doc.get_model_by_name(name).text)).split())


def _runs_finished(text: str) -> int:
    found = re.search(r"(\d+) of 4 runs finished", text)
    assert found, text[:1000]
    return int(found.group(1))


def _cell_rows_html(doc: Any) -> dict[str, list[str]]:
    """cell -> its row's cells, from the study's table as served."""
    import html as html_lib

    table = doc.get_model_by_name("study").text.split("study-cells", 2)[-1]
    out = {}
    for tr in re.findall(r"<tr>(.*?)</tr>", table)[1:]:
        cells = [html_lib.unescape(re.sub(r"<[^>]+>", "", c)).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", tr)]
        out[cells[0]] = cells
    return out


# The study's headline as the browser drew it: each element's box in the viewport's coordinates
STUDY_BOXES = """
function find(n, pred) {
  if (n.shadowRoot) { const r = find(n.shadowRoot, pred); if (r) return r; }
  for (const c of n.children || []) { if (pred(c)) return c; const r = find(c, pred); if (r) return r; }
  return null;
}
const rect = (r) => [r.left, r.top, r.right, r.bottom];
const out = {viewport: [window.innerWidth, window.innerHeight]};
const progress = find(document.body, (e) => e.classList && e.classList.contains('study-progress'));
if (progress) { out.progress = rect(progress.getBoundingClientRect()); out.progress_text = progress.textContent; }
const table = find(document.body, (e) => e.tagName === 'TABLE' && e.classList.contains('study-cells'));
if (table) {
  out.table = rect(table.getBoundingClientRect());
  out.rows = [...table.rows].map((r) => [...r.cells].map((c) => c.textContent.trim()));
}
const select = find(document.body, (e) => e.tagName === 'SELECT');
if (select) out.selector = rect(select.getBoundingClientRect());
const cell = find(document.body, (e) => e.tagName === 'TABLE' && e.classList.contains('cell-table1'));
if (cell) out.cell_table1 = rect(cell.getBoundingClientRect());
return out;
"""


@pytest.mark.service
@pytest.mark.slow
class TestAStudyOnThePage:
    """One tiny real study (2 cells x 2 Mutual runs: about a minute on 2 shared cores) for both tests, which one
    xdist worker runs in order (tests/conftest.py keeps a class together): the dashboard is started on the study as
    soon as its study.json is written, while its runs go on."""

    @pytest.fixture(scope="class")
    @classmethod
    def study(cls, tmp_path_factory: pytest.TempPathFactory) -> Any:
        import signal

        from procs import poll, stop

        tmp = tmp_path_factory.mktemp("study-page")
        out = tmp / "study"
        with open(tmp / "study.log", "wb") as log:
            proc = subprocess.Popen([sys.executable, "-m", "coevo", "study", "--out", str(out), "--quiet", *TINY_STUDY],
                                    stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        dash = None
        try:
            poll(lambda: (out / "study.json").exists() or proc.poll() is not None, 120, "the study's study.json")
            dash, port = _dashboard_proc(str(out), "--stale", "60", log=tmp / "dashboard.log")
            yield {"out": out, "proc": proc, "port": port, "tmp": tmp}
        finally:
            if proc.poll() is None:  # the study and every run under it
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            if dash is not None:
                stop(dash)
        said = (tmp / "dashboard.log").read_text()
        assert dash is not None and dash.returncode == 0, said[-3000:]
        assert "Traceback" not in said, said[said.index("Traceback") - 500:][:3000]

    def test_the_served_page_counts_the_study_as_its_runs_finish(self, study: dict[str, Any]) -> None:
        from procs import poll

        from coevo.experiments.study.experiment import study_progress
        from coevo.experiments.study.intervals import Proportion

        out, port, proc = study["out"], study["port"], study["proc"]
        before = study_progress(out).runs_done
        doc = poll(lambda: _served(port), 60, "the page")
        assert proc.poll() is None, "the study ended before its page was read: nothing in progress was seen"
        text = _text(doc, "study")
        first = _runs_finished(text)
        assert before <= first < 4 and "the study: finished" not in text, text[:600]
        assert "of 2 cells finished" in text
        assert [o[0] for o in doc.get_model_by_name("cell-selector").options] == ["00-max_lead=1", "01-max_lead=off"]

        # a run finishes: the page moves on (within the dashboard's next reads: the first read of a finished run
        # makes its record, a Docking probe, and its cell's intervals)
        done = poll(lambda: (n := study_progress(out).runs_done) > first and n, 300, "a run of the study finishing")
        poll(lambda: (d := _served(port)) is not None and _runs_finished(_text(d, "study")) >= done, 60,
             f"the page counting {done} runs finished")

        # the study ends: every run, both cells, finished, and the report's own numbers per cell
        assert proc.wait(timeout=600) == 0, (study["tmp"] / "study.log").read_text()[-3000:]
        progress = study_progress(out)
        assert progress.complete and progress.runs_done == 4

        def finished_page() -> Any:
            d = _served(port)
            return d if d is not None and "the study: finished" in _text(d, "study") else None

        from coevo.experiments.study.report import format_mean

        doc = poll(finished_page, 60, "the page saying the study finished")
        text = _text(doc, "study")
        assert "4 of 4 runs finished" in text and "2 of 2 cells finished" in text, text[:600]
        results = json.loads((out / "results.json").read_text())
        rows = _cell_rows_html(doc)
        assert set(rows) == {"00-max_lead=1", "01-max_lead=off"}
        for r in results["cell_rows"]:
            served = rows[r["cell"]]
            assert served[1:4] == ["finished", "2/2", "mutual"], served
            for col, key in ((4, "good_docking"), (5, "no_docking")):
                p = r[key]
                assert served[col] == Proportion(p["k"], p["n"], p["low"], p["high"]).text(), (key, served)
            e = r["executive_end"]
            expected = f"{e['mean']:.2f} [{e['low']:.2f}, {e['high']:.2f}]" if e["low"] is not None else format_mean(e, False)
            assert served[6] == expected, served  # two runs a cell: a mean and why it has no interval
        verdict = _text(doc, "study-verdict")
        first_line = results["verdict"].split("\n")[0].removeprefix("- ").replace("**", "")
        # (the page's bold verdict word reads "Not established :" as text: its markup ends before the colon)
        assert " ".join(first_line.split()[:8]) in " ".join(verdict.split()).replace(" :", ":"), verdict[:600]
        # the cell shown below: its Table 1 with Wilson intervals, and its regimes' panels with a band over its runs
        assert "Cell 00-max_lead=1 (max_lead 1): 2 done" in _text(doc, "table1")
        band = doc.get_model_by_name("band-0-mutual").data
        assert band["generation"] == [1, 2, 3] and band["n"] == [2, 2, 2]

    def test_a_finished_study_opens_with_its_headline_above_the_fold_in_headless_chromium(
            self, study: dict[str, Any], tmp_path: Path) -> None:
        from procs import poll

        browser = _browser(tmp_path)
        try:
            assert study["proc"].wait(timeout=600) == 0
            results = json.loads((study["out"] / "results.json").read_text())
            page = _first_screen(browser, study["port"], STUDY_BOXES,
                                 lambda b: b.get("table") and b.get("cell_table1") and
                                 "finished" in b.get("progress_text", ""),
                                 "the study's headline drawn", tmp_path / "study.png",
                                 "COEVO_DASHBOARD_STUDY_SCREENSHOT")  # docs/dashboard-study.png is made this way
            viewport = page["viewport"]
            from pages import check_page  # what a screenshot of every page is checked for (tests/pages.py)

            check_page(browser, tmp_path / "study.png", picture="dashboard-study.png",
                       title=f"coevo dashboard: study {study['out']}", heading="A study declared on the command line",
                       headline="4 of 4 runs finished")
            for what in ("progress", "table", "selector"):  # the headline, and the way to a cell, on the first screen
                assert _above_the_fold(page[what], viewport), (what, page[what])
            assert "4 of 4 runs finished" in page["progress_text"] and "the study: finished" in page["progress_text"]
            head, *rows = page["rows"]
            assert head == ["cell", "state", "runs done", "group", "Good Docking", "No Docking", "Executive end", "AEL"]
            by_cell = {r[0]: r for r in rows}
            for r in results["cell_rows"]:
                assert by_cell[r["cell"]][1:3] == ["finished", "2/2"]
                assert by_cell[r["cell"]][5].startswith(f"{r['no_docking']['k']}/2 ["), by_cell[r["cell"]]

            # another cell picked: its Table 1 and its panels replace the first's, in this page
            browser.execute_script("Bokeh.documents[0].get_model_by_name('cell-selector').value = '01-max_lead=off'")
            poll(lambda: "Cell 01-max_lead=off (max_lead off): 2 done" in browser.execute_script(DEEP_TEXT), 30,
                 lambda: f"the second cell shown: {browser.execute_script(DEEP_TEXT)[:1500]}")
            legends = browser.execute_script(HEADLINE_BOXES)["legends"]
            assert legends and all(x["labels"] == ["mutual, 2 runs, no band (needs 3)"] for x in legends), legends
        finally:
            browser.quit()


# ---------------------------------------------------------------- the robot, from the publication logs
def _publish(d: Path, behaviour: str, version: int, rules: Any) -> None:
    with open(d / "workers" / behaviour / "published.jsonl", "a") as f:
        f.write(json.dumps({"version": version, "behaviour": behaviour, "rules": rules.to_dict(), "fitness": 0.1}) + "\n")


def test_the_robot_is_drawn_from_the_newest_policies_once_every_agent_published_and_at_most_so_often(
        tmp_path: Path) -> None:
    import numpy as np

    from coevo.dashboard import render
    from coevo.dashboard.model import View
    from coevo.dashboard.robot import RobotPanel
    from coevo.policy.rules import random_ruleset
    from coevo.tasks import get_task

    task = get_task("fuel")
    d = _run_dir(tmp_path)
    panel = RobotPanel(d, every=10.0)
    assert not panel.update(now=0.0) and "waiting" in panel.picture.note  # nothing published yet
    _publish(d, "tracking", 1, task.initial_rules("tracking", task.world_settings()))
    _publish(d, "docking", 1, task.initial_rules("docking", task.world_settings()))
    assert panel.update(now=1.0) and not panel.picture.png  # the Executive has not published: said, not drawn
    assert "no robot yet" in panel.picture.note and "executive" in panel.picture.note
    _publish(d, "executive", 1, random_ruleset("executive", 4, np.random.default_rng(0)))
    assert not panel.update(now=5.0)  # ten seconds between drawings
    assert panel.update(now=11.0) and panel.picture.versions == {"docking": 1, "executive": 1, "tracking": 1}
    assert panel.picture.png and len(panel.picture.tables) == 3 and panel.picture.episodes >= 1
    page = render.robot_html(View("t", robot=panel.picture))
    assert 'class="robot"' in page and "data:image/png;base64," in page and "rules fired" in page
    from PIL import Image

    from coevo.dashboard.robot import DPI, TEXT_PX
    from coevo.scene.draw import SMALLEST_TEXT

    width = Image.open(io.BytesIO(base64.b64decode(panel.picture.png))).size[0]
    assert SMALLEST_TEXT * DPI / 72 >= TEXT_PX >= 12  # the smallest text, at the picture's own size
    assert width == pytest.approx(10.5 * DPI, abs=2) and width <= 1240  # its own size fits a laptop's page
    assert not panel.update(now=30.0)  # nothing newer: not drawn again
    _publish(d, "tracking", 2, task.initial_rules("tracking", task.world_settings()))
    assert panel.update(now=31.0) and panel.picture.versions["tracking"] == 2


def test_a_page_without_a_robot_says_why_and_how_to_have_one(tmp_path: Path) -> None:
    from coevo.dashboard.command import _no_robot

    # the case: --connect ENDPOINT --runs-dir ROOT, no --run and no --robot
    note = _no_robot(None, None, tmp_path / "runs", None, local=False)
    assert "every run on the bus" in note and f"--robot RUN (a run's name under {tmp_path / 'runs'})" in note
    assert "--runs-dir ROOT" in _no_robot(None, None, None, "r1", local=False)  # --run without its files
    assert "a run's name under" in _no_robot(tmp_path, "comparison", None, None, local=False)
    html = render.robot_html(View("t", robot_note=note))
    assert 'class="robot-note"' in html and "--robot RUN" in html
    assert render.robot_html(View("t")) == ""  # --no-robot: nothing asked for, nothing said


# ---------------------------------------------------------------- zero-config following
@pytest.mark.service
def test_a_run_is_followed_with_no_flags_and_a_gone_broker_is_said_at_once(tmp_path: Path) -> None:
    """`coevo run` says where it listens and how to follow it; the dashboard's model with no flags (the runs under
    runs/) follows it on its bus, then shows it done from its files, with no problem line; afterwards `coevo status`
    says it is done in one line, and a dashboard pointed at its gone broker says so at once."""
    from coevo.dashboard.model import LocalRuns
    from coevo.runs.local import free_port, wait_until

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    small = ["--generations", "4", "--population", "6", "--episodes", "10", "--ga", "best_episodes=10",
             "--ga", "initial_rules=8"]
    run = subprocess.Popen([sys.executable, "-m", "coevo", "run", "--regime", "mutual", "--run", "r1", "--listen",
                            endpoint, "--quiet", *small], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    source = LocalRuns(tmp_path / "runs")
    dash = Dashboard(bus=source)
    seen: set[tuple[str, str]] = set()
    try:
        first = [run.stdout.readline(), run.stdout.readline()]
        assert first == [f"run r1: its broker listens on {endpoint}, its files are in runs/r1\n",
                         "follow it with: coevo status --run r1  or  coevo dashboard\n"], first

        def look() -> set[tuple[str, str]]:
            dash.refresh()
            for r in dash.current()[1].runs:
                assert not r.problems, r.problems  # no "no broker" while it starts, nor after its normal end
                seen.add((r.source, r.state))
            return seen

        wait_until(lambda: ("bus+files", "running") in look(), 60, lambda: f"the run followed on its bus ({seen})")
        assert run.wait(120) == 0, run.stdout.read()
        wait_until(lambda: ("files", "done") in look(), 20, lambda: f"the run done from its files ({seen})")
    finally:
        source.close()
        if run.poll() is None:
            run.kill()
    t0 = time.monotonic()
    status = subprocess.run([sys.executable, "-m", "coevo", "status"], cwd=tmp_path, capture_output=True, text=True,
                            timeout=60)
    assert status.returncode == 0 and status.stdout == \
        "run r1: done (docking 4/4, executive 4/4, tracking 4/4), from its files in runs/r1\n", status
    gone = subprocess.run([sys.executable, "-m", "coevo", "dashboard", "--connect", endpoint], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert gone.returncode == 2 and gone.stderr.startswith(f"ServiceError: no broker answers at {endpoint}"), gone
    assert time.monotonic() - t0 < 20  # at once, not after a 30 s connect timeout each (two interpreters start here)
    port = free_port()
    t1 = time.monotonic()
    files = subprocess.Popen([sys.executable, "-m", "coevo", "dashboard", "--connect", endpoint, "--runs-dir", "runs",
                              "--port", str(port)], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert files.stdout.readline() == (f"dashboard: no broker answers at {endpoint}: showing the runs under runs "
                                           "from their files\n")
        # ... and it does: the page is served from the files (it went on to the bus and ended 30 s later, on a
        # ServiceError)
        served = files.stdout.readline()
        assert served == f"dashboard: http://127.0.0.1:{port}/ (read-only; Ctrl-C stops it)\n", served
        assert time.monotonic() - t1 < 25  # not after the bus's 30 s connect timeout
    finally:
        files.terminate()
        files.wait(20)


# ---------------------------------------------------------------- under load, bad paths, SIGTERM
def _rss_mb(pid: int) -> float:
    return next(int(x.split()[1]) for x in Path(f"/proc/{pid}/status").read_text().splitlines()
                if x.startswith("VmRSS")) / 1024


def _get(url: str, timeout: float = 60) -> int | str:
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(url, timeout=timeout) as r:
            r.read()
            return r.status
    except urllib.error.HTTPError as exc:
        return exc.code
    except OSError as exc:
        return type(exc).__name__


@pytest.mark.service
def test_200_page_loads_at_once_leave_it_answering_and_its_memory_bounded(tmp_path: Path) -> None:
    """The issue's burst: each load beyond the bound is answered 503 at once instead of building a page (0.3-0.5 s
    of CPU each); afterwards a new page comes within 5 s and memory stays under twice idle (the measured figures
    are in docs/faults.md)."""
    from collections import Counter
    from concurrent.futures import ThreadPoolExecutor

    from procs import poll, stop


    log = tmp_path / "dashboard.log"
    dash, port = _dashboard_proc(str(_run_dir(tmp_path)), log=log)
    try:
        url = f"http://127.0.0.1:{port}"
        assert _get(url + "/") == 200
        assert _get(url + "/static/%00") == 400  # a path no file system holds
        assert _get(url + "/?bokeh-session-id=chosen-by-the-client") == 403  # ids are made and signed by the server
        idle = _rss_mb(dash.pid)
        t0 = time.monotonic()
        with ThreadPoolExecutor(200) as pool:
            codes = list(pool.map(lambda _: _get(url + "/"), range(200)))
        burst = time.monotonic() - t0
        assert set(codes) <= {200, 503} and codes.count(200) >= 1 and burst < 60, (burst, Counter(codes))
        t1 = time.monotonic()
        poll(lambda: _get(url + "/", timeout=5) == 200, 5, "a new page after the burst")
        after = time.monotonic() - t1
        assert _rss_mb(dash.pid) < 2 * idle, (idle, _rss_mb(dash.pid))
        print(f"idle {idle:.0f} MB, burst {burst:.1f} s ({codes.count(200)} pages, {codes.count(503)} refused), "
              f"a page {after:.2f} s after, then {_rss_mb(dash.pid):.0f} MB")
    finally:
        stop(dash)
    assert "Traceback" not in log.read_text(), log.read_text()[-2000:]


@pytest.mark.service
@pytest.mark.parametrize("argv", [["dashboard"], ["status", "--run", "x"]])
def test_sigterm_ends_it_at_once_while_it_is_still_connecting(argv: list[str], tmp_path: Path) -> None:
    """A peer that takes the TCP connection and never speaks zenoh (nothing listening at all is said at once, see
    coevo.runs.discover): zenoh keeps trying for --connect-timeout (30 s), the process ends within 2 s of SIGTERM."""
    import signal
    import socket

    from procs import coevo_proc

    mute = socket.create_server(("127.0.0.1", 0), backlog=16)  # accepts (the kernel does), then says nothing
    p = coevo_proc(*argv, "--connect", f"tcp/127.0.0.1:{mute.getsockname()[1]}", log=tmp_path / "log")
    try:
        time.sleep(3)  # well inside the connect: the command is importing, then waiting for the router
        assert p.poll() is None, (tmp_path / "log").read_text()
        t0 = time.monotonic()
        p.send_signal(signal.SIGTERM)
        p.wait(timeout=10)
        assert time.monotonic() - t0 < 2, time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
        mute.close()
    assert "Traceback" not in (tmp_path / "log").read_text()


def test_a_finished_studys_verdict_keeps_the_smoke_test_warning() -> None:
    """The issue: a finished study's page dropped the "settings below the report's" line that its running page and
    its report.md show; a verdict is never shown without it."""
    from types import SimpleNamespace

    from coevo.dashboard import render

    caveat = "These settings are below the report's: generations 3 (the report's 50). This is a smoke test"
    study = {"caveat": caveat, "runs_done": 4, "runs_total": 4, "dir": "runs/s",
             "verdict": {"text": "- No detectable effect of max_lead on x.", "finished": 4, "expected": 4}}
    finished = render.study_verdict_html(SimpleNamespace(study=study))  # type: ignore[arg-type]
    shown = render._e(caveat)  # as the page escapes it
    assert "No detectable effect" in finished and shown in finished
    running = render.study_verdict_html(SimpleNamespace(study=study | {"verdict": None}))  # type: ignore[arg-type]
    assert "No report yet" in running and shown in running
    assert shown not in render.study_verdict_html(SimpleNamespace(study=study | {"caveat": ""}))  # type: ignore[arg-type]


def test_a_regimes_legend_counts_its_runs_in_words_and_says_when_there_is_no_band() -> None:
    from coevo.dashboard import render

    assert render.legend_label("mutual", 1, 0) == "mutual, 1 run, no band (needs 3)"  # not "1 runs"
    assert render.legend_label("mutual", 2, 1) == "mutual, 2 runs, no band (needs 3) (+1 going)"
    assert render.legend_label("independent", 10, 0) == "independent, 10 runs"
    assert render.legend_label("independent", 0, 2) == "independent, 0 runs (+2 going)"
