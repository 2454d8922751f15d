"""The page's pieces from a :class:`~coevo.dashboard.model.View`, without a web library: HTML tables and plot lines.

The workers' table has the columns of ``coevo status`` (worker, generation, best fitness, the
task's own measures, partner versions, unconfirmed, rejections by reason, state); every text that
comes from the bus or a file is escaped.
"""

from __future__ import annotations

import html
import math
import re
from collections.abc import Sequence
from typing import Any

from coevo.dashboard.model import AcrossDynamics, View
from coevo.experiments.compare import plots
from coevo.experiments.glossary import TERMS, with_unit

__all__ = ["PALETTE", "REGIME_COLOURS", "problems_html", "runs_html", "workers_html", "comparison_html",
           "table1_html", "verdict_html", "regime_colour", "regime_columns", "curve_lines", "behaviours",
           "measure_names", "external_lines", "robot_html", "study_title_html", "study_progress_html",
           "study_verdict_html", "study_cell", "study_cell_table1_html", "study_cell_note_html", "study_tables_html"]

# Bokeh's Category20 (d3): a colour per run for up to twenty runs, then the colours repeat (a line style never
# stands for a run: on the measures' plot it says which measure, nowhere else)
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf",
           "#aec7e8", "#ffbb78", "#98df8a", "#ff9896", "#c5b0d5", "#c49c94", "#f7b6d2", "#c7c7c7", "#dbdb8d", "#9edae5")
DASHES = ("solid", "dashed", "dotted", "dotdash")
#: A comparison's groups in the colours and band hatchings of its report's regimes.png (Okabe and Ito's
#: colour-blind-safe colours: :data:`coevo.experiments.compare.plots.REGIME_COLOURS`).
REGIME_COLOURS, REGIME_HATCHES = plots.REGIME_COLOURS, plots.REGIME_HATCHES
#: The width of a study's progress and cells table, in pixels (its verdict takes the rest of the row).
STUDY_PROGRESS_WIDTH = 840
_STATE_COLOUR = {"alive": "#2ca02c", "running": "#2ca02c", "done": "#1f77b4", "stalled": "#b8860b", "dead": "#d62728",
                 "failed": "#d62728", "stopped": "#7f7f7f", "up": "#2ca02c", "down": "#d62728", "degraded": "#b8860b",
                 "waiting": "#7f7f7f", "files": "#7f7f7f", "starting": "#7f7f7f"}

_STYLE = ("<style>table.coevo{border-collapse:collapse;font:13px sans-serif;margin:2px 0 8px 0}"
          "table.coevo th,table.coevo td{padding:2px 10px;text-align:left;border-bottom:1px solid #ddd}"
          "table.coevo td.num{text-align:right;font-variant-numeric:tabular-nums}"
          "h3.coevo{font:bold 15px sans-serif;margin:8px 0 2px 0}</style>")


def _e(x: Any) -> str:
    return html.escape(str(x))


def _state(s: str) -> str:
    return f'<b style="color:{_STATE_COLOUR.get(s, "#000")}" class="state-{_e(s)}">{_e(s)}</b>'


