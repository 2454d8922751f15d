"""The page's pieces from a :class:`~coevo.dashboard.model.View`, without a web library: HTML tables and plot lines.

The workers' table has the columns of ``coevo status`` (worker, generation, best fitness, the
task's own measures, partner versions, unconfirmed, rejections by reason, state); every text that
comes from the bus or a file is escaped.
"""

from __future__ import annotations

import html
import math
from typing import Any

from coevo.dashboard.model import View

__all__ = ["PALETTE", "problems_html", "runs_html", "workers_html", "comparison_html", "curve_lines", "behaviours", "measure_names",
           "external_lines", "robot_html"]

# Bokeh's Category10 (d3): distinct lines for up to ten runs, then repeated with another dash
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
DASHES = ("solid", "dashed", "dotted", "dotdash")
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


def _labels() -> dict[str, str]:
    from coevo.tasks import measure_labels

    return measure_labels()


def _measures(m: dict[str, float]) -> str:
    labels = _labels()
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
        final = ", ".join(f"{_e(k)} {v:.1f}" for k, v in r.final.items()
                          if k in ("quality_tracking", "successful_docking", "dock_choice", "docking_success_rate")) or "-"
        rows.append([_e(r.run), _e(r.task), _e(r.regime), _state(r.state), _e(r.source), _state(b.get("state", "-")),
                     stored, _reasons(b.get("rejected", {})), final])
    return "<h3 class='coevo'>Runs</h3>" + _table("runs", ["run", "task", "regime", "state", "seen on", "broker",
                                                            "stored", "rejected", "final measures (%)"], rows)


def workers_html(view: View) -> str:
    """A row per worker (and CEL robot), as ``coevo status`` shows it."""
    rows = []
    for r in view.runs:
        for w in r.workers:
            partners = " ".join(f"{_e(k[0].upper())}v{v}" for k, v in sorted(w["partner_versions"].items())) or "-"
            rows.append([_e(r.run), _e(w["worker"]), _e(w["behaviour"]), f"{w['generation']}/{w['generations']}",
                         f"{w['best_fitness']:.3f}", _measures(w.get("measures", {})), partners, str(w.get("buffered", 0)),
                         _reasons(w.get("rejected_by_reason", {})), _state(w["state"])])
        for x in r.robots:
            rows.append([_e(r.run), _e(x["robot"]), "execution", str(x["generation"]), "",
                         f"external={x['performance']:.0f}%",
                         f"rules v{x['rules_version']}, {len(x['capabilities'])} sensors, {x['changes']} changes", "",
                         _reasons(x.get("rejected_by_reason", {})), _state(x["state"])])
    if not rows:
        return ""
    return "<h3 class='coevo'>Workers</h3>" + _table(
        "workers", ["run", "worker", "behaviour", "gen", "best", "own measures", "partners", "unconfirmed", "rejected",
                    "state"], rows, numeric={3, 4, 7})


def comparison_html(view: View) -> str:
    """A comparison's replicates by state and its Table 1 so far."""
    c = view.comparison
    if not c:
        return ""
    counts = ", ".join(f"{n} {s}" for s, n in c["counts"].items())
    reps = [[_e(r["run"]), _e(r["group"]), _state(r["state"]), f"{r['generations']}/{r['of']}", _e(r["class"] or "-"),
             _e(r["why"])] for r in c["replicates"]]
    groups = list(c["table1"])
    t1 = [[_e(cls)] + [str(c["table1"][g].get(cls, 0)) for g in groups] for cls in c["classes"]]
    done = {g: sum(c["table1"][g].values()) for g in groups}
    t1.append(["<i>runs finished</i>"] + [str(done[g]) for g in groups])
    return (f"<h3 class='coevo'>Comparison {_e(c['dir'])}: {counts}</h3>"
            + _table("table1", ["Table 1 so far"] + groups, t1, numeric=set(range(1, len(groups) + 1)))
            + _executive_curve_html(c.get("executive_curve", {}))
            + _table("replicates", ["replicate", "group", "state", "worker generations", "class", "why"], reps,
                     numeric={3}))


