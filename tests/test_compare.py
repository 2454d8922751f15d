"""`coevo compare`: a tiny real comparison end to end, resuming it, its bad input, and its pieces."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from coevo.experiments.compare.stats import compare_groups, compare_samples, magnitude, mean_interval
from coevo.experiments.compare.table1 import CLASSES, REPORT_COUNTS, classify, count
from coevo.rundir.settings import RunSettings

TINY = ["--runs", "2", "--generations", "3", "--population", "6", "--episodes", "10", "--ga", "best_episodes=10",
        "--ga", "initial_rules=8", "--measure-epochs", "5", "--jobs", "2", "--quiet"]
RUNS = ("mutual-00", "independent-00", "mutual-01", "independent-01")


def coevo(*args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=timeout,
                          check=False)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cmp") / "tiny"
    r = coevo("compare", "--out", str(out), *TINY)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 of 4 runs already done, 4 to run, 2 at a time" in r.stdout
    return out


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.service
@pytest.mark.slow
class TestTinyComparison:
    """The two tests on the module's comparison (half a minute to make): a class, so that the whole suite's scheduler
    (tests/conftest.py) gives both to one xdist worker, which makes it once; the second changes it, after the first
    has read it."""

    def test_tiny_comparison_writes_a_consistent_report(self, tiny: Path) -> None:
        for name in ("compare.json", "report.md", "results.json", "runs.csv", "curves.csv",
                     "figure-mutual.png", "figure-independent.png", "regimes.png"):
            assert (tiny / name).is_file(), name
        for png in tiny.glob("*.png"):
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000

        res = json.loads((tiny / "results.json").read_text())
        assert res["runs_expected"] == res["runs_finished"] == 4
        assert sorted(x["run"] for x in res["runs"]) == sorted(RUNS)

        # Every run's measures are its own summary's, and its class follows from them.
        for x in res["runs"]:
            summary = json.loads((tiny / "runs" / x["run"] / "summary.json").read_text())
            assert x["measures"] == pytest.approx(summary["measures"])
            assert x["class"] == classify(summary["measures"])
            assert 0.0 <= x["docking_from_random_starts"] <= 100.0
            for beh, final in x["final_best_so_far"].items():
                rows = (tiny / "runs" / x["run"] / "workers" / beh / "curve.jsonl").read_text().splitlines()
                assert len(rows) == 3 and final == pytest.approx(json.loads(rows[-1])["best_so_far"])

        # The Executive curve's end and its steadier reading are means of the runs' curves.
        for regime in ("mutual", "independent"):
            ec = res["executive_curve"][regime]
            curves = [[json.loads(r)["best_fitness"] for r in (tiny / "runs" / x["run"] / "workers" / "executive" /
                                                                 "curve.jsonl").read_text().splitlines()]
                      for x in res["runs"] if x["regime"] == regime]
            assert ec["end"]["n"] == len(curves) == 2
            assert ec["end"]["mean"] == pytest.approx(np.mean([c[-1] for c in curves]))
            assert ec["last_generations"]["mean"] == pytest.approx(np.mean([np.mean(c[-10:]) for c in curves]))
            assert ec["end"]["low"] <= ec["end"]["mean"] <= ec["end"]["high"]
        assert "## The Executive's curve" in (tiny / "report.md").read_text()

        # Table 1 counts are the classes of the runs, nine columns per regime, beside the report's own.
        for regime in ("mutual", "independent"):
            counts = res["table1"][regime]
            assert set(counts) == set(CLASSES)  # results.json keeps keys sorted
            assert counts == count(x["class"] for x in res["runs"] if x["regime"] == regime)
            assert sum(counts.values()) == 2
        assert res["table1_report"] == REPORT_COUNTS

        # The rank tests are recomputable from the per-run numbers.
        tests = {t["measure"]: t for t in res["tests"]}
        assert set(tests) == {"final_executive_fitness", "successful_docking"}
        by = {r: [x for x in res["runs"] if x["regime"] == r] for r in ("mutual", "independent")}
        again = compare_samples("final_executive_fitness",
                                "mutual", [x["final_best_so_far"]["executive"] for x in by["mutual"]],
                                "independent", [x["final_best_so_far"]["executive"] for x in by["independent"]])
        assert tests["final_executive_fitness"] == pytest.approx(again.as_dict())
        for t in tests.values():
            assert 0.0 <= t["p_value"] <= 1.0 and 0.0 <= t["a12"] <= 1.0
        assert res["verdict"]
        # A verdict at settings far below the report's says so first, printed and in the report.
        assert res["verdict"].startswith("These settings are below the report's: generations 3 (the report's 50)")
        assert "runs a regime 2 (the report's 10)" in res["verdict"]

        # The CSVs say what results.json says.
        rows = {r["run"]: r for r in _csv(tiny / "runs.csv")}
        assert set(rows) == set(RUNS)
        for x in res["runs"]:
            assert rows[x["run"]]["class"] == x["class"]
            assert float(rows[x["run"]]["docking_from_random_starts"]) == pytest.approx(x["docking_from_random_starts"])
            assert float(rows[x["run"]]["successful_docking"]) == pytest.approx(x["measures"]["successful_docking"])
        curves = _csv(tiny / "curves.csv")
        assert len(curves) == 4 * 3 * 3  # runs x behaviours x generations
        assert Counter(r["behaviour"] for r in curves) == {"tracking": 12, "docking": 12, "executive": 12}

        md = (tiny / "report.md").read_text()
        for part in ("## Verdict", "## Table 1", "| mutual (ours) |", "| mutual (report) |", "| independent (report) |",
                     "## Statistical comparison", "## Runs", "![regimes.png](regimes.png)", res["verdict"]):
            assert part in md, part
        for run in RUNS:
            assert f"| {run} |" in md

        # Each live regime's best and worst run by executive payoff, drawn playing one epoch.
        for regime in ("mutual", "independent"):
            runs = sorted(by[regime], key=lambda x: (x["measures"]["executive_payoff"], x["run"]))
            shown = {r["which"]: r for r in res["robots"] if r["regime"] == regime}
            assert shown["best"]["run"] == runs[-1]["run"] and shown["worst"]["run"] == runs[0]["run"]
            for which in ("best", "worst"):
                name = f"robot-{regime}-{which}.png"
                assert (tiny / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
                assert f"![{name}]({name})" in md


    def test_resume_reruns_only_what_is_unfinished(self, tiny: Path) -> None:
        kept = {r: (tiny / "runs" / r / "summary.json").read_bytes() for r in RUNS if r != "mutual-01"}
        (tiny / "runs" / "mutual-01" / "summary.json").unlink()  # as if killed before the end
        curve = (tiny / "runs" / "mutual-01" / "workers" / "docking" / "curve.jsonl").read_bytes()

        again = coevo("compare", "--out", str(tiny), *TINY)
        assert again.returncode == 2 and "add --resume" in again.stderr
        r = coevo("compare", "--out", str(tiny), "--resume", *TINY)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "3 of 4 runs already done, 1 to run" in r.stdout
        for run, body in kept.items():
            assert (tiny / "runs" / run / "summary.json").read_bytes() == body, run
        assert json.loads((tiny / "runs" / "mutual-01" / "summary.json").read_text())["resumed"] is True
        # continued, not redone
        assert (tiny / "runs" / "mutual-01" / "workers" / "docking" / "curve.jsonl").read_bytes() == curve
        assert json.loads((tiny / "results.json").read_text())["runs_finished"] == 4

        other = coevo("compare", "--out", str(tiny), "--resume", *TINY, "--seed", "7")
        assert other.returncode == 2 and "different comparison" in other.stderr and "seed" in other.stderr


@pytest.mark.parametrize(("args", "message"), [
    (["--regimes", "mutual", "cooperative"], "unknown regime 'cooperative'"),
    (["--regimes", "mutual", "mutual"], "regimes repeat"),
    (["--runs", "0"], "runs"),
    (["--runs", "-3"], "runs"),
    (["--jobs", "0"], "--jobs: invalid number 0"),
    (["--generations", "0"], "generations"),
    (["--measure-epochs", "0"], "--measure-epochs: invalid number 0"),
    (["--max-lead", "-1"], "-1"),
    (["--regimes", "mutual", "independent-offline"], "add independent to the regimes"),
    (["--regimes", "independent", "independent-offline", "--rates", "0", "1"], "--rates: invalid number 0"),
    (["--regimes", "independent", "independent-offline", "--rates", "-2"], "--rates: invalid number -2"),
    (["--regimes", "independent", "independent-offline", "--rates", "1", "1"], "rates repeat"),
    (["--regimes", "independent", "independent-offline", "--rates", "nan"], "--rates: invalid number nan"),
])
def test_bad_settings_fail_before_anything_starts(tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / "never"
    r = coevo("compare", "--out", str(out), "--quiet", *args, timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr
    assert not out.exists()


def test_an_output_directory_that_is_not_a_comparison_is_refused(tmp_path: Path) -> None:
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    r = coevo("compare", "--out", str(tmp_path / "busy"), "--quiet", timeout=60)
    assert r.returncode == 2 and "holds no comparison" in r.stderr
    assert [p.name for p in (tmp_path / "busy").iterdir()] == ["notes.txt"]
    (tmp_path / "file").write_text("x")
    r = coevo("compare", "--out", str(tmp_path / "file"), "--quiet", timeout=60)
    assert r.returncode == 2 and "is a file" in r.stderr
    r = coevo("compare", "--out", str(tmp_path / "nothing"), "--report-only", "--quiet", timeout=60)
    assert r.returncode == 2 and "no compare.json" in r.stderr


@pytest.mark.parametrize(("measures", "expected"), [
    # Good/Poor Docking reads the 20 % on the episodes Docking was picked for (SPEC §2), not on all episodes.
    ({"docking_success_rate": 20.0, "successful_docking": 4.0, "dock_choice": 20.0, "quality_tracking": 60.1},
     "Good Docking / Hi"),
    ({"docking_success_rate": 19.9, "successful_docking": 19.9, "dock_choice": 100.0, "quality_tracking": 60.0},
     "Poor Docking / Med"),
    ({"docking_success_rate": 100.0, "successful_docking": 4.9, "dock_choice": 4.9, "quality_tracking": 30.1},
     "No Docking / Med"),
    ({"docking_success_rate": 0.0, "successful_docking": 0.0, "dock_choice": 0.0, "quality_tracking": 30.0},
     "No Docking / Lo"),
])
def test_table1_class_boundaries(measures: dict[str, float], expected: str) -> None:
    assert classify(measures) == expected


def test_table1_counts_all_nine_classes_and_rejects_others() -> None:
    counts = count(["No Docking / Hi", "No Docking / Hi", "Good Docking / Lo"])
    assert list(counts) == list(CLASSES) and sum(counts.values()) == 3 and counts["No Docking / Hi"] == 2
    for regime, c in REPORT_COUNTS.items():
        assert sum(c.values()) == 10 and set(c) <= set(CLASSES), regime
    with pytest.raises(ValueError, match="Great Docking"):
        count(["Great Docking / Hi"])


def test_rank_comparison_effect_size_and_p_value() -> None:
    lo, hi = [0.1, 0.2, 0.3, 0.4], [0.5, 0.6, 0.7, 0.8]
    t = compare_samples("x", "a", lo, "b", hi)
    assert t.a12 == 1.0 and t.magnitude == "large"
    assert t.p_value == pytest.approx(stats.mannwhitneyu(hi, lo, alternative="two-sided").pvalue)
    assert compare_samples("x", "a", hi, "b", lo).a12 == 0.0
    same = compare_samples("x", "a", [0.0] * 5, "b", [0.0] * 5)  # every run starved: no difference, no NaN
    assert same.a12 == 0.5 and same.p_value == 1.0 and same.magnitude == "negligible"
    rng = np.random.default_rng(3)
    a, b = rng.normal(0, 1, 30), rng.normal(0.5, 1, 30)
    t = compare_samples("x", "a", a, "b", b)
    assert t.a12 == pytest.approx(stats.mannwhitneyu(b, a).statistic / 900)
    assert magnitude(0.5) == "negligible" and magnitude(0.36) == "medium" and magnitude(0.9) == "large"
    with pytest.raises(ValueError, match="non-finite"):
        compare_samples("x", "a", [float("nan")], "b", [1.0])
    with pytest.raises(ValueError, match="at least one run"):
        compare_samples("x", "a", [], "b", [1.0])


def test_mean_interval_bootstrap() -> None:
    rng = np.random.default_rng(5)
    x = rng.normal(0.6, 0.05, 40)
    m = mean_interval(x)
    assert m.n == 40 and m.mean == pytest.approx(x.mean()) and m.low < m.mean < m.high
    half = 1.96 * x.std(ddof=1) / np.sqrt(x.size)  # the normal approximation's interval, for a sample this size
    assert m.high - m.low == pytest.approx(2 * half, rel=0.2)
    assert mean_interval(x) == m  # a fixed seed: the same report when written again
    same = mean_interval([0.5, 0.5, 0.5])  # all equal: the interval is the value, not a failure
    assert (same.low, same.mean, same.high) == (0.5, 0.5, 0.5)
    one = mean_interval([0.7, float("nan")])
    assert one.n == 1 and one.mean == 0.7 and np.isnan(one.low) and "n = 1" in one.text()
    assert mean_interval([]).n == 0 and mean_interval([]).text() == "–"


def test_mean_intervals_is_mean_interval_per_generation() -> None:
    from coevo.experiments.compare.stats import mean_intervals

    runs = np.random.default_rng(3).random((7, 6))
    runs[:, 2] = 0.25  # every run the same
    runs[4, 5] = np.nan  # a run without that generation
    mean, low, high = mean_intervals(runs)
    for j in range(runs.shape[1]):
        one = mean_interval(runs[:, j])
        assert (mean[j], low[j], high[j]) == pytest.approx((one.mean, one.low, one.high), rel=1e-12)
    assert np.isnan(mean_intervals(runs[:1])[1]).all()  # one run: no interval


def test_kruskal_wallis_across_groups_and_its_effect_size() -> None:
    same = compare_groups("x", {"r1": [0.0] * 4, "r2": [0.0] * 4})
    assert same.h == 0.0 and same.p_value == 1.0 and not same.appreciable
    apart = compare_groups("x", {"r1": [0.1, 0.2, 0.3], "r2": [0.4, 0.5, 0.6], "r3": [0.7, 0.8, 0.9]})
    ref = stats.kruskal([0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9])
    assert apart.h == pytest.approx(ref.statistic) and apart.p_value == pytest.approx(ref.pvalue)
    assert apart.epsilon2 == pytest.approx(ref.statistic / 8) and apart.magnitude == "large" and apart.appreciable
    with pytest.raises(ValueError, match="two groups"):
        compare_groups("x", {"r1": [1.0]})


OFFLINE_TINY = ["--regimes", "independent", "independent-offline", "--rates", "0.5", "2", "--runs", "2",
                "--generations", "3", "--population", "6", "--episodes", "10", "--ga", "best_episodes=10",
                "--ga", "initial_rules=8", "--measure-epochs", "5", "--jobs", "2", "--quiet"]


@pytest.mark.slow
def test_independent_offline_learns_the_executive_on_the_live_histories_at_each_rate(tmp_path: Path) -> None:
    out = tmp_path / "offline"
    r = coevo("compare", "--out", str(out), *OFFLINE_TINY)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 of 6 runs already done, 6 to run" in r.stdout
    res = json.loads((out / "results.json").read_text())
    assert res["runs_finished"] == 6
    assert set(res["table1"]) == {"independent", "independent-offline rate 0.5", "independent-offline rate 2"}
    assert [t["measure"] for t in res["rate_tests"]] == ["final_executive_fitness", "successful_docking",
                                                         "docking_success_rate"]
    assert "independent-offline" in res["verdict"] and "rate of asynchrony" in res["verdict"]
    assert (out / "figure-independent-offline.png").stat().st_size > 10_000
    for i in range(2):
        for rate in ("0.5", "2"):
            d = out / "runs" / f"offline-rate{rate}-0{i}"
            cfg = json.loads((d / "config.json").read_text())
            # Learned on the live independent run of the same replicate, with the live Executive's seed.
            assert cfg["history"] == str(out / "runs" / f"independent-0{i}") and cfg["rate"] == float(rate)
            live = json.loads((out / "runs" / f"independent-0{i}" / "run.json").read_text())
            assert cfg["seed"] == live["seed"] + 2
    report = (out / "report.md").read_text()
    assert "## Rates of asynchrony (independent-offline)" in report
    # Resume: an offline run removed is the only one run again.
    import shutil

    shutil.rmtree(out / "runs" / "offline-rate2-01")
    again = coevo("compare", "--out", str(out), "--resume", *OFFLINE_TINY)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "5 of 6 runs already done, 1 to run" in again.stdout


def test_a_history_that_is_incomplete_is_refused(tmp_path: Path) -> None:
    run = tmp_path / "half"
    (run / "workers" / "tracking").mkdir(parents=True)
    RunSettings.make(run="half", regime="independent").save(run / "run.json")
    (run / "workers" / "tracking" / "done.json").write_text(json.dumps({"finished": False, "generations": 12}))
    r = coevo("learn", "--behaviour", "executive", "--history", str(run), "--quiet", "--out", str(tmp_path / "x"),
              timeout=60)
    assert r.returncode == 2 and "is incomplete" in r.stderr and "tracking" in r.stderr and "12 generations" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()