def _table(cls: str, headers: list[str], rows: list[list[str]], numeric: set[int] | None = None) -> str:
    numeric = numeric or set()
    head = "".join(f"<th>{_e(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f'<td class="num">{c}</td>' if i in numeric else f"<td>{c}</td>"
                                    for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f'{_STYLE}<table class="coevo {cls}"><tr>{head}</tr>{body}</table>'


def _reasons(counts: dict[str, int]) -> str:
    return ", ".join(f"{_e(r)} {n}" for r, n in sorted(counts.items())) or "0"


def _labels(behaviours: Sequence[str] = ()) -> dict[str, str]:
    from coevo.tasks import measure_labels

    return measure_labels(behaviours)


def _measures(m: dict[str, float], behaviour: str = "") -> str:
    labels = _labels([behaviour] if behaviour else [])
    return " ".join(f"{_e(labels.get(k, k))}={v:.0f}%" for k, v in m.items()) or "-"


def problems_html(view: View, extra: list[str] | None = None) -> str:
    """One line per problem (bad input, no broker, rejections), red; empty when all is well."""
    lines = list(extra or []) + view.problems + [p for r in view.runs for p in r.problems]
    if not lines:
        return ""
    return "".join(f'<div class="problem" style="color:#b00;font:bold 14px sans-serif">{_e(p)}</div>' for p in lines)


def runs_html(view: View) -> str:
    """A row per run: its state, where it is seen, the broker's store and rejections, the final measures."""
    if not view.runs:
        return '<p class="no-runs" style="font:13px sans-serif">no runs yet</p>'
    rows = []
    for r in view.runs:
        b = r.broker or {}
        stored = " ".join(f"{_e(k)}:{v}" for k, v in sorted(b.get("stored", {}).items())) or "-"
        final = ", ".join(_e(with_unit(k, v)) for k, v in r.final.items()
                          if k in ("quality_tracking", "successful_docking", "dock_choice", "docking_success_rate")) or "-"
        rows.append([_e(r.run), _e(r.task), _e(r.regime), _state(r.state), _e(r.source), _state(b.get("state", "-")),
                     stored, _reasons(b.get("rejected", {})), final])
    return "<h3 class='coevo'>Runs</h3>" + _table("runs", ["run", "task", "regime", "state", "seen on", "broker",
                                                            "stored", "rejected", "final measures"], rows)


def workers_html(view: View) -> str:
    """A row per worker (and CEL robot), as ``coevo status`` shows it."""
    rows = []
    for r in view.runs:
        for w in r.workers:
            partners = " ".join(f"{_e(k[0].upper())}v{v}" for k, v in sorted(w["partner_versions"].items())) or "-"
            curve = r.curves.get(str(w["worker"]))
            so_far = curve[1].best_so_far[-1] if curve and curve[1].best_so_far else w["best_fitness"]
            rows.append([_e(r.run), _e(w["worker"]), _e(w["behaviour"]), f"{w['generation']}/{w['generations']}",
                         f"{so_far:.3f}", _measures(w.get("measures", {}), str(w.get("behaviour", ""))), partners, str(w.get("buffered", 0)),
                         _reasons(w.get("rejected_by_reason", {})), _state(w["state"])])
        for x in r.robots:
            rows.append([_e(r.run), _e(x["robot"]), "execution", str(x["generation"]), "",
                         f"external={x['performance']:.0f}%",
                         f"rules v{x['rules_version']}, {len(x['capabilities'])} sensors, {x['changes']} changes", "",
                         _reasons(x.get("rejected_by_reason", {})), _state(x["state"])])
    if not rows:
        return ""
    return ("<h3 class='coevo'>Workers</h3>" + _table(
        "workers", ["run", "worker", "behaviour", "gen", "best so far", "own measures", "partners", "unconfirmed",
                    "rejected", "state"], rows, numeric={3, 4, 7})
        + f"<p class='definition' style='font:12px sans-serif;color:#555'><b>best so far</b>: "
          f"{_e(TERMS['best_so_far'].definition)} The curves' thin line is each <b>generation's best</b>.</p>")


def comparison_html(view: View) -> str:
    """A comparison's long tables, for the fold below its headline: the headline curve of the finished runs and the
    replicates by state."""
    c = view.comparison
    if not c:
        return ""
    reps = [[_e(r["run"]), _e(r["group"]), _state(r["state"]), f"{r['generations']}/{r['of']}", _e(r["class"] or "-"),
             _e(r["why"])] for r in c["replicates"]]
    return (_headline_curve_html(c.get("headline_curve", {}), c.get("curve") or "")
            + _table("replicates", ["replicate", "group", "state", "worker generations", "class", "why"], reps,
                     numeric={3}))


def table1_html(view: View) -> str:
    """The comparison's headline: its replicates by state, and Table 1 over the finished runs beside the report's
    counts (a grey column "report" after each regime the report counted)."""
    c = view.comparison
    if not c:
        return ""
    counts = ", ".join(f"{n} {s}" for s, n in c["counts"].items())
    groups = list(c["table1"])
    report = c.get("table1_report", {})
    heads, cols = ["Table 1" if c["classes"] else "regime"], []
    for g in groups:
        heads.append(f"{g} so far")
        cols.append(lambda cls, g=g: str(c["table1"][g].get(cls, 0)))
        if g in report:
            heads.append("report")
            cols.append(lambda cls, g=g: f'<span class="report">{report[g].get(cls, 0)}</span>')
    rows = [[_e(cls)] + [f(cls) for f in cols] for cls in c["classes"]]
    done = c.get("finished") or {g: sum(c["table1"][g].values()) for g in groups}
    rows.append(["<i>runs finished</i>"] + [x for g in groups for x in (
        [str(done[g])] + ([f'<span class="report">{sum(report[g].values())}</span>'] if g in report else []))])
    style = ("<style>table.table1 td,table.table1 th{white-space:nowrap;padding:1px 8px}"
             "table.table1 span.report{color:#777}</style>")
    return (f"<h3 class='coevo'>Runs: {counts}</h3>" + style
            + _table("table1", heads, rows, numeric=set(range(1, len(heads)))))


def verdict_html(view: View) -> str:
    """The verdict of the comparison's report once written (said when it covers fewer runs than have finished), else
    when it will be, and always whether the settings are below the report's."""
    c = view.comparison
    if not c:
        return ""
    v = c.get("verdict")
    done = c["counts"]["done"]
    total = len(c["replicates"])
    box = "font:13px/1.35 sans-serif;max-height:300px;overflow:auto;margin:0 0 0 12px"
    if v is None:
        body = (f"<p>No report yet: the verdict is written when the comparison ends ({done} of {total} runs finished). "
                f"<code>coevo compare --report-only --out {_e(c['dir'])}</code> writes one from the runs finished so "
                "far.</p>" + (f"<p><i>{_e(c['caveat'])}</i></p>" if c.get("caveat") else ""))
    else:
        stale = (f" (the report covers {v['finished']} of {v['expected']} runs; {done} have finished since: "
                 f"coevo compare --report-only --out {_e(c['dir'])} writes it again)" if v["finished"] < done else "")
        body = "".join(f"<p>{_e(p)}</p>" for p in v["text"].split("\n\n")) + (f"<p><i>{stale}</i></p>" if stale else "")
    return f"<h3 class='coevo'>Verdict</h3><div class='verdict' style='{box}'>{body}</div>"


def legend_label(group: str, done: int, going: int) -> str:
    """A regime's legend on the comparison's panels: its finished runs (in the mean and the band), those going, and,
    below the runs an interval needs, that there is no band: 'mutual, 2 runs, no band (needs 3) (+1 going)'."""
    from coevo.experiments.common import plural
    from coevo.experiments.compare.stats import MIN_RUNS

    band = f", no band (needs {MIN_RUNS})" if 0 < done < MIN_RUNS else ""
    return f"{group}, {plural(done, 'run')}{band}" + (f" (+{going} going)" if going else "")


def panel_title(title: str, panel: dict[str, Any]) -> str:
    """A comparison panel's title, saying when a band on it was cut at its measure's range (the legends, one entry a
    regime, have no room for it at 1280 px): 'Executive learning curve (bands clipped at 0 and 1)'."""
    from coevo.experiments.compare.stats import clip_words

    cut = sorted({b for g in panel["groups"].values() for b in ((g.get("band") or {}).get("clipped") or ())})
    return f"{title} (bands {clip_words(cut)})" if cut else title


def regime_colour(view: View, group: str) -> str:
    """A comparison group's colour: its place among the comparison's groups, as in the report's regimes.png."""
    groups = list((view.comparison or {}).get("table1", {}))
    i = groups.index(group) if group in groups else len(groups)
    return REGIME_COLOURS[i % len(REGIME_COLOURS)]


def regime_hatch(i: int) -> str:
    """The hatching of the ``i``-th group's band."""
    return REGIME_HATCHES[i % len(REGIME_HATCHES)]


RUN_ALPHA, RUN_WIDTH = 0.3, 1.0  # a run: thin and faint under its regime's mean
PICKED_ALPHA, PICKED_WIDTH = 0.95, 2.5  # a run picked in the run selector


def regime_columns(panel: dict[str, Any], group: str, picked: set[str] | frozenset[str] = frozenset()
                   ) -> tuple[dict[str, list[Any]], dict[str, list[Any]]]:
    """One regime on one of a comparison's panels: (the band's columns: generation, mean, low, high, n; the runs'
    lines: xs, ys, run, state, alpha, width, dash).  A finished run is solid, one not finished (running, or
    failed) dotted; a picked run thick."""
    g = panel["groups"].get(group) or {"lines": [], "band": None}
    b = g["band"] or {"generation": [], "mean": [], "low": [], "high": [], "n": []}
    band = {k: list(b[k]) for k in ("generation", "mean", "low", "high", "n")}
    band["regime"] = [group] * len(band["generation"])
    lines: dict[str, list[Any]] = {"xs": [], "ys": [], "run": [], "state": [], "alpha": [], "width": [], "dash": []}
    for ln in g["lines"]:
        on = ln["run"] in picked
        lines["xs"].append(list(ln["generation"]))
        lines["ys"].append(_clean(list(ln["value"])))
        lines["run"].append(ln["run"])
        lines["state"].append(ln["state"])
        lines["alpha"].append(PICKED_ALPHA if on else RUN_ALPHA)
        lines["width"].append(PICKED_WIDTH if on else RUN_WIDTH)
        lines["dash"].append("solid" if ln["state"] == "done" else "dotted")
    return band, lines


def _headline_curve_html(curves: dict[str, dict], behaviour: str) -> str:
    """The curve its reading quotes (the fuel task's Executive's) of each regime's finished runs: its last generation's best and the mean over the last
    generations, means over the runs with 95 % intervals (coevo compare's report)."""
    from coevo.experiments.compare.report import tail_text
    from coevo.experiments.compare.stats import MeanInterval

    if not curves:
        return ""
    tail = next(iter(curves.values()))["tail_generations"]
    rows = [[_e(g), _e(MeanInterval(**c["end"]).text()), _e(MeanInterval(**c["last_generations"]).text())]
            for g, c in curves.items()]
    return _table("headline-curve", [f"{behaviour.capitalize()} curve (finished runs)", "generation's best at the last generation",
                                      f"generation's best, mean of its last {tail_text(tail)}"], rows)


def behaviours(view: View) -> list[str]:
    """The behaviours with a curve, in their task's order (Tracking, Docking, Executive)."""
    from coevo.errors import ConfigError
    from coevo.tasks import task_of

    seen = {b for r in view.runs for b, _ in r.curves.values()}
    order: list[str] = []
    for b in sorted(seen):
        try:
            order += [x for x in task_of(b).behaviours if x not in order]
        except ConfigError:
            pass
    return sorted(seen, key=lambda b: (order.index(b) if b in order else len(order), b))


def measure_names(view: View, behaviour: str) -> str:
    """What the lines of ``behaviour``'s measures plot are: 'picks-D (solid), docked (dotted)'."""
    labels = _labels([behaviour])
    keys = sorted({k for r in view.runs for b, c in r.curves.values() if b == behaviour for k in c.measures})
    return ", ".join(f"{labels.get(k, k)} ({DASHES[j % len(DASHES)] if j else 'solid'})" for j, k in enumerate(keys))


def _clean(values: list[float | None]) -> list[float]:
    return [math.nan if v is None or not math.isfinite(v) else float(v) for v in values]


def _colour(i: int) -> str:
    return PALETTE[i % len(PALETTE)]


def curve_lines(view: View, behaviour: str, what: str = "fitness") -> dict[str, list[Any]]:
    """A multi-line plot's columns for ``behaviour``: per run, its generation's best fitness and the fitness of the
    policy it publishes as its best (``fitness``: thick the published best, thin the generation's), or each of the task's
    measures (``measures``: a dash per measure); a colour per run, and only the colour says which run.

    The best so far's fitness is, with ``GAConfig.best_candidates`` (Docking's default), the mean of all its
    re-evaluations, so it can go down as evidence comes in: it is not labelled a running maximum."""
    cols: dict[str, list[Any]] = {"xs": [], "ys": [], "run": [], "line": [], "color": [], "dash": [], "width": []}
    for i, r in enumerate(view.runs):
        colour = _colour(i)
        for wid, (b, c) in sorted(r.curves.items()):
            if b != behaviour or not len(c):
                continue
            lines: list[tuple[str, Sequence[float | None], float]]
            if what == "fitness":
                lines = [("best so far (the published policy)", c.best_so_far, 2.5),
                         ("generation's best", c.best, 1.0)]
            else:
                labels = _labels([behaviour])
                lines = [(labels.get(k, k), col, 2.0) for k, col in sorted(c.measures.items())]
            for j, (name, ys, width) in enumerate(lines):
                cols["xs"].append(list(c.generation))
                cols["ys"].append(_clean(list(ys)))
                cols["run"].append(r.run)
                cols["line"].append(f"{wid} {name}")
                cols["color"].append(colour)
                cols["dash"].append("solid" if what == "fitness" else DASHES[j % len(DASHES)])  # a dash: a measure
                cols["width"].append(width)
    return cols


def external_lines(view: View) -> dict[str, list[Any]]:
    """CEL runs' external performance (%) per generation, a line per run."""
    cols: dict[str, list[Any]] = {"xs": [], "ys": [], "run": [], "line": [], "color": [], "dash": [], "width": []}
    for i, r in enumerate(view.runs):
        if r.external is None or not len(r.external):
            continue
        colour = _colour(i)
        cols["xs"].append(list(r.external.generation))
        cols["ys"].append(_clean(list(r.external.best)))
        cols["run"].append(r.run)
        cols["line"].append("external performance")
        cols["color"].append(colour)
        cols["dash"].append("solid")
        cols["width"].append(2.0)
    return cols


ROBOT_RULES = 12  # rules listed per rule set: the strongest that fired


def dynamics_html(view: View) -> str:
    """Each finished run's ``coevo dynamics`` pictures (master tournament, CIAO matrix per pair), when it has them;
    for a folder of runs whose summary was played, that summary instead (its runs' own pictures stay in their
    directories: thirty runs' matrices are no page)."""
    if view.across is not None:
        return _STYLE + _across_html(view.across)
    parts = []
    for r in view.runs:
        d = r.dynamics
        if d is None or not d.pictures:
            continue
        span = d.played.get("generations") or ["?", "?"]
        parts.append(f'<h3 class="coevo">Dynamics of {_e(r.run)}</h3><p style="font:12px sans-serif;color:#555;'
                     f'margin:0">every published version against every partner version, generations {_e(span[0])} to '
                     f'{_e(span[-1])}, {_e(d.played.get("episodes", "?"))} episodes a cell from seed '
                     f'{_e(d.played.get("seed", "?"))} (coevo dynamics {_e(r.run)}; how to read them: '
                     'docs/competition.md)</p>')
        parts += [f'<img class="dynamics" alt="{_e(name)}" title="{_e(name)}" style="max-width:49%" '
                  f'src="data:image/png;base64,{png}"/>' for name, png in d.pictures]
    return (_STYLE + "".join(parts)) if parts else ""


def _across_html(a: AcrossDynamics) -> str:
    """The master tournament across a folder's runs: its rise per pair and group in a table, then its pictures."""
    def num(x: Any) -> str:  # a damaged rise.json shows "?", as a damaged line elsewhere is skipped
        return "" if x is None else f"{x:+.3f}" if isinstance(x, (int, float)) else "?"

    rows = "".join(
        f"<tr><td>{_e(r.get('learner'))} against {_e(r.get('partner'))}</td><td>{_e(r.get('group'))}</td>"
        f"<td class=\"num\">{_e(r.get('runs'))}</td><td class=\"num\">{_e(r.get('first'))} → {_e(r.get('last'))}</td>"
        f"<td class=\"num\">{num(r.get('mean'))}</td><td class=\"num\">"
        f"{'' if r.get('low95') is None else '[' + num(r['low95']) + ', ' + num(r['high95']) + ']'}</td>"
        f"<td class=\"num\">{_e(r.get('rose'))} / {_e(r.get('fell'))} / {_e(r.get('same'))}</td></tr>"
        for r in a.rise)
    head = (f'<h3 class="coevo">Dynamics across {a.runs} runs ({_e(", ".join(a.groups))})</h3>'
            '<p style="font:12px sans-serif;color:#555;margin:0">the master tournament of each generation\'s version '
            "against every generation of its partner, per run, then across the runs (coevo dynamics DIR; how to read "
            "it: docs/competition.md). Rise: each run's score at the last generation minus at the first, its mean "
            "across the runs with a 95 % t interval; runs that rose / fell / stayed.</p>")
    table = ('<table class="coevo dynamics-rise"><tr><th>pair</th><th>runs of</th><th>runs</th><th>generations</th>'
             f"<th>rise</th><th>95 %</th><th>rose / fell / same</th></tr>{rows}</table>") if rows else ""
    pics = "".join(f'<img class="dynamics" alt="{_e(name)}" title="{_e(name)}" style="max-width:49%" '
                   f'src="data:image/png;base64,{png}"/>' for name, png in a.pictures)
    return head + table + pics


def robot_html(view: View) -> str:
    """The drawn robot of one run: its picture (an inline PNG, shown at its own size: its smallest text is
    robot.TEXT_PX) and each rule set's strongest rules that fired; or why there is none and how to have one."""
    pic = view.robot
    if pic is None:
        return (_STYLE + '<h3 class="coevo">Robot</h3><p class="robot-note" style="font:13px sans-serif">'
                f"{_e(view.robot_note)}</p>") if view.robot_note else ""
    versions = ", ".join(f"{_e(b)} v{v}" for b, v in pic.versions.items())
    head = f'<h3 class="coevo">Robot of {_e(pic.run)}' + (f": {versions}" if versions else "") + "</h3>"
    if not pic.png:
        return _STYLE + head + f'<p class="robot-note" style="font:13px sans-serif">{_e(pic.note)}</p>'
    what = "episode" if pic.episodes == 1 else "episodes"
    parts = [_STYLE, head, f'<p style="font:12px sans-serif;color:#555;margin:0">{pic.episodes} {what} from seed 0, '
             "redrawn when a newer policy is published (coevo show RUN_DIR draws the same)</p>",
             f'<img class="robot" alt="the robot of {_e(pic.run)}" style="max-width:100%" '
             f'src="data:image/png;base64,{pic.png}"/>']
    for t in pic.tables:
        fired = [r for r in t.rows if r.fired > 0]
        rows = [[f"{_e(t.letter)}{r.number}", f"{r.strength:.2f}", str(r.fired), _e(r.text)] for r in fired[:ROBOT_RULES]]
        more = len(fired) - len(rows)
        parts.append(f'<h3 class="coevo">{_e(t.title)}</h3><p style="font:12px sans-serif;margin:0">'
                     f'{len(fired)} of {len(t.rows)} rules fired' + (f"; the {len(rows)} strongest shown" if more > 0 else "")
                     + "</p>")
        parts.append(_table("rules", ["rule", "strength", "fired", "IF ... THEN ..."], rows, numeric={1, 2}))
    return "".join(parts)


# ---------------------------------------------------------------- a study
def _share(d: dict[str, Any]) -> str:
    """k/n [low–high %] of a Wilson interval's dict (:meth:`~coevo.experiments.study.intervals.Proportion.as_dict`)."""
    from coevo.experiments.study.intervals import Proportion

    return _e(Proportion(int(d["k"]), int(d["n"]), float(d["low"]), float(d["high"])).text())


def _mean(d: dict[str, Any]) -> str:
    """mean [low, high] of an interval's dict (:meth:`~coevo.experiments.compare.stats.MeanInterval.as_dict`), its n
    left to the runs' column, or why there is no interval (the report's :func:`~coevo.experiments.study.report.format_mean`)."""
    from coevo.experiments.study.report import format_mean

    return _e(format_mean(d, False))


def _median(d: dict[str, Any]) -> str:
    """The median of a learning-run cell's measure (:func:`~coevo.experiments.study.learn_report.learn_cell_rows`)."""
    m = d.get("median")
    return "–" if not d["n"] or m is None or math.isnan(m) else f"{m:.2f}"


_CELL_STATE_COLOUR = {"finished": "#1f77b4", "running": "#2ca02c", "stopped": "#d62728", "waiting": "#7f7f7f",
                      "not started": "#7f7f7f", "writing its report": "#2ca02c"}


def _cell_state(s: str) -> str:
    return (f'<b style="color:{_CELL_STATE_COLOUR.get(s, "#000")}" class="state-{_e(s.replace(" ", "-"))}">'
            f"{_e(s)}</b>")


def study_title_html(view: View) -> str:
    """The study's name, its description, its folder."""
    s = view.study or {}
    desc = f"{_e(s['description'])} · " if s.get("description") else ""
    name = s.get("name")  # a study declared on the command line has the declaration's default name, "study"
    heading = f"Study {_e(name)}" if name and name != "study" else "A study declared on the command line"
    return (f"<h2 style='font:bold 20px sans-serif;margin:4px 0'>{heading}</h2>"
            f"<span style='font:13px sans-serif;color:#333'>{desc}</span>"
            f"<span style='font:12px sans-serif;color:#555'>{_e(s.get('dir', ''))} · factors {_e(s.get('factors', ''))}"
            " · read-only: nothing here can steer a run</span>")


def study_progress_html(view: View) -> str:
    """The study's headline: runs and cells done of the total, its state (finished only when its completion marker
    says so), a bar, and a row per cell and group: its state, runs, and the report's numbers so far (Good and No
    Docking with 95 % Wilson intervals, the Executive curve's end and AEL with 95 % t intervals)."""
    s = view.study
    if not s:
        return ""
    done, total = s["runs_done"], s["runs_total"]
    pct = 100 * done / total if total else 0.0
    going = ", ".join(f"{n} {k}" for k, n in s["counts"].items() if n and k != "done")
    why = f": {_e(s['why'])}" if s["why"] else ""
    head = (f"<div class='study-progress' style='font:15px sans-serif;margin:2px 0'>"
            f"<b class='runs-done'>{done} of {total} runs finished</b> ({pct:.0f} %)"
            + (f" · {_e(going)}" if going else "")
            + f" · <span class='cells-done'>{s['cells_done']} of {s['cells_total']} cells finished</span>"
            f" · the study: {_cell_state(s['state'])}{why}</div>"
            f"<div style='width:420px;height:8px;background:#e5e5e5;margin:2px 0 6px 0'>"
            f"<div class='bar' style='width:{pct:.1f}%;height:8px;background:"
            f"{_CELL_STATE_COLOUR.get(s['state'], '#2ca02c')}'></div></div>")
    rows = []
    learn = s.get("kind") == "learn"
    for c in s["cells"]:
        runs = f"{c['runs_done']}/{c['runs_total']}"
        extra = ", ".join(f"{n} {k}" for k, n in c["counts"].items() if n and k in ("running", "failed"))
        lead = [f"<span title='{_e(c['label'])}, seed {c['seed']}'>{_e(c['id'])}</span>", _cell_state(c["state"]),
                runs + (f" ({_e(extra)})" if extra else "")]
        for i, r in enumerate(c["rows"]):
            cells = lead if i == 0 else ["", "", ""]
            if learn:  # a study of learning runs: its behaviour's measures, each a mean [95 %] and the median
                rows.append([*cells, *(f"{_mean(r['measures'][k])} · {_median(r['measures'][k])}"
                                       for k, _ in s["measures"])])
            else:
                rows.append([*cells, _e(r["group"]), _share(r["good_docking"]), _share(r["no_docking"]),
                             _mean(r["executive_end"]), _mean(r["average_epoch_length"])])
    if learn:
        heads = [f"{title}: mean [95 %] · median" for _, title in s["measures"]]
        table = _table("study-cells", ["cell", "state", "runs done", *heads], rows,
                       numeric=set(range(2, 3 + len(heads))))
    else:
        table = _table("study-cells", ["cell", "state", "runs done", "group", "Good Docking", "No Docking",
                                       "Executive end", "AEL"], rows, numeric={2, 6, 7})
    style = "<style>table.study-cells td,table.study-cells th{white-space:nowrap;padding:1px 8px}</style>"
    # a study of many cells scrolls in its box: the cell selector below stays on the first screen
    # its own box, scrolled both ways: a wide table (a study of learning runs has two columns a measure) stays in the
    # box's width instead of running on under the verdict beside it
    return head + style + (f"<div class='study-cells-box' style='max-height:440px;max-width:{STUDY_PROGRESS_WIDTH}px;"
                           f"overflow:auto'>{table}</div>")


def study_verdict_html(view: View) -> str:
    """The study's report's verdict once written (said when it covers fewer runs than have finished), else when it
    will be, and whether the settings are below the report's."""
    s = view.study
    if not s:
        return ""
    v = s.get("verdict")
    box = "font:13px/1.35 sans-serif;max-height:200px;overflow:auto;margin:0 0 0 12px"
    caveat = f"<p class='caveat'><i>{_e(s['caveat'])}</i></p>" if s.get("caveat") else ""
    if v is None:
        body = (f"<p>No report yet: it is written when the study ends ({s['runs_done']} of {s['runs_total']} runs "
                f"finished). <code>coevo study --report-only --out {_e(s['dir'])}</code> writes one from the runs "
                "finished so far.</p>" + caveat)
    else:
        stale = (f" (the report covers {v['finished']} of {v['expected']} runs; {s['runs_done']} have finished since:"
                 f" coevo study --report-only --out {_e(s['dir'])} writes it again)"
                 if v["finished"] < s["runs_done"] else "")
        items, paras = [], []
        for part in v["text"].split("\n"):
            text = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", _e(part.strip()))  # the report's Markdown bold
            if part.startswith("- "):
                items.append(f"<li>{text[2:]}</li>")
            elif part.strip():
                paras.append(f"<p>{text}</p>")
        # the smoke-test warning first: a finished study's verdict is read with it, as its report.md says it; then
        # the findings in words (the paragraphs), then the tests one by one: a finding is not left at the bottom of
        # a box of a dozen bullets
        body = caveat + "".join(paras)
        body += (f"<ul style='padding-left:18px;margin:4px 0'>{''.join(items)}</ul>" if items else "")
        body += f"<p><i>{stale}</i></p>" if stale else ""
    return f"<h3 class='coevo'>The study's verdict</h3><div class='study-verdict' style='{box}'>{body}</div>"


def study_cell(view: View, cell: str) -> dict[str, Any] | None:
    """One cell of the study as its page shows it (its row in :func:`study_progress_html`), or None."""
    return next((c for c in (view.study or {}).get("cells", []) if c["id"] == cell), None)


def study_cell_table1_html(view: View, cell: str) -> str:
    """One cell's Table 1 so far: each class k of n with its 95 % Wilson interval per group, beside the report's
    counts of 10 with theirs (as the study's report.md)."""
    from coevo.experiments.compare.table1 import CLASSES, REPORT_COUNTS
    from coevo.experiments.study.intervals import wilson

    c = study_cell(view, cell)
    if c is None or (view.study or {}).get("kind") == "learn":  # learning runs have no Table 1
        return ""
    rows = c["rows"]
    heads = ["Table 1"]
    for r in rows:
        heads.append(f"{r['group']} so far")
        if r["group"] in REPORT_COUNTS:
            heads.append("report")
    body = []
    for k in CLASSES:
        line = [_e(k)]
        for r in rows:
            line.append(_share(r["table1"][k]))
            if r["group"] in REPORT_COUNTS:
                line.append(f'<span class="report">{_e(wilson(REPORT_COUNTS[r["group"]].get(k, 0), 10).text())}</span>')
        body.append(line)
    style = ("<style>table.cell-table1 td,table.cell-table1 th{white-space:nowrap;padding:1px 8px}"
             "table.cell-table1 span.report{color:#777}</style>")
    counts = ", ".join(f"{n} {s}" for s, n in c["counts"].items())
    return (f"<h3 class='coevo'>Cell {_e(c['id'])} ({_e(c['label'])}): {_e(counts)}</h3>" + style
            + _table("cell-table1", heads, body, numeric=set(range(1, len(heads)))))


def study_cell_note_html(view: View, cell: str) -> str:
    """Beside a cell's Table 1: its own comparison report's verdict if one was written, else how to write one; and
    its failed runs, with why."""
    c = study_cell(view, cell)
    comparison = ((view.study or {}).get("shown") or {}).get(cell)
    if c is None:
        return ""
    box = "font:13px/1.35 sans-serif;max-height:300px;overflow:auto;margin:0 0 0 12px"
    failed = "".join(f"<li>{_e(f)}</li>" for f in c["failed"])
    failed = f"<p>Failed or stopped runs (coevo study --resume runs them again):</p><ul>{failed}</ul>" if failed else ""
    s = view.study or {}
    if s.get("kind") == "learn":
        where = f"{s.get('dir', '')}/cells/{cell}"
        body = (f"<p>A cell is {c['runs_total']} runs of <code>coevo learn --behaviour {_e(s.get('behaviour'))}"
                f"</code>, one per seed (cell seed {c['seed']}, then + 1000 a run), in <code>{_e(where)}/runs</code>"
                "; each run's measures are its measures.json.</p>" + failed)
        return f"<h3 class='coevo'>Cell {_e(c['id'])}</h3><div class='cell-note' style='{box}'>{body}</div>"
    if comparison and comparison.get("verdict"):
        return verdict_html(View(view.title, comparison=comparison)) + (f"<div style='{box}'>{failed}</div>"
                                                                       if failed else "")
    where = comparison["dir"] if comparison else f"{(view.study or {}).get('dir', '')}/cells/{cell}"
    body = (f"<p>A cell is one comparison, paired by seed (cell seed {c['seed']}). Its own report (rank tests, curves, "
            f"robots): <code>coevo compare --report-only --out {_e(where)}</code>; <code>coevo dashboard "
            f"{_e(where)}</code> shows it alone.</p>" + failed)
    return f"<h3 class='coevo'>This cell</h3><div class='cell-note' style='{box}'>{body}</div>"


def study_tables_html(view: View) -> str:
    """Every cell's Table 1 so far with 95 % Wilson intervals, for the fold at the bottom of a study's page."""
    s = view.study
    if not s:
        return ""
    return "".join(study_cell_table1_html(view, c["id"]) for c in s["cells"])
