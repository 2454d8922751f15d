"""The dashboard's web page: a Bokeh server (the library behind Dask's dashboard) on this machine.

Three pages: a run's or runs' (tables and curves), a comparison's (:class:`_Regimes`: its Table 1 and verdict, then
the report's panels per regime) and a study's (:class:`_Study`: its progress and cells, then one cell at a time as
a comparison, picked in a selector).

One :class:`~coevo.dashboard.model.Dashboard` is read by a polling thread for the whole process;
each open page holds a Bokeh document whose periodic callback redraws only when the model's
version moved (the fingerprint of what the page shows), so an idle page costs a comparison of two
integers.  BokehJS is served by this server from the installed ``bokeh`` package
(``resources = server``): the page fetches nothing from the internet.  Its few widgets (a
comparison's run selector, the buttons that fold its long tables, a legend that hides a regime)
change only how this page draws: nothing on it can reach a run (the Bokeh document's own state,
e.g. a plot's zoom or the runs picked, stays in the page and this process).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sized
from typing import TYPE_CHECKING, Any

from coevo.dashboard import render
from coevo.dashboard.model import Dashboard, View, follow

if TYPE_CHECKING:  # bokeh is imported when a page is made, not when the module is
    from bokeh.document import Document
    from bokeh.models import ColumnDataSource, LayoutDOM
    from bokeh.models.annotations import LegendItem
    from bokeh.models.renderers import GlyphRenderer
    from bokeh.plotting import figure
    from bokeh.server.views.static_handler import StaticHandler
    from tornado.httputil import HTTPServerRequest
    from tornado.ioloop import IOLoop

__all__ = ["make_document", "serve"]

log = logging.getLogger(__name__)

REDRAW = 300  # ms between a page's checks of the model's version


class _Page:
    """One browser page: its Bokeh models, updated from the dashboard's view."""

    def __init__(self, doc: Document, dash: Dashboard, problems: list[str]) -> None:
        from bokeh.layouts import column, row
        from bokeh.models.widgets import Div  # (where the typed stubs see it; bokeh.models re-exports it)

        self.doc, self.dash, self.problems = doc, dash, problems
        self.version: tuple[int, tuple[str, ...]] | None = None  # the view and problems drawn last
        self.title = Div(text="", name="title", sizing_mode="stretch_width")
        self.banner = Div(text="", name="problems", sizing_mode="stretch_width")
        self.runs = Div(text="", name="runs", sizing_mode="stretch_width")
        self.workers = Div(text="", name="workers", sizing_mode="stretch_width")
        self.comparison = Div(text="", name="comparison", sizing_mode="stretch_width")
        self.robot = Div(text="", name="robot", sizing_mode="stretch_width")
        self.dynamics = Div(text="", name="dynamics", sizing_mode="stretch_width")
        self.fitness_row = row(sizing_mode="stretch_width")
        self.measures_row = row(sizing_mode="stretch_width")
        self.external_row = row(sizing_mode="stretch_width")
        self.plots: dict[tuple[str, str], ColumnDataSource] = {}  # (behaviour, what) -> its lines
        self.figures: dict[tuple[str, str], figure] = {}
        doc.title = dash.title
        self.regimes: _Regimes | None = None
        self.study: _Study | None = None
        if dash.kind == "study":
            self.study = _Study(dash)
            if self.study.regimes is None:  # a study of learning runs: no cell is a comparison
                layout = column(self.title, self.banner, self.study.headline, self.study.controls,
                                *_folded("every cell's runs", self.study.tables), self.robot,
                                sizing_mode="stretch_width")
            else:
                layout = column(self.title, self.banner, self.study.headline, self.study.controls,
                                self.study.regimes.headline, self.study.regimes.controls, *self.study.regimes.rows,
                                *_folded("the cell's replicates and its curve's table", self.comparison),
                                *_folded("every cell's Table 1", self.study.tables), self.robot,
                                sizing_mode="stretch_width")
        elif dash.kind == "comparison":
            self.regimes = _Regimes(dash)
            layout = column(self.title, self.banner, self.regimes.headline, self.regimes.controls, *self.regimes.rows,
                            self.dynamics,  # its runs' dynamics across them, once coevo dynamics played them
                            *_folded("replicates and the curve's table", self.comparison),
                            *_folded("runs and workers", column(self.runs, self.workers, sizing_mode="stretch_width")),
                            self.robot, sizing_mode="stretch_width")
        else:
            layout = column(self.title, self.banner, self.runs, self.workers, self.fitness_row, self.measures_row,
                            self.external_row, self.comparison, self.dynamics, self.robot, sizing_mode="stretch_width")
        self.update()  # before the layout is the document's: a change to a model held by a document costs a walk
        doc.add_root(layout)  # over all of its models (seconds for a comparison's hundred), one here costs nothing
        doc.add_periodic_callback(self.update, REDRAW)

    def _figure(self, name: str, title: str, y_label: str) -> tuple[figure, ColumnDataSource]:
        from bokeh.models import ColumnDataSource, HoverTool

        src = ColumnDataSource({"xs": [], "ys": [], "run": [], "line": [], "color": [], "dash": [], "width": []},
                               name=name)
        fig = _plain_figure(f"figure-{name}", title, y_label, height=260)
        fig.multi_line("xs", "ys", source=src, line_color="color", line_dash="dash", line_width="width")
        fig.add_tools(HoverTool(tooltips=[("run", "@run"), ("line", "@line"), ("generation", "$snap_x{0}"),
                                          ("value", "$snap_y{0.000}")], line_policy="nearest"))
        return fig, src

    def _source(self, behaviour: str, what: str, title: str = "") -> ColumnDataSource:
        key = (behaviour, what)
        if key in self.plots and title:
            from bokeh.models.annotations import Title

            shown = self.figures[key].title
            if isinstance(shown, Title):  # (always: _plain_figure gives it one)
                shown.text = title
        if key not in self.plots:
            if what == "fitness":
                fig, src = self._figure(f"curve-{behaviour}", f"{behaviour}: fitness (thick: best so far; thin: generation's best)",
                                        "fitness")
                self.fitness_row.children.append(fig)
            elif what == "measures":
                fig, src = self._figure(f"measures-{behaviour}", title or f"{behaviour}: the task's measures", "%")
                self.measures_row.children.append(fig)
            else:
                fig, src = self._figure("external", "CEL: external performance", "%")
                self.external_row.children.append(fig)
            self.plots[key], self.figures[key] = src, fig
        return self.plots[key]

    def update(self) -> None:
        if self.study is not None and self.study.regimes is not None:
            self.dash.want(self.study.cell)  # while this page is open, its cell's comparison is read
        version, view = self.dash.current()
        key = (version, tuple(self.problems))
        if key == self.version:
            return
        self.version = key
        with self.doc.models.freeze():  # the document's models walked once, after every change
            self._draw(view)

    def _draw(self, view: View) -> None:
        if self.study is not None:
            self.title.text = render.study_title_html(view)
            self.banner.text = render.problems_html(view, self.problems)
            self.banner.visible = bool(self.banner.text)
            self.study.update(view)
            if self.study.regimes is not None:
                self.comparison.text = render.comparison_html(self.study.cell_view(view))
            self.robot.text = render.robot_html(view)
            return
        n = len(view.runs)
        self.title.text = (f"<h2 style='font:bold 20px sans-serif;margin:4px 0'>{render._e(view.title)}</h2>"
                           f"<span style='font:12px sans-serif;color:#555'>{n} run{'s' * (n != 1)} · read-only: "
                           "nothing here can steer a run</span>")
        self.banner.text = render.problems_html(view, self.problems)
        self.banner.visible = bool(self.banner.text)  # an empty one would still take a line
        self.runs.text = render.runs_html(view)
        self.workers.text = render.workers_html(view)
        self.comparison.text = render.comparison_html(view)
        self.robot.text = render.robot_html(view)
        self.dynamics.text = render.dynamics_html(view)
        if self.regimes is not None:
            self.regimes.update(view)
            return
        for b in render.behaviours(view):
            self._source(b, "fitness").data = render.curve_lines(view, b, "fitness")
            lines = render.curve_lines(view, b, "measures")
            if lines["xs"] or (b, "measures") in self.plots:
                self._source(b, "measures", f"{b}: {render.measure_names(view, b)} (%)").data = lines
        ext = render.external_lines(view)
        if ext["xs"] or ("", "external") in self.plots:
            self._source("", "external").data = ext


