"""``coevo dynamics`` on a finished fuel-task Mutual run (the shared one of tests/procs.py), in process: the
cooperative reading (what the Executive would have earned with each version of Docking), ``--generations A:B``, and
every bad input one line naming the value, exit status 2, nothing written."""

from __future__ import annotations

import csv
import json
import os
import time
from pathlib import Path

import pytest
from procs import coevo_main, copy_of

from coevo.experiments.dynamics.matrix import versions_of, within
from coevo.rundir.layout import RunPaths


def _refused(run: Path, *extra: str, needle: str) -> None:
    before = sorted(p.name for p in run.iterdir()) if run.is_dir() else None
    r = coevo_main("dynamics", str(run), "--episodes", "2", "--quiet", *extra)
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert r.returncode == 2 and len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr, r.stderr
    if before is not None:
        assert sorted(p.name for p in run.iterdir()) == before  # nothing written, not even an empty dynamics/


@pytest.fixture
def run(finished_mutual: Path, tmp_path: Path) -> Path:
    return copy_of(finished_mutual, tmp_path)


def test_the_cooperative_reading_and_a_window_of_generations(run: Path) -> None:
    r = coevo_main("dynamics", str(run), "--episodes", "2", "--quiet")
    assert r.returncode == 0, r.stderr
    out = run / "dynamics"
    assert {"ciao-executive-docking.csv", "master-executive-docking.png", "ciao-docking-tracking.png"} <= \
        {p.name for p in out.iterdir()}
    rows = list(csv.DictReader(open(out / "ciao-executive-docking.csv")))
    docking = versions_of(RunPaths(run), "docking")
    assert len(rows) == len(versions_of(RunPaths(run), "executive").version)
    assert [k for k in rows[0] if k.startswith("docking@")] == [f"docking@{g}" for g in docking.generation]
    (out / "stale.csv").write_text("from before\n")
    r = coevo_main("dynamics", str(run), "--episodes", "2", "--quiet", "--generations", "2:3")
    assert r.returncode == 0, r.stderr
    assert not (out / "stale.csv").exists() and not list(run.glob(".dynamics*"))  # replaced whole
    rows = list(csv.DictReader(open(out / "ciao-executive-docking.csv")))
    kept = within(docking, 2, 3)
    assert [k for k in rows[0] if k.startswith("docking@")] == [f"docking@{g}" for g in kept.generation]
    assert all(g >= 2 for g in kept.generation[1:]) and len(kept.generation) <= len(docking.generation)


def test_a_run_still_going_or_stopped_is_refused_naming_its_worker(run: Path) -> None:
    done = run / "workers" / "docking" / "done.json"
    saved = json.loads(done.read_text())
    done.unlink()
    _refused(run, needle="its docking worker has no done.json")
    done.write_text(json.dumps({**saved, "finished": False, "generations": 2}))
    _refused(run, needle="docking worker stopped after 2 of 3 generations")


def test_a_damaged_run_directory_is_one_line(run: Path, tmp_path: Path) -> None:
    store = RunPaths(run).store_file("tracking")
    with open(store, "a") as f:
        f.write("{not json\n")
    _refused(run, needle=str(store.name))
    (run / "run.json").write_text("{")
    _refused(run, needle="run.json")
    _refused(tmp_path / "nowhere", needle="nowhere")


def test_a_run_with_one_behaviour_is_refused_naming_its_task(tmp_path: Path) -> None:
    one = tmp_path / "one"
    one.mkdir()
    (one / "run.json").write_text(json.dumps({"run": "one", "task": "corridor", "regime": "independent"}))
    _refused(one, needle="behaviours: corridor")


@pytest.mark.parametrize(("span", "needle"), [("0:4", "--generations 0:4: run small has generations 0 to 3"),
                                              ("3:1", "'3:1': A must not exceed B"), ("1-3", "'1-3'"),
                                              ("-1:2", "'-1:2'"), (":", "':'")])
def test_a_generation_range_outside_the_run_or_malformed_is_one_line(run: Path, span: str, needle: str) -> None:
    _refused(run, f"--generations={span}", needle=needle)


def _master_by_generation(ciao: Path, generations: int) -> dict[int, float]:
    """The generation-weighted master score, computed the plain way: for each generation g, the learner's version in
    play at g against the partner's version in play at every generation h (h with none left out)."""
    rows = list(csv.DictReader(open(ciao)))
    cols = [(int(k.split("@")[1]), k) for k in rows[0] if "@" in k]
    out = {}
    for g in range(1, generations + 1):
        mine = [r for r in rows if int(r["generation"]) <= g]
        if not mine:
            continue
        row = mine[-1]
        vals = []
        for h in range(1, generations + 1):
            theirs = [k for gen, k in cols if gen <= h]
            if theirs:
                vals.append(float(row[theirs[-1]]))
        out[g] = sum(vals) / len(vals)
    return out


