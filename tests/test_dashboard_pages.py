"""The dashboard's pages read true (issue 55): a study declared on the command line is not "Study study"; a study's
findings come before its dozen test lines; a panel of a measure that cannot be negative starts at 0 (an all-zero
panel read "% of fresh starts" down to -1); a comparison's regimes are told apart by colour-blind-safe colours and by
their bands' hatching and edges, not only by two colours whose overlap blends into a third."""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from coevo.dashboard import render


def _study(**kw: Any) -> Any:
    return SimpleNamespace(study={"dir": "runs/s", "factors": "max_lead", "caveat": "", "runs_done": 4,
                                  "runs_total": 4, **kw})


def test_a_study_declared_on_the_command_line_is_not_titled_study_study() -> None:
    declared = render.study_title_html(_study(name="study"))  # the declaration's default name
    assert "Study study" not in declared and "A study declared on the command line" in declared
    assert "Study mutual-failure" in render.study_title_html(_study(name="mutual-failure"))


def test_a_studys_findings_in_words_come_before_its_tests() -> None:
    text = "\n".join([*(f"- No detectable effect of f{i} on x." for i in range(12)),
                      "Docking starved (No Docking) in most runs of: 00-a."])
    html = render.study_verdict_html(_study(verdict={"text": text, "finished": 4, "expected": 4}))
    assert html.index("Docking starved") < html.index("No detectable effect of f0")


def test_a_panel_of_a_measure_that_cannot_be_negative_starts_at_zero_and_spans_a_tenth_of_its_scale() -> None:
    from coevo.dashboard.server import _plain_figure

    pct = _plain_figure("p", "Docking alone", "% of fresh starts", height=200, top=100.0)
    fitness = _plain_figure("f", "Executive learning curve", "generation's best fitness", height=200, top=1.0)
    measures = _plain_figure("m", "docking: docks (solid) (%)", "%", height=200)
    other = _plain_figure("o", "something", "metres", height=200)
    assert (pct.y_range.start, pct.y_range.min_interval) == (0, 10.0)
    assert (fitness.y_range.start, fitness.y_range.min_interval) == (0, 0.1)
    assert (measures.y_range.start, measures.y_range.min_interval) == (0, 10.0)
    assert math.isnan(other.y_range.start)  # a measure whose sign is unknown keeps Bokeh's own range (unset: NaN)


def _srgb_to_linear(c: float) -> float:
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


def _deuteranope(hex_colour: str) -> tuple[float, float, float]:
    """How a deuteranope sees a colour (Viénot, Brettel and Mollon's 1999 simulation), in linear RGB."""
    r, g, b = (_srgb_to_linear(int(hex_colour[i:i + 2], 16) / 255) for i in (1, 3, 5))
    return (0.29031 * r + 0.70969 * g, 0.29031 * r + 0.70969 * g, -0.02197 * r + 0.02197 * g + b)


def test_the_regimes_colours_stay_apart_for_a_deuteranope_and_each_band_has_its_own_hatching() -> None:
    seen = [_deuteranope(c) for c in render.REGIME_COLOURS[:4]]
    for i in range(len(seen)):
        for j in range(i + 1, len(seen)):
            assert sum((a - b) ** 2 for a, b in zip(seen[i], seen[j])) ** 0.5 > 0.1, (render.REGIME_COLOURS[i],
                                                                                     render.REGIME_COLOURS[j])
    old_red, old_green = _deuteranope("#d62728"), _deuteranope("#2ca02c")  # what the first two regimes were
    assert sum((a - b) ** 2 for a, b in zip(old_red, old_green)) ** 0.5 < 0.1  # ... one colour to a deuteranope
    assert len({render.regime_hatch(i) for i in range(len(render.REGIME_COLOURS))}) == len(render.REGIME_COLOURS)