def _plain_figure(name: str, title: str, y_label: str, *, height: int, top: float | None = None) -> figure:
    """A figure of something per generation: whole-number generation ticks, and the page's tools.  A measure that
    cannot be negative (a %, or a panel with a ``top``: a fitness from 0 to 1) starts its axis at 0 and spans at least
    a tenth of its scale, so an all-zero panel starts at 0 (it read -1 to 1)."""
    from bokeh.models import BasicTicker, DataRange1d
    from bokeh.plotting import figure

    scale = top if top is not None else 100.0 if "%" in y_label else None
    y_range = DataRange1d(start=0, min_interval=scale / 10) if scale else DataRange1d()
    fig = figure(title=title, height=height, sizing_mode="stretch_width", x_axis_label="generation",
                 y_axis_label=y_label, tools="pan,wheel_zoom,box_zoom,reset,save", name=name, y_range=y_range)
    fig.xaxis.ticker = BasicTicker(min_interval=1)  # generations are whole: no 1.5 on a 3-generation run
    return fig


def _folded(label: str, body: LayoutDOM) -> list[LayoutDOM]:
    """``body`` behind a button that shows and hides it, folded at first.  A button, not an HTML ``<details>``: the
    tables are redrawn as the runs go on, and a ``<details>`` inside them would fold again at every redraw; the
    button's state is the page's own."""
    from bokeh.models import CustomJS
    from bokeh.models.widgets import Toggle

    body.visible = False
    button = Toggle(label=f"▸ {label}", active=False, name=f"fold-{label.split()[0]}", button_type="light")
    button.js_on_change("active", CustomJS(args={"body": body, "label": label}, code=(
        "body.visible = cb_obj.active; cb_obj.label = (cb_obj.active ? '▾ ' : '▸ ') + label;")))
    return [button, body]