def _executive_curve_html(curves: dict[str, dict]) -> str:
    """The Executive curve of each regime's finished runs: its last generation's best and the mean over the last
    generations, means over the runs with 95 % intervals (coevo compare's report)."""
    from coevo.experiments.compare.stats import MeanInterval

    if not curves:
        return ""
    tail = next(iter(curves.values()))["tail_generations"]
    rows = [[_e(g), _e(MeanInterval(**c["end"]).text()), _e(MeanInterval(**c["last_generations"]).text())]
            for g, c in curves.items()]
    return _table("executive-curve", ["Executive curve (finished runs)", "best at the last generation",
                                      f"mean best over the last {tail} generations"], rows)


def behaviours(view: View) -> list[str]:
    """The behaviours with a curve, in their task's order (Tracking, Docking, Executive)."""
    from coevo.tasks import TASKS

    order = [b for t in TASKS.values() for b in t.behaviours]
    seen = {b for r in view.runs for b, _ in r.curves.values()}
    return sorted(seen, key=lambda b: (order.index(b) if b in order else len(order), b))


def measure_names(view: View, behaviour: str) -> str:
    """What the lines of ``behaviour``'s measures plot are: 'picks-D (solid), docked (dotted)'."""
    labels = _labels()
    keys = sorted({k for r in view.runs for b, c in r.curves.values() if b == behaviour for k in c.measures})
    return ", ".join(f"{labels.get(k, k)} ({DASHES[j % len(DASHES)] if j else 'solid'})" for j, k in enumerate(keys))


def _clean(values: list[float | None]) -> list[float]:
    return [math.nan if v is None or not math.isfinite(v) else float(v) for v in values]


def _style(i: int) -> tuple[str, str]:
    return PALETTE[i % len(PALETTE)], DASHES[(i // len(PALETTE)) % len(DASHES)]


def curve_lines(view: View, behaviour: str, what: str = "fitness") -> dict[str, list[Any]]:
    """A multi-line plot's columns for ``behaviour``: per run, its generation's best fitness and the fitness of the
    policy it publishes as its best (``fitness``), or each of the task's measures (``measures``); a colour per run.

    The published best's fitness is the mean of all its re-evaluations (``GAConfig.best_candidates``), so it can go
    down as evidence comes in: it is not a running maximum, and is not labelled one."""
    cols: dict[str, list[Any]] = {"xs": [], "ys": [], "run": [], "line": [], "color": [], "dash": [], "width": []}
    for i, r in enumerate(view.runs):
        colour, dash = _style(i)
        for wid, (b, c) in sorted(r.curves.items()):
            if b != behaviour or not len(c):
                continue
            if what == "fitness":
                lines = [("published best (mean of its re-evaluations)", c.best_so_far, 2.5),
                         ("generation's best", c.best, 1.0)]
            else:
                labels = _labels()
                lines = [(labels.get(k, k), col, 2.0) for k, col in sorted(c.measures.items())]
            for j, (name, ys, width) in enumerate(lines):
                cols["xs"].append(list(c.generation))
                cols["ys"].append(_clean(list(ys)))
                cols["run"].append(r.run)
                cols["line"].append(f"{wid} {name}")
                cols["color"].append(colour)
                cols["dash"].append(dash if what == "fitness" or j == 0 else DASHES[j % len(DASHES)])
                cols["width"].append(width)
    return cols


def external_lines(view: View) -> dict[str, list[Any]]:
    """CEL runs' external performance (%) per generation, a line per run."""
    cols: dict[str, list[Any]] = {"xs": [], "ys": [], "run": [], "line": [], "color": [], "dash": [], "width": []}
    for i, r in enumerate(view.runs):
        if r.external is None or not len(r.external):
            continue
        colour, dash = _style(i)
        cols["xs"].append(list(r.external.generation))
        cols["ys"].append(_clean(list(r.external.best)))
        cols["run"].append(r.run)
        cols["line"].append("external performance")
        cols["color"].append(colour)
        cols["dash"].append(dash)
        cols["width"].append(2.0)
    return cols


ROBOT_RULES = 12  # rules listed per rule set: the strongest that fired


def robot_html(view: View) -> str:
    """The drawn robot of one run: its picture (an inline PNG) and each rule set's strongest rules that fired."""
    pic = view.robot
    if pic is None:
        return ""
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