def test_a_closed_tab_leaves_no_warnings_in_the_terminal_and_other_warnings_stay() -> None:
    """Bokeh logged "Failed sending message as connection was closed" for each update a closed tab missed (7 a tab)."""
    import logging

    from bokeh.server.views import ws

    from coevo.dashboard.server import CLOSED_TAB, quiet_closed_tabs

    seen: list[str] = []
    handler = logging.Handler()
    handler.emit = lambda record: seen.append(record.getMessage())  # type: ignore[method-assign]
    ws.log.addHandler(handler)
    level, disabled = ws.log.level, logging.root.manager.disable
    ws.log.setLevel(logging.WARNING)  # whatever an earlier test of the session left it at
    logging.disable(logging.NOTSET)
    try:
        quiet_closed_tabs()
        quiet_closed_tabs()  # once is enough, twice adds nothing
        ws.log.warning(CLOSED_TAB)
        ws.log.warning("WebSocket connection opened")
    finally:
        ws.log.removeHandler(handler)
        ws.log.setLevel(level)
        logging.disable(disabled)
    assert seen == ["WebSocket connection opened"]
    assert len(ws.log.filters) == 1
    import inspect

    assert f'log.warning("{CLOSED_TAB}")' in inspect.getsource(ws)  # Bokeh still says it so: the filter still bites


def test_a_band_of_a_rate_is_cut_at_its_range_and_its_panel_says_so() -> None:
    """Three runs at 0, 0 and 100 % give a t interval of 33 % [−110, 177]: the band is cut at 0 and 100 (its measure's
    range, the panel's 0 to its top) and the panel's title says so (its legends have no room at 1280 px); a band
    inside the range is not marked."""
    from coevo.dashboard.compare import ComparisonFiles
    from coevo.experiments.compare.table1 import PANELS

    rate = next(p for p in PANELS if p.column == "dock_choice")
    assert rate.bounds == (0.0, 100.0) and PANELS[0].bounds == (0.0, 1.0)
    lines = [{"run": f"r{i}", "state": "done", "generation": [1, 2], "value": [v, 5.0 + i]}
             for i, v in enumerate((0.0, 0.0, 100.0))]
    whole = ComparisonFiles._band(lines)
    cut = ComparisonFiles._band(lines, rate.bounds)
    assert whole is not None and cut is not None
    assert whole["low"][0] < -100 and whole["high"][0] > 170 and whole["clipped"] == []
    assert (cut["low"][0], cut["high"][0]) == (0.0, 100.0) and cut["mean"] == whole["mean"]
    assert (cut["low"][1], cut["high"][1]) == (whole["low"][1], whole["high"][1])  # inside the range: untouched
    assert cut["clipped"] == [0.0, 100.0]
    panel = {"groups": {"mutual": {"lines": lines, "band": cut}, "independent": {"lines": [], "band": None}}}
    assert render.panel_title("Docking picked", panel) == "Docking picked (bands clipped at 0 and 100)"
    panel["groups"]["mutual"]["band"] = whole
    assert render.panel_title("Docking picked", panel) == "Docking picked"


def test_regimes_png_draws_the_dashboards_colour_blind_safe_colours_not_red_and_green(tmp_path: Any) -> None:
    """The report's regimes.png drew Mutual in matplotlib's red and Independent in its green (one colour to a
    deuteranope); it draws them in the dashboard's colours now: each mean line's colour is in the picture, and
    neither the old red nor the old green is."""
    import numpy as np
    from matplotlib.image import imread

    from coevo.experiments.compare.plots import figure_regimes
    from coevo.experiments.compare.table1 import PANELS

    def runs(level: float) -> dict[str, Any]:
        return {f"r{i}": {"executive": {"best_fitness": [level, level + 0.1 * i, level + 0.05]}} for i in range(3)}

    path = tmp_path / "regimes.png"
    figure_regimes({"mutual": runs(0.2), "independent": runs(0.6)}, path, PANELS[:1])
    pixels = (imread(path)[..., :3] * 255).round().astype(int).reshape(-1, 3)
    seen = {tuple(p) for p in np.unique(pixels, axis=0)}

    def rgb(hex_colour: str) -> tuple[int, int, int]:
        return tuple(int(hex_colour[i:i + 2], 16) for i in (1, 3, 5))  # type: ignore[return-value]

    assert rgb(render.REGIME_COLOURS[0]) in seen and rgb(render.REGIME_COLOURS[1]) in seen
    assert rgb("#d62728") not in seen and rgb("#2ca02c") not in seen


# ---------------------------------------------------------------- every page in headless Chromium at 1280 x 800
# The comparison's and the study's pages are checked by their own browser tests in tests/test_dashboard.py (on the
# comparison and the study they make: each calls pages.check_page); here the pages of a finished run, of a directory
# of runs and of a study of learning runs, on the session's shared finished run and one tiny learning study.
TINY_LEARN_STUDY = ["--learn", "tracking", "--factor", "world.target_speed=2,3", "--runs", "1", "--generations", "2",
                    "--population", "4", "--episodes", "4", "--measure-epochs", "2", "--jobs", "2", "--quiet"]