def _panels_of(view: View) -> list[tuple[str, str, str, str, float | None]]:
    """The panels of the view's comparison (its task's reading), or, before it is read (a study's cell), the default
    task's: a study's cells compare its regimes."""
    from coevo.experiments.compare.reading import reading_of
    from coevo.tasks import DEFAULT_TASK, get_task

    panels = (view.comparison or {}).get("panels")
    if panels:
        return [(p["title"], p["behaviour"], p["column"], p["ylabel"], p["top"]) for p in panels]
    return [tuple(p) for p in reading_of(get_task(DEFAULT_TASK)).panels]  # type: ignore[misc]


class _Regimes:
    """A comparison's page: its headline (Table 1 so far beside the report's counts, the verdict), a run selector,
    and the report's panels with a band, a mean and the runs' lines per regime; a legend in each panel hides a regime
    in all of them."""

    def __init__(self, dash: Dashboard, first: View | None = None) -> None:
        """``first``: the view whose comparison the page opens on (default: the dashboard's)."""
        from bokeh.layouts import row
        from bokeh.models.widgets import Div, MultiChoice

        self.dash = dash
        self.table1 = Div(text="", name="table1", width=600)
        self.verdict = Div(text="", name="verdict", sizing_mode="stretch_width")
        self.headline = row(self.table1, self.verdict, sizing_mode="stretch_width")
        self.picker = MultiChoice(title="Runs drawn thick (all runs are drawn thin; a legend entry hides its regime):",
                                  options=[], value=[], name="run-selector", width=560)
        self.picker.on_change("value", self._picked)
        key = Div(text=("<p style='font:13px sans-serif;color:#333;margin:22px 0 0 12px'>Per regime: "
                        "<b>thick line</b> the mean of its finished runs, <b>band</b> the 95 % interval of that mean "
                        "(Student t; none below 3 runs; cut at the measure's range, 0–100 % or 0–1, where it would reach "
                        "beyond, and the panel's title says so; as in the report's regimes.png), <b>thin lines</b> its runs "
                        "(<b>dotted</b>: not finished). Hover for values.</p>"),
                  sizing_mode="stretch_width")
        self.controls = row(self.picker, key, sizing_mode="stretch_width")
        view = first if first is not None else dash.current()[1]
        self.panels = _panels_of(view)
        self.figures: list[figure] = []
        self.sources: dict[tuple[int, str], tuple[ColumnDataSource, ColumnDataSource]] = {}  # (panel, group) -> (band, lines)
        self.renderers: dict[str, list[GlyphRenderer[Any]]] = {}  # group -> its renderers in every panel
        self.items: list[tuple[int, str, LegendItem]] = []  # (panel, group, its legend entry)
        self.labels: dict[tuple[int, str], str] = {}  # ... and its text now
        self.groups: list[str] = []
        self.view: View | None = None
        figs = [_plain_figure(f"panel-{beh}-{col}", title, ylabel, height=270, top=top)
                for title, beh, col, ylabel, top in self.panels]
        self.figures = figs
        self.rows = [row(*figs[i:i + 3], sizing_mode="stretch_width") for i in range(0, len(figs), 3)]
        self._add_groups(view)

    def _add_groups(self, view: View) -> None:
        """Every regime of the view's comparison not drawn yet (a study's page may open before its cell is read)."""
        for g in (view.comparison or {}).get("regimes", []):
            if g not in self.groups:
                self.groups.append(g)
                self._add_group(g, render.regime_colour(view, g))

    def _add_group(self, group: str, colour: str) -> None:
        """The band, mean and runs of a new group in every panel, with its legend entries."""
        from bokeh.core.properties import value
        from bokeh.models import ColumnDataSource, CustomJS, HoverTool
        from bokeh.models.annotations import Legend, LegendItem

        mine: list[GlyphRenderer[Any]] = []
        for i, fig in enumerate(self.figures):
            band = ColumnDataSource({k: [] for k in ("generation", "mean", "low", "high", "n", "regime")},
                                    name=f"band-{i}-{group}")
            lines = ColumnDataSource({k: [] for k in ("xs", "ys", "run", "state", "alpha", "width", "dash")},
                                     name=f"runs-{i}-{group}")
            # two bands that overlap stay two: each hatched its own way, its edges drawn (colours that blend, such
            # as red and green into olive, are told apart by the hatching and the lines)
            area = fig.varea("generation", "low", "high", source=band, fill_color=colour, fill_alpha=0.12,
                             hatch_pattern=render.regime_hatch(self.groups.index(group)), hatch_color=colour,
                             hatch_alpha=0.35, hatch_scale=12, name=f"band-{group}")
            edges = [fig.line("generation", edge, source=band, line_color=colour, line_width=1, line_dash="dashed",
                              name=f"edge-{edge}-{group}") for edge in ("low", "high")]
            runs = fig.multi_line("xs", "ys", source=lines, line_color=colour, line_alpha="alpha", line_width="width",
                                  line_dash="dash", name=f"runs-{group}")
            mean = fig.line("generation", "mean", source=band, line_color=colour, line_width=3.5, name=f"mean-{group}")
            fig.add_tools(HoverTool(renderers=[runs], line_policy="nearest", tooltips=[
                ("run", "@run (@state)"), ("generation", "$snap_x{0}"), ("value", "$snap_y{0.000}")]))
            fig.add_tools(HoverTool(renderers=[mean], mode="vline", tooltips=[
                ("regime", "@regime"), ("generation", "@generation"), ("mean", "@mean{0.000}"),
                ("95 % interval", "@low{0.000} to @high{0.000}"), ("finished runs", "@n")]))
            if not fig.legend:
                fig.add_layout(Legend(click_policy="hide", location="top_left", orientation="horizontal",
                                      name=f"legend-{i}", label_text_font_size="12px",
                                      padding=2,  # type: ignore[arg-type]  # bokeh 3.9's stub types Legend.padding
                                      # as the Property itself (Padding, not PaddingType): an int is refused there,
                                      # though it is what the property takes
                                      margin=0, spacing=12, glyph_width=16, border_line_alpha=0), "above")
            item = LegendItem(label=value(group), renderers=[mean, area, *edges, runs])  # type: ignore[list-item]  # the stub's
            # GlyphRenderer[Glyph] is invariant in its glyph: a line's renderer is refused where any glyph's is taken
            fig.legend[0].items.append(item)  # type: ignore[arg-type]  # bokeh 3.9's stub types the items as the
            # (label, renderers) pairs the property also takes, not the LegendItem it holds
            self.items.append((i, group, item))
            self.sources[(i, group)] = (band, lines)
            mine += [area, *edges, mean, runs]
        # a click on a legend entry hides the regime in its panel: the same in every panel
        sync = CustomJS(args={"all": mine}, code="for (const r of all) { if (r.visible != cb_obj.visible) "
                                                 "r.visible = cb_obj.visible; }")
        for r in mine:
            r.js_on_change("visible", sync)
        self.renderers[group] = mine

    def update(self, view: View, *, table1: str | None = None, verdict: str | None = None) -> None:
        """Draw the view's comparison; ``table1`` and ``verdict``: the headline's two boxes, when not the
        comparison's own (a study's cell: its Table 1 with intervals, and how to have its own report)."""
        c = view.comparison
        if table1 is not None:
            self.table1.text = table1
        if verdict is not None:
            self.verdict.text = verdict
        if not c:  # (a study's cell picked, not read yet) no other cell's lines under its name
            if self.view is not None:
                self.view = None
                for band, lines in self.sources.values():
                    band.data = {k: [] for k in band.data}
                    lines.data = {k: [] for k in lines.data}
            return
        self.view = view
        self._add_groups(view)
        if table1 is None:
            self.table1.text = render.table1_html(view)
        if verdict is None:
            self.verdict.text = render.verdict_html(view)
        runs = sorted({ln["run"] for p in c["panels"] for grp in p["groups"].values() for ln in grp["lines"]})
        if runs != list(self.picker.options):
            self.picker.options = runs
        self._redraw()

    def _picked(self, attr: str, old: list[str], new: list[str]) -> None:
        """The run selector moved (in this page only): its panels drawn again, the document walked once."""
        doc = self.picker.document
        if doc is None:  # not on a page: no document to walk
            self._redraw()
            return
        with doc.models.freeze():
            self._redraw()

    def _redraw(self) -> None:
        from bokeh.core.properties import value
        from bokeh.models.annotations import Title

        c = self.view.comparison if self.view is not None else None
        if not c:
            return
        picked = set(self.picker.value)
        for i, panel in enumerate(c["panels"]):
            title, shown = render.panel_title(self.panels[i][0], panel), self.figures[i].title
            if isinstance(shown, Title) and shown.text != title:  # (always a Title: _plain_figure gives it one)
                shown.text = title
            for g in self.groups:
                band, lines = render.regime_columns(panel, g, picked)
                src_band, src_lines = self.sources[(i, g)]
                src_band.data, src_lines.data = band, lines
        for i, g, item in self.items:
            lines = c["panels"][i]["groups"].get(g, {"lines": []})["lines"]
            done = sum(ln["state"] == "done" for ln in lines)
            label = render.legend_label(g, done, len(lines) - done)
            if self.labels.get((i, g)) != label:  # a legend redrawn only when its text changes
                self.labels[(i, g)] = label
                item.label = value(label)


