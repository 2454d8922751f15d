"""One tiny comparison under the hall of fame on the pursuit task (its installed package), shared by every check
here: ``coevo compare --model hall`` (one regime, two runs), ``coevo check`` replay exact on one of its runs,
``coevo dynamics`` over the folder on a local Dask cluster (``--cluster local:2``), the summary's rise computed
again the plain way from the runs' own matrices, and the dashboard in headless Chromium showing the summary for the
comparison and the matrices of one finished run."""

from __future__ import annotations

import csv
import json
import os
import re
from pathlib import Path
from typing import Any

import pytest
from test_dashboard import DEEP_TEXT, _browser, _dashboard_proc
from test_dynamics import _master_by_generation
from test_own_task import _run, pursuit_site  # noqa: F401  (a fixture: the example installed once per session)

GENERATIONS = 3
TINY = ["--task", "pursuit", "--regimes", "mutual", "--model", "hall", "--ga", "initial=random", "--runs", "2",
        "--generations", str(GENERATIONS), "--population", "4", "--episodes", "4", "--ga", "best_episodes=4", "--ga",
        "initial_rules=8", "--measure-epochs", "2", "--jobs", "2", "--seed", "5210", "--quiet"]

# Every <img class="dynamics"> on the page (BokehJS puts a Div's HTML in a shadow root): its alt, its decoded width
DYNAMICS_IMAGES = """
const out = [];
function walk(n) {
  if (n.shadowRoot) walk(n.shadowRoot);
  for (const c of n.children || []) {
    if (c.tagName === 'IMG' && c.classList.contains('dynamics')) out.push([c.alt, c.naturalWidth]);
    walk(c);
  }
}
walk(document.body);
return out;
"""


@pytest.fixture(scope="class")
def cmp(pursuit_site: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str]:  # noqa: F811
    """(the comparison, the pursuit site, what coevo dynamics said), made once for the class below."""
    cwd = tmp_path_factory.mktemp("hall-cmp")
    r = _run(["coevo", "compare", "--out", "cmp", *TINY], pursuit_site, cwd, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    r = _run(["coevo", "dynamics", "cmp", "--cluster", "local:2", "--episodes", "2", "--quiet"], pursuit_site, cwd,
             timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    return cwd / "cmp", pursuit_site, r.stdout


@pytest.mark.service
@pytest.mark.slow
class TestAHallComparisonsDynamics:
    def test_the_hall_is_recorded_and_one_run_replays_exactly(self, cmp: tuple[Path, Path, str]) -> None:
        out, site, _ = cmp
        runs = sorted((out / "runs").iterdir())
        assert [r.name for r in runs] == ["mutual-00", "mutual-01"]
        for run in runs:
            settings = json.loads((run / "run.json").read_text())
            assert (settings["task"], settings["model"], settings["hall_sample"]) == ("pursuit", "hall", 3)
            assert settings["ga"]["initial"] == "random"
        r = _run(["coevo", "check", "cmp/runs/mutual-01"], site, out.parent)
        assert r.returncode == 0 and "replay exact" in r.stdout, r.stdout + r.stderr

    def test_the_cluster_played_each_run_and_the_rise_is_each_runs_last_minus_first(
            self, cmp: tuple[Path, Path, str]) -> None:
        out, _, said = cmp
        assert "2 runs (mutual, model hall)" in said and "rise.json" in said, said
        for run in sorted((out / "runs").iterdir()):
            played = json.loads((run / "dynamics" / "dynamics.json").read_text())
            assert played["episodes"] == 2 and played["generations"] == [0, GENERATIONS]
        rise = json.loads((out / "dynamics" / "rise.json").read_text())["rise"]
        assert {(r["learner"], r["partner"]) for r in rise} == {("pursuer", "evader"), ("evader", "pursuer")}
        for r in rise:
            scores = [_master_by_generation(run / "dynamics" / f"ciao-{r['learner']}-{r['partner']}.csv", GENERATIONS)
                      for run in sorted((out / "runs").iterdir())]
            first = max(min(s) for s in scores)  # a side's generation-1 best may not have been met (pacing)
            d = [s[GENERATIONS] - s[first] for s in scores]
            assert (r["group"], r["first"], r["last"], r["runs"]) == ("mutual, model hall", first, GENERATIONS, 2)
            assert r["mean"] == pytest.approx(sum(d) / 2, abs=2e-6)
            assert (r["rose"], r["fell"], r["same"]) == (sum(x > 1e-9 for x in d), sum(x < -1e-9 for x in d),
                                                         sum(abs(x) <= 1e-9 for x in d))
            assert r["low95"] is None  # two runs: no interval
            summary = list(csv.DictReader(open(out / "dynamics" / f"summary-{r['learner']}-{r['partner']}.csv")))
            last = [row for row in summary if int(row["generation"]) == GENERATIONS]
            assert float(last[0]["mean"]) == pytest.approx(sum(s[GENERATIONS] for s in scores) / 2, abs=2e-6)

    def test_the_dashboard_shows_the_summary_for_the_comparison_and_the_matrices_for_one_run(
            self, cmp: tuple[Path, Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
        from procs import poll, stop

        out, site, _ = cmp
        monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH")) if p))
        browser = _browser(tmp_path)
        procs = []
        try:
            for target, expected, heading in [
                    (out, ["summary-evader-pursuer.png", "summary-pursuer-evader.png"],
                     "Dynamics across 2 runs (mutual, model hall)"),
                    (out / "runs" / "mutual-00", ["master-pursuer-evader.png", "ciao-pursuer-evader.png",
                                                  "master-evader-pursuer.png", "ciao-evader-pursuer.png"],
                     "Dynamics of mutual-00")]:
                dash, port = _dashboard_proc(str(target), log=tmp_path / f"dashboard-{len(procs)}.log")
                procs.append(dash)
                browser.get(f"http://127.0.0.1:{port}/")
                images: Any = poll(lambda: (i := browser.execute_script(DYNAMICS_IMAGES)) and len(i) >= len(expected)
                                   and all(w > 100 for _, w in i) and i, 90,
                                   lambda: f"the dynamics pictures of {target.name}: "
                                           f"{browser.execute_script(DYNAMICS_IMAGES)}")
                assert [alt for alt, _ in images] == expected, images
                text = browser.execute_script(DEEP_TEXT)
                assert heading in text, text[-1500:]
                if target == out:  # the rise's table: a row per pair, the generations it spans
                    # (its 2 runs; the first generation both runs have, which the runs' timing decides, to the last)
                    assert re.search(r"pursuer against evader mutual, model hall 2 \d+ → \d+", " ".join(text.split())), \
                        text[-1500:]
                stop(dash)
        finally:
            browser.quit()
            for p in procs:
                stop(p)
        for i in range(len(procs)):  # (its exit status is not asked: on a loaded machine SIGTERM's 10 s can pass)
            log = (tmp_path / f"dashboard-{i}.log").read_text()
            assert "Traceback" not in log, log