@pytest.mark.service
@pytest.mark.slow
class TestEveryPageInChromium:
    """One browser and three dashboards for the three pages (tests/conftest.py keeps a class on one xdist worker)."""

    @pytest.fixture(scope="class")
    @classmethod
    def served(cls, finished_mutual: Path, tmp_path_factory: pytest.TempPathFactory) -> Any:
        import subprocess
        import sys

        from procs import copy_of, stop
        from test_dashboard import _browser, _dashboard_proc

        tmp = tmp_path_factory.mktemp("pages")
        (tmp / "runs").mkdir()
        run = copy_of(finished_mutual, tmp / "runs")  # the dashboard reads it; a copy all the same
        study = tmp / "learn-study"
        made = subprocess.run([sys.executable, "-m", "coevo", "study", "--out", str(study), *TINY_LEARN_STUDY],
                              capture_output=True, text=True, timeout=900, check=False)
        assert made.returncode == 0, made.stdout + made.stderr
        browser = _browser(tmp)
        dashes = []
        try:
            ports = {}
            for name, target in (("run", run), ("runs", tmp / "runs"), ("learn-study", study)):
                dash, ports[name] = _dashboard_proc(str(target), log=tmp / f"dashboard-{name}.log")
                dashes.append(dash)
            yield {"browser": browser, "ports": ports, "run": run, "runs": tmp / "runs", "study": study, "tmp": tmp}
        finally:
            browser.quit()
            for dash in dashes:
                stop(dash)
        for name in ("run", "runs", "learn-study"):
            said = (tmp / f"dashboard-{name}.log").read_text()
            assert "Traceback" not in said, said[-3000:]

    def test_a_finished_runs_page(self, served: dict[str, Any]) -> None:
        from pages import check_page, open_page

        browser, run = served["browser"], served["run"]
        open_page(browser, served["ports"]["run"])
        title = f"coevo dashboard: run {run}"
        facts = check_page(browser, served["tmp"] / "run.png", picture="dashboard-run.png", title=title, heading=title,
                           headline=re.compile(r"executive-\d+ executive 3/3"))
        assert "Quality Tracking" in facts["text"] and "read-only" in facts["text"]

    def test_a_directory_of_runs_page(self, served: dict[str, Any]) -> None:
        from pages import check_page, open_page

        browser = served["browser"]
        open_page(browser, served["ports"]["runs"])
        title = f"coevo dashboard: runs {served['runs']}"
        check_page(browser, served["tmp"] / "runs.png", picture="dashboard-runs.png", title=title, heading=title,
                   headline=re.compile(r"tracking-\d+ tracking 3/3"))

    def test_a_study_of_learning_runs_page(self, served: dict[str, Any]) -> None:
        from pages import check_page, open_page

        browser, study = served["browser"], served["study"]
        open_page(browser, served["ports"]["learn-study"])
        facts = check_page(browser, served["tmp"] / "learn-study.png", picture="dashboard-learn-study.png",
                           title=f"coevo dashboard: study {study}", heading="A study declared on the command line",
                           headline="2 of 2 runs finished")
        assert "Quality Tracking (%): mean [95 %] · median" in facts["text"], facts["text"][:2000]
        # its wide table (two columns a measure) scrolls in its box instead of running on under the verdict
        table, verdict = (browser.execute_script(BOX, cls) for cls in ("study-cells-box", "study-verdict"))
        assert table and verdict and table[2] <= verdict[0], (table, verdict)


# An element's box in the viewport, by its class (in Bokeh's shadow roots too): [left, top, right, bottom]
BOX = """
function find(n, cls) {
  if (n.shadowRoot) { const r = find(n.shadowRoot, cls); if (r) return r; }
  for (const c of n.children || []) {
    if (c.classList && c.classList.contains(cls)) return c;
    const r = find(c, cls); if (r) return r;
  }
  return null;
}
const e = find(document.body, arguments[0]);
if (!e) return null;
const r = e.getBoundingClientRect();
return [r.left, r.top, r.right, r.bottom];
"""