class _Study:
    """A study's page: its headline (progress, each cell's state and numbers so far, the study's verdict), a cell
    selector, and the cell picked shown as a comparison (:class:`_Regimes`) with its Table 1's intervals.  The cell
    picked is this page's own; the dashboard reads the comparisons of the cells open pages ask for.  A study of
    learning runs has its headline alone (its cells are no comparisons: no selector, ``regimes`` None), and every
    cell's runs in the fold."""

    def __init__(self, dash: Dashboard) -> None:
        from bokeh.layouts import row
        from bokeh.models.widgets import Div, Select

        self.dash = dash
        view = dash.current()[1]
        s = view.study or {}
        self.cell: str = s.get("default", "")
        self.progress = Div(text="", name="study", width=render.STUDY_PROGRESS_WIDTH)
        self.verdict = Div(text="", name="study-verdict", sizing_mode="stretch_width")
        self.headline = row(self.progress, self.verdict, sizing_mode="stretch_width")
        self.tables = Div(text="", name="study-tables", sizing_mode="stretch_width")
        self.regimes: _Regimes | None = None
        if s.get("kind") == "learn":
            self.controls = row(Div(text=(
                "<p style='font:13px sans-serif;color:#333;margin:4px 0'>Each cell is a set of learning runs "
                f"(<code>coevo learn --behaviour {render._e(s.get('behaviour'))}</code>, one per seed), not a "
                "comparison: above, each measure of its finished runs' best policies, the mean with its 95 % "
                "t interval (none below 3 runs) and the median.</p>"), sizing_mode="stretch_width"), sizing_mode="stretch_width")
            return
        self.options = self._options(view)  # as last given to the selector
        self.selector = Select(title="The cell shown below, as a comparison:", options=self.options,
                               value=self.cell, name="cell-selector", width=420)
        self.selector.on_change("value", self._picked)
        key = Div(text=("<p style='font:13px sans-serif;color:#333;margin:22px 0 0 12px'>Each cell is one regime "
                        "comparison with its own seeds. Below: its Table 1 so far with 95 % Wilson intervals (the "
                        "report's counts of 10 in grey) and its regimes' curves.</p>"), sizing_mode="stretch_width")
        self.controls = row(self.selector, key, sizing_mode="stretch_width")
        self.regimes = _Regimes(dash, first=self.cell_view(view))
        dash.want(self.cell)

    @staticmethod
    def _options(view: View) -> list[str | tuple[str, str]]:
        return [(c["id"], f"{c['id']}: {c['state']}, {c['runs_done']}/{c['runs_total']} runs")
                for c in (view.study or {}).get("cells", [])]

    def cell_view(self, view: View) -> View:
        """The picked cell's comparison as a view of its own, for the comparison's page pieces."""
        return View(view.title, comparison=((view.study or {}).get("shown") or {}).get(self.cell))

    def update(self, view: View) -> None:
        self.progress.text = render.study_progress_html(view)
        self.verdict.text = render.study_verdict_html(view)
        if self.regimes is None:  # learning runs: every cell's note (its runs, those that failed)
            self.tables.text = "".join(render.study_cell_note_html(view, c["id"])
                                       for c in (view.study or {}).get("cells", []))
            return
        options = self._options(view)
        if options != self.options:
            self.selector.options = self.options = options
        self.tables.text = render.study_tables_html(view)
        cell = self.cell_view(view)
        wait = "" if cell.comparison else f"<p style='font:13px sans-serif'>reading cell {render._e(self.cell)} ...</p>"
        self.regimes.update(cell, table1=render.study_cell_table1_html(view, self.cell) + wait,
                            verdict=render.study_cell_note_html(view, self.cell))

    def _picked(self, attr: str, old: str, new: str) -> None:
        """Another cell picked (in this page only): asked of the dashboard, and drawn now as far as it is read."""
        self.cell = new
        self.dash.want(new)
        if self.regimes is not None:  # (always: only a study of comparisons has a selector)
            self.regimes.picker.value = []  # a run id names a run of each cell: the one picked was the other cell's
        doc = self.selector.document
        if doc is None:
            self.update(self.dash.current()[1])
            return
        with doc.models.freeze():
            self.update(self.dash.current()[1])