def test_a_folder_of_runs_each_played_then_summarised_across_them(finished_mutual: Path, tmp_path: Path) -> None:
    folder = tmp_path / "many"
    (folder / "one").mkdir(parents=True)
    (folder / "two").mkdir()
    a, b = copy_of(finished_mutual, folder / "one"), copy_of(finished_mutual, folder / "two")
    going = copy_of(finished_mutual, folder)
    (going / "workers" / "executive" / "done.json").unlink()
    _refused(folder, needle="its executive worker has no done.json")
    assert not (a / "dynamics").exists() and not (folder / "logs").exists()
    import shutil
    shutil.rmtree(going)
    r = coevo_main("dynamics", str(folder), "--episodes", "2", "--quiet", "--jobs", "2")
    assert r.returncode == 0, r.stderr
    assert (a / "dynamics" / "dynamics.json").is_file() and (b / "dynamics" / "ciao-executive-docking.csv").is_file()
    rows = list(csv.DictReader(open(folder / "dynamics" / "summary-executive-docking.csv")))
    expected = _master_by_generation(a / "dynamics" / "ciao-executive-docking.csv", 3)
    assert rows and {r["group"] for r in rows} == {"mutual, model best"}
    assert {int(r["generation"]): (int(r["runs"]), float(r["mean"])) for r in rows} == \
        {g: (2, pytest.approx(v, abs=1e-6)) for g, v in expected.items()}
    rise = {(r["learner"], r["partner"]): r for r in json.loads((folder / "dynamics" / "rise.json").read_text())["rise"]}
    d = expected[3] - expected[min(expected)]  # two copies of one run: each rises by as much
    assert rise["executive", "docking"] == {"learner": "executive", "partner": "docking", "group": "mutual, model best",
                                            "first": min(expected), "last": 3, "runs": 2, "mean": pytest.approx(d, abs=2e-6),
                                            "low95": None, "high95": None, "rose": 2 * (d > 0), "fell": 2 * (d < 0),
                                            "same": 2 * (d == 0)}
    r = coevo_main("dynamics", str(a), "--jobs", "2")
    assert r.returncode == 2 and "--jobs and --cluster are for a folder of runs" in r.stderr, r.stderr


def test_the_dashboard_shows_a_finished_runs_dynamics_once_they_are_played(run: Path) -> None:
    from coevo.dashboard import render
    from coevo.dashboard.model import Dashboard, RunFiles

    files = RunFiles(run)
    assert files.read().dynamics is None
    dash = Dashboard(target=run)
    dash.refresh()
    before = dash.current()[0]
    assert render.dynamics_html(dash.current()[1]) == ""
    r = coevo_main("dynamics", str(run), "--episodes", "2", "--quiet")
    assert r.returncode == 0, r.stderr
    d = files.read().dynamics
    assert d is not None and d.played["episodes"] == 2
    names = [n for n, _ in d.pictures]
    assert names[:2] == ["master-tracking-docking.png", "ciao-tracking-docking.png"] and len(names) == 12
    assert all(png.startswith("iVBOR") for _, png in d.pictures)  # base64 of a PNG's signature
    dash.refresh()
    version, view = dash.current()
    html = render.dynamics_html(view)
    assert version != before and html.count("<img class=\"dynamics\"") == 12 and "Dynamics of small" in html


def test_jobs_n_plays_n_runs_at_a_time(tmp_path: Path) -> None:
    """--jobs 2 played four runs at once (each counted as half a slot, an offline learner's): its help says runs."""
    from coevo.experiments.dynamics.across import replicates
    from coevo.replicates.backends import LocalBackend

    reps = replicates(tmp_path, [tmp_path / "a", tmp_path / "b", tmp_path / "c"],
                      lambda r: {"episodes": 2, "seed": 1, "generations": [0, 3]})
    jobs = LocalBackend(2)
    busy = 0
    for rep in reps:
        if not jobs.room(busy, rep):
            break
        busy += rep.weight
    assert busy == 2 * reps[0].weight  # two started, the third waits


def test_a_folders_damaged_summary_is_shown_as_far_as_it_reads_and_never_breaks_the_page(tmp_path: Path) -> None:
    from coevo.dashboard import render
    from coevo.dashboard.model import Dashboard

    (tmp_path / "r1").mkdir()
    (tmp_path / "r1" / "run.json").write_text(json.dumps({"run": "r1", "task": "fuel", "regime": "mutual"}))
    (tmp_path / "dynamics").mkdir()
    dash = Dashboard(target=tmp_path)
    for runs, rise in [("{", "{"), ('{"runs": 3, "groups": []}', '{"rise": 5}'),
                       ('{"runs": ["r1"], "groups": {"r1": "mutual, model hall"}}',
                        '{"rise": [{"learner": "pursuer", "partner": "evader", "mean": "x", "low95": 0.1, '
                        '"high95": 0.2, "rose": 1}, 7]}')]:
        (tmp_path / "dynamics" / "runs.json").write_text(runs)
        (tmp_path / "dynamics" / "rise.json").write_text(rise)
        os.utime(tmp_path / "dynamics" / "runs.json", (time.time() + len(runs), time.time() + len(runs)))
        dash.refresh()
        html = render.dynamics_html(dash.current()[1])
    assert "Dynamics across 1 runs (mutual, model hall)" in html and "pursuer against evader" in html
    assert html.count("<tr>") == 2 and "[+0.100, +0.200]" in html and ">?<" in html
