"""One name for each measure: docs/glossary.md lists each term of :mod:`coevo.experiments.glossary` once, and the
reports and the dashboard call the measures by those names (issue 55: "best" meant two things, raw field names were
printed)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from coevo.experiments import glossary
from coevo.experiments.glossary import TERMS, label

ROOT = Path(__file__).resolve().parent.parent
NAMES = {t.name for t in TERMS.values()}
FIELDS = ("quality_tracking", "successful_docking", "docking_success_rate", "dock_choice", "average_epoch_length",
          "executive_payoff", "docking_from_random_starts", "final_executive_fitness", "best_fitness", "best_so_far")


def test_the_glossary_page_lists_each_term_once_as_the_code_defines_it() -> None:
    page = (ROOT / "docs" / "glossary.md").read_text()
    assert glossary.markdown() in page, "docs/glossary.md is stale: write glossary.markdown() into it"
    entries = re.findall(r"^- \*\*(.+?)\*\*", page, flags=re.M)
    assert sorted(entries) == sorted(t.name for t in TERMS.values())  # each once, none extra
    assert len(NAMES) == len(TERMS)  # no two fields share a name
    assert "glossary.md" in (ROOT / "mkdocs.yml").read_text()


def _record(run: str, regime: str, payoff: float) -> dict[str, Any]:
    m = {"quality_tracking": 72.2, "successful_docking": 8.0, "docking_success_rate": 60.0, "dock_choice": 13.0,
         "average_epoch_length": 7.05, "executive_payoff": payoff, "collision_rate": 3.1}
    return {"run": run, "regime": regime, "group": regime, "rate": None, "index": 0, "seed": 0, "seconds": 60.0,
            "docking_from_random_starts": 55.0, "measures": m, "class": "Good Docking / Hi",
            "final_best_so_far": {"executive": payoff, "docking": 0.7, "tracking": 0.8}, "versions": {}, "curves": {}}


def test_the_comparison_report_names_every_measure_as_the_glossary_does() -> None:
    from coevo.experiments.compare import report
    from coevo.experiments.compare.experiment import CompareSpec
    from coevo.experiments.compare.stats import compare_samples
    from coevo.experiments.compare.table1 import count

    spec = CompareSpec.make(runs=2)
    records = [_record("mutual-00", "mutual", 0.2), _record("mutual-01", "mutual", 0.3),
               _record("independent-00", "independent", 0.6), _record("independent-01", "independent", 0.7)]
    tests = [compare_samples(m, "mutual", [0.2, 0.3], "independent", [0.6, 0.7])
             for m in ("final_executive_fitness", "successful_docking")]
    curve = {g: report.executive_curve([[0.1, 0.2, 0.3, 0.4, 0.5]] * 2) for g in ("mutual", "independent")}
    table = {g: count(x["class"] for x in records if x["group"] == g) for g in ("mutual", "independent")}
    md = report._markdown(spec, records, table, tests, [], report._verdict(spec, records, tests), [], 4, None, [],
                          curve)
    runs = next(line for line in md.splitlines() if line.startswith("| run | class |"))
    heads = [h.strip() for h in runs.strip("|").split("|")][2:]
    for h in heads:  # each a glossary name, with its unit: 'Quality Tracking %', 'Average Epoch Length (episodes)'
        name = re.sub(r" (%|\(.*\))$", "", h)
        assert name in NAMES or name in ("final best so far E / D / T", "minutes"), h
    for field in report.RUN_COLUMNS:  # and each defined one line away, below the table
        assert f"- **{label(field)}**: {TERMS[field].definition}" in md, field
    section = md.split("## Statistical comparison")[1].split("\n## ")[0]
    stats = [line.split("|")[1].strip() for line in section.splitlines()
             if line.startswith("| ") and not line.startswith("| measure")]
    assert stats == [label("final_executive_fitness"), label("successful_docking")]
    for field in FIELDS:  # no raw field name where a reader reads
        assert field not in md.replace(f"`{field}`", ""), field
    # A 5-generation run's "last 10 generations" are its 5, and the report says so; the two fitnesses are told apart.
    assert "last 10 generations" not in md and "mean of its last 5 generations" in md
    assert "*Generation's best*" in md and "*best so far*" in md


def test_a_studys_measures_and_the_dashboards_columns_are_the_glossarys() -> None:
    from types import SimpleNamespace

    from coevo.dashboard import render
    from coevo.dashboard.model import Curve
    from coevo.experiments.study.report import MEASURES

    for field, (title, _, _) in MEASURES.items():
        assert title.startswith(label(field) + " ("), title
    c = Curve()
    c.add(1, 0.6)
    c.add(2, 0.4)  # the generation's best fell; the best so far did not
    w = {"worker": "executive-0", "behaviour": "executive", "generation": 2, "generations": 2, "best_fitness": 0.4,
         "partner_versions": {}, "measures": {}, "state": "done"}
    run = SimpleNamespace(run="r1", workers=[w], robots=[], curves={"executive-0": ("executive", c)}, broker={},
                          task="fuel", regime="mutual", state="done", source="files",
                          final={"quality_tracking": 72.2, "successful_docking": 8.0})
    view = SimpleNamespace(runs=[run])
    workers = render.workers_html(view)  # type: ignore[arg-type]
    assert "<th>best so far</th>" in workers.replace(" class='num'", "") or ">best so far<" in workers
    assert ">0.600<" in workers and render._e(TERMS["best_so_far"].definition) in workers
    runs = render.runs_html(view)  # type: ignore[arg-type]
    assert "Quality Tracking 72.2 %" in runs and "Successful Docking 8.0 %" in runs and "quality_tracking" not in runs