def make_document(dash: Dashboard, problems: list[str],
                  built: Callable[[], None] | None = None) -> Callable[[Document], None]:
    """The Bokeh application handler: a page per browser session over the shared ``dash``; ``built()`` after each."""

    def make(doc: Document) -> None:
        _Page(doc, dash, problems)
        if built is not None:
            built()

    return make


#: Pages open at once (Bokeh sessions); a page beyond them is answered 503 at once.  A dashboard is watched by a
#: few people; each page holds its own plots (~1 MB).
MAX_PAGES = 32
#: New pages: a burst of this many, then PAGES_PER_S a second of time not spent building pages.  Building a page's
#: document costs 0.3-0.5 s of CPU (measured: six Bokeh figures made and serialised; the data behind them is the
#: process's one ``Dashboard``), so 200 page loads at once kept the process busy for minutes; beyond the rate a
#: load is answered 503 at once.
PAGE_BURST, PAGES_PER_S = 4, 0.5
#: A page whose browser is gone (or never connected its websocket) is dropped this long after; checked every second.
UNUSED_MS = 5_000


class _Admission:
    """Bokeh's ``process_request`` hook, called for every new page before its session is made: a token bucket of
    new pages and a bound on open ones.  The bucket does not fill while a page is built (:meth:`built`), so on a
    machine so busy that a page takes seconds, pages still take at most a share of the time."""

    def __init__(self, sessions: Callable[[], Sized]) -> None:
        self.sessions = sessions  # () -> the open sessions
        self.tokens, self.at = float(PAGE_BURST), time.monotonic()

    def __call__(self, request: HTTPServerRequest) -> dict[str, Any]:
        from tornado.web import HTTPError

        now = time.monotonic()
        self.tokens, self.at = min(PAGE_BURST, self.tokens + (now - self.at) * PAGES_PER_S), now
        if len(self.sessions()) >= MAX_PAGES:
            raise HTTPError(503, reason=f"{MAX_PAGES} pages are open: close one")
        if self.tokens < 1:
            raise HTTPError(503, reason=f"more than {PAGES_PER_S:g} new pages a second: try again")
        self.tokens -= 1
        return {}

    def built(self) -> None:
        self.at = max(self.at, time.monotonic())


