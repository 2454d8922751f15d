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
import time
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
                fig, src = self._figure(f"curve-{behaviour}", f"{behaviour}: best fitness (thick: the published best)", "fitness")
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


def make_document(dash: Dashboard, problems: list[str], built: Any = None) -> Any:
    """The Bokeh application handler: a page per browser session over the shared ``dash``; ``built()`` after each."""

    def make(doc: Any) -> None:
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

    def __init__(self, sessions: Any) -> None:
        self.sessions = sessions  # () -> the open sessions
        self.tokens, self.at = float(PAGE_BURST), time.monotonic()

    def __call__(self, request: Any) -> dict[str, Any]:
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


def _static_handler() -> Any:
    """Bokeh's handler of its own files (BokehJS), answering a path the file system cannot hold (``/static/%00``)
    with 400 instead of a traceback and 500."""
    from bokeh.server.views.static_handler import StaticHandler
    from tornado.web import HTTPError

    class Static(StaticHandler):  # type: ignore[misc]
        def validate_absolute_path(self, root: str, absolute_path: str) -> str | None:
            if "\x00" in absolute_path:
                raise HTTPError(400, reason="bad path")
            return super().validate_absolute_path(root, absolute_path)  # type: ignore[no-any-return]

    return Static


def serve(dash: Dashboard, *, host: str, port: int, every: float = 0.5, on_ready: Any = None) -> None:
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

    from coevo.errors import ConfigError

    settings.resources.set_value("server")  # BokehJS from this server, whatever BOKEH_RESOURCES says
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
    except OSError as exc:
        raise ConfigError(f"cannot serve on {host}:{port}: {exc.strerror or exc} (choose another --port or --host)") from None
    origins = [f"{host}:{port}"] + ([f"localhost:{port}", f"127.0.0.1:{port}"] if host in ("127.0.0.1", "localhost") else [])
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
    if on_ready:
        on_ready(f"http://{host}:{port}/")
    try:
        server.io_loop.start()
    except KeyboardInterrupt:
        pass
    finally:
        stop.set()
        server.stop()
        poller.join(timeout=5)
