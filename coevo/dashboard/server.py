"""The dashboard's web page: a Bokeh server (the library behind Dask's dashboard) on this machine.

One :class:`~coevo.dashboard.model.Dashboard` is read by a polling thread for the whole process;
each open page holds a Bokeh document whose periodic callback redraws only when the model's
version moved (the fingerprint of what the page shows), so an idle page costs a comparison of two
integers.  BokehJS is served by this server from the installed ``bokeh`` package
(``resources = server``): the page fetches nothing from the internet.  The page has no widgets:
nothing on it can reach a run (the Bokeh document's own state, e.g. a plot's zoom, stays in the
page and this process).
"""

from __future__ import annotations

import logging
import threading
from typing import Any

from coevo.dashboard import render
from coevo.dashboard.model import Dashboard, follow

__all__ = ["make_document", "serve"]

log = logging.getLogger(__name__)

REDRAW = 300  # ms between a page's checks of the model's version


class _Page:
    """One browser page: its Bokeh models, updated from the dashboard's view."""

    def __init__(self, doc: Any, dash: Dashboard, problems: list[str]) -> None:
        from bokeh.layouts import column, row
        from bokeh.models import Div

        self.doc, self.dash, self.problems = doc, dash, problems
        self.version = -1
        self.title = Div(text="", name="title", sizing_mode="stretch_width")
        self.banner = Div(text="", name="problems", sizing_mode="stretch_width")
        self.runs = Div(text="", name="runs", sizing_mode="stretch_width")
        self.workers = Div(text="", name="workers", sizing_mode="stretch_width")
        self.comparison = Div(text="", name="comparison", sizing_mode="stretch_width")
        self.robot = Div(text="", name="robot", sizing_mode="stretch_width")
        self.fitness_row = row(sizing_mode="stretch_width")
        self.measures_row = row(sizing_mode="stretch_width")
        self.external_row = row(sizing_mode="stretch_width")
        self.plots: dict[tuple[str, str], Any] = {}  # (behaviour, what) -> ColumnDataSource
        self.figures: dict[tuple[str, str], Any] = {}
        doc.title = dash.title
        doc.add_root(column(self.title, self.banner, self.runs, self.workers, self.fitness_row, self.measures_row,
                            self.external_row, self.comparison, self.robot, sizing_mode="stretch_width"))
        self.update()
        doc.add_periodic_callback(self.update, REDRAW)

    def _figure(self, name: str, title: str, y_label: str) -> tuple[Any, Any]:
        from bokeh.models import ColumnDataSource, HoverTool
        from bokeh.plotting import figure

        src = ColumnDataSource({"xs": [], "ys": [], "run": [], "line": [], "color": [], "dash": [], "width": []},
                               name=name)
        fig = figure(title=title, height=260, sizing_mode="stretch_width", x_axis_label="generation",
                     y_axis_label=y_label, tools="pan,wheel_zoom,box_zoom,reset,save", name=f"figure-{name}")
        fig.multi_line("xs", "ys", source=src, line_color="color", line_dash="dash", line_width="width")
        fig.add_tools(HoverTool(tooltips=[("run", "@run"), ("line", "@line")]))
        return fig, src

    def _source(self, behaviour: str, what: str, title: str = "") -> Any:
        key = (behaviour, what)
        if key in self.plots and title:
            self.figures[key].title.text = title
        if key not in self.plots:
            if what == "fitness":
                fig, src = self._figure(f"curve-{behaviour}", f"{behaviour}: best fitness (thick: best so far)", "fitness")
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
        version, view = self.dash.current()
        key = (version, tuple(self.problems))
        if key == self.version:
            return
        self.version = key
        n = len(view.runs)
        self.title.text = (f"<h2 style='font:bold 20px sans-serif;margin:4px 0'>{render._e(view.title)}</h2>"
                           f"<span style='font:12px sans-serif;color:#555'>{n} run{'s' * (n != 1)} · read-only: "
                           "nothing here can steer a run</span>")
        self.banner.text = render.problems_html(view, self.problems)
        self.runs.text = render.runs_html(view)
        self.workers.text = render.workers_html(view)
        self.comparison.text = render.comparison_html(view)
        self.robot.text = render.robot_html(view)
        for b in render.behaviours(view):
            self._source(b, "fitness").data = render.curve_lines(view, b, "fitness")
            lines = render.curve_lines(view, b, "measures")
            if lines["xs"] or (b, "measures") in self.plots:
                self._source(b, "measures", f"{b}: {render.measure_names(view, b)} (%)").data = lines
        ext = render.external_lines(view)
        if ext["xs"] or ("", "external") in self.plots:
            self._source("", "external").data = ext


def make_document(dash: Dashboard, problems: list[str]) -> Any:
    """The Bokeh application handler: a page per browser session over the shared ``dash``."""

    def make(doc: Any) -> None:
        _Page(doc, dash, problems)

    return make


def serve(dash: Dashboard, *, host: str, port: int, every: float = 0.5, on_ready: Any = None) -> None:
    """Serve ``dash`` on http://host:port/ until SIGINT/SIGTERM, refreshing it every ``every`` s on its own thread."""
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server
    from bokeh.settings import settings

    from coevo.errors import ConfigError

    from bokeh.core.validation import silence
    from bokeh.core.validation.warnings import EMPTY_LAYOUT

    settings.resources.set_value("server")  # BokehJS from this server, whatever BOKEH_RESOURCES says
    silence(EMPTY_LAYOUT, True)  # the rows of plots are empty until a run's first generation
    problems: list[str] = []  # a refresh that failed: said on the page (and logged)

    def on_error(text: str | None) -> None:
        problems[:] = [text] if text else []

    stop = threading.Event()
    dash.refresh()
    poller = threading.Thread(target=follow, args=(dash, every, stop, on_error), name="dashboard-refresh", daemon=True)
    origins = [f"{host}:{port}"] + ([f"localhost:{port}", f"127.0.0.1:{port}"] if host in ("127.0.0.1", "localhost") else [])
    try:
        server = Server({"/": Application(FunctionHandler(make_document(dash, problems)))}, address=host, port=port,
                        allow_websocket_origin=origins, check_unused_sessions_milliseconds=5000,
                        unused_session_lifetime_milliseconds=15000)
    except OSError as exc:
        raise ConfigError(f"cannot serve on {host}:{port}: {exc.strerror or exc} (choose another --port or --host)") from None
    poller.start()
    server.start()
    if on_ready:
        on_ready(f"http://{host}:{server.port}/")
    try:
        server.io_loop.start()
    except KeyboardInterrupt:
        pass
    finally:
        stop.set()
        server.stop()
        poller.join(timeout=5)