def _static_handler() -> type[StaticHandler]:
    """Bokeh's handler of its own files (BokehJS), answering a path the file system cannot hold (``/static/%00``)
    with 400 instead of a traceback and 500."""
    from bokeh.server.views.static_handler import StaticHandler
    from tornado.web import HTTPError

    class Static(StaticHandler):
        def validate_absolute_path(self, root: str, absolute_path: str) -> str | None:
            if "\x00" in absolute_path:
                raise HTTPError(400, reason="bad path")
            return super().validate_absolute_path(root, absolute_path)

    return Static


#: What Bokeh logs, once per pending update, when a page's tab was closed: nothing is wrong (7 lines a closed tab).
CLOSED_TAB = "Failed sending message as connection was closed"


def _not_a_closed_tab(record: logging.LogRecord) -> bool:
    return record.getMessage() != CLOSED_TAB


def quiet_closed_tabs() -> None:
    """Leave out of the terminal Bokeh's warning for each update that could not reach a tab closed meanwhile; every
    other warning of its websocket stays."""
    ws = logging.getLogger("bokeh.server.views.ws")
    if _not_a_closed_tab not in ws.filters:
        ws.addFilter(_not_a_closed_tab)


def serve(dash: Dashboard, *, host: str, port: int, every: float = 0.5,
          on_ready: Callable[[str], None] | None = None) -> None:
    """Serve ``dash`` on http://host:port/ until SIGINT/SIGTERM, refreshing it every ``every`` s on its own thread.

    Every session id is made and signed here with a key of this process (``sign_sessions``): a page cannot choose
    its own.  Sessions are bounded (:class:`_Admission`) and dropped :data:`UNUSED_MS` after their page went."""
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.core.validation import silence
    from bokeh.core.validation.warnings import EMPTY_LAYOUT
    from bokeh.server.server import BaseServer
    from bokeh.server.tornado import BokehTornado
    from bokeh.settings import settings
    from bokeh.util.token import generate_secret_key
    from tornado.httpserver import HTTPServer
    from tornado.ioloop import IOLoop
    from tornado.netutil import bind_sockets

    settings.resources.set_value("server")  # BokehJS from this server, whatever BOKEH_RESOURCES says
    quiet_closed_tabs()
    silence(EMPTY_LAYOUT, True)  # the rows of plots are empty until a run's first generation
    problems: list[str] = []  # a refresh that failed: said on the page (and logged)

    def on_error(text: str | None) -> None:
        problems[:] = [text] if text else []

    stop = threading.Event()
    dash.refresh()
    poller = threading.Thread(target=follow, args=(dash, every, stop, on_error), name="dashboard-refresh", daemon=True)
    try:
        # a burst of page loads waits in a long queue (each answered at once) instead of its connections being
        # dropped and retried by the clients seconds later
        sockets = bind_sockets(port, address=host, backlog=1024)
        port = sockets[0].getsockname()[1]
    except OSError as exc:  # taken since coevo dashboard's check_port found it free
        from coevo.dashboard.port import cannot_serve

        raise cannot_serve(host, port, exc) from None
    origins = [f"{host}:{port}"] + ([f"localhost:{port}", f"127.0.0.1:{port}"] if host in ("127.0.0.1", "localhost") else [])
    server: BaseServer  # made below: the admission hook is called only once it serves
    admission = _Admission(lambda: server.get_sessions())
    app = Application(FunctionHandler(make_document(dash, problems, admission.built)))
    tornado_app = BokehTornado({"/": app}, extra_websocket_origins=origins, sign_sessions=True,
                               secret_key=generate_secret_key().encode(), session_token_expiration=60,
                               check_unused_sessions_milliseconds=1000, unused_session_lifetime_milliseconds=UNUSED_MS)
    tornado_app.add_handlers(r".*", [(r"/static/(.*)", _static_handler())])  # before Bokeh's own
    http = HTTPServer(tornado_app)
    http.add_sockets(sockets)
    server = BaseServer(IOLoop.current(), tornado_app, http)
    app.process_request = admission  # type: ignore[method-assign]
    poller.start()
    server.start()
    unhook = _stop_on_signals(server.io_loop)
    if on_ready:
        on_ready(f"http://{host}:{port}/")
    try:
        server.io_loop.start()
    except KeyboardInterrupt:
        pass
    finally:
        unhook()
        stop.set()
        server.stop()
        poller.join(timeout=5)


def _stop_on_signals(loop: IOLoop) -> Callable[[], None]:
    """While serving, SIGINT and SIGTERM stop ``loop`` from the loop itself (asyncio's signal handlers: the signal
    wakes the loop, which stops); returns what puts the handlers before back.

    Not a KeyboardInterrupt raised wherever the main thread is (the command's handler until the page serves): raised
    inside a callback the interpreter runs for a C library, it is printed as "ignored" and lost.  pymunk frees its
    bodies in such callbacks (``ffi.gc``) when the garbage collector runs, and a study's Docking probes and a robot's
    drawing leave them: a SIGTERM arriving then left the dashboard running until it was killed."""
    import signal

    from tornado.platform.asyncio import BaseAsyncIOLoop

    if not isinstance(loop, BaseAsyncIOLoop):  # (tornado's loops are asyncio's since tornado 5)
        return lambda: None
    aio = loop.asyncio_loop
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig in before:
        aio.add_signal_handler(sig, loop.stop)

    def unhook() -> None:
        for sig, handler in before.items():
            aio.remove_signal_handler(sig)
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)

    return unhook
