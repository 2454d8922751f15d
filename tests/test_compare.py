"""`coevo compare`: a tiny real comparison end to end, resuming it, its bad input, and its pieces.

Refusals that come before anything starts run coevo's command line in this process (procs.coevo_main): the same
main() as ``python -m coevo``, without an interpreter started for each."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from procs import THREE_RUN_COMPARISON, coevo_main, copy_of, said_when_made
from scipy import stats

from coevo.experiments.compare.stats import compare_groups, compare_samples, magnitude, mean_interval, mean_intervals
from coevo.experiments.compare.table1 import CLASSES, REPORT_COUNTS, classify, count
from coevo.experiments.glossary import bounds_of
from coevo.rundir.settings import RunSettings

TINY = THREE_RUN_COMPARISON[1:]  # the session's shared comparison's settings (tests/procs.py): 3 runs a regime
RUNS = tuple(f"{regime}-0{i}" for i in range(3) for regime in ("mutual", "independent"))


def coevo(*args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=timeout,
                          check=False)


@pytest.fixture(scope="module")
def tiny(three_run_comparison: Path) -> Path:
    """The session's comparison of 3 runs a regime (tests/procs.py), read-only: the resume test works on a copy, and
    the offline comparison starts from a copy of one of its Independent runs; tests/test_dashboard.py opens it."""
    return three_run_comparison


def _csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.service
@pytest.mark.slow
class TestTinyComparison:
    """The two tests on the session's comparison: the first reads it, the second resumes a copy of it."""

    def test_tiny_comparison_writes_a_consistent_report(self, tiny: Path) -> None:
        assert "0 of 6 runs already done, 6 to run, 2 at a time" in said_when_made(tiny)
        for name in ("compare.json", "report.md", "results.json", "runs.csv", "curves.csv",
                     "figure-mutual.png", "figure-independent.png", "regimes.png"):
            assert (tiny / name).is_file(), name
        for png in tiny.glob("*.png"):
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000

        res = json.loads((tiny / "results.json").read_text())
        assert res["runs_expected"] == res["runs_finished"] == 6
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
            assert ec["end"]["n"] == len(curves) == 3
            expected = mean_interval([c[-1] for c in curves], bounds=bounds_of("executive_end")).as_dict()
            end = dict(ec["end"])
            assert list(end.pop("clipped")) == list(expected.pop("clipped"))  # cut at 0 or 1 where it reached beyond
            assert end == pytest.approx(expected)  # 3 runs: an interval
            assert not np.isnan(ec["end"]["low"]) and not np.isnan(ec["end"]["high"])
            assert ec["end"]["mean"] == pytest.approx(np.mean([c[-1] for c in curves]))
            assert ec["last_generations"]["mean"] == pytest.approx(np.mean([np.mean(c[-10:]) for c in curves]))
            assert ec["tail_generations"] == 3  # a 3-generation run's "last 10 generations" are its 3
        md = (tiny / "report.md").read_text()
        assert "## The Executive's curve" in md and "(n = 3" in md and "too few runs for an interval" not in md
        assert "last 10 generations" not in md and "mean of its last 3 generations" in md

        # Table 1 counts are the classes of the runs, nine columns per regime, beside the report's own.
        for regime in ("mutual", "independent"):
            counts = res["table1"][regime]
            assert set(counts) == set(CLASSES)  # results.json keeps keys sorted
            assert counts == count(x["class"] for x in res["runs"] if x["regime"] == regime)
            assert sum(counts.values()) == 3
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
            assert t["min_p"] == pytest.approx(1 / 10) and 1 / 10 - 1e-12 <= t["p_value"] <= 1.0  # 2 of C(6, 3)
            assert 0.0 <= t["a12"] <= 1.0
        assert res["verdict"].count("with 3 and 3 runs no p below 0.1 is possible") == 2
        # A verdict at settings far below the report's says so first, printed and in the report.
        assert res["verdict"].startswith("These settings are below the report's: generations 3 (the report's 50)")
        assert "runs a regime 3 (the report's 10)" in res["verdict"]

        # The CSVs say what results.json says.
        rows = {r["run"]: r for r in _csv(tiny / "runs.csv")}
        assert set(rows) == set(RUNS)
        for x in res["runs"]:
            assert rows[x["run"]]["class"] == x["class"]
            assert float(rows[x["run"]]["docking_from_random_starts"]) == pytest.approx(x["docking_from_random_starts"])
            assert float(rows[x["run"]]["successful_docking"]) == pytest.approx(x["measures"]["successful_docking"])
        curves = _csv(tiny / "curves.csv")
        assert len(curves) == 6 * 3 * 3  # runs x behaviours x generations
        assert Counter(r["behaviour"] for r in curves) == {"tracking": 18, "docking": 18, "executive": 18}

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


    def test_resume_reruns_only_what_is_unfinished(self, tiny: Path, tmp_path: Path) -> None:
        tiny = copy_of(tiny, tmp_path)
        kept = {r: (tiny / "runs" / r / "summary.json").read_bytes() for r in RUNS if r != "mutual-01"}
        (tiny / "runs" / "mutual-01" / "summary.json").unlink()  # as if killed before the end
        curve = (tiny / "runs" / "mutual-01" / "workers" / "docking" / "curve.jsonl").read_bytes()

        again = coevo_main("compare", "--out", str(tiny), *TINY)
        assert again.returncode == 2 and "add --resume" in again.stderr
        r = coevo("compare", "--out", str(tiny), "--resume", *TINY)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "5 of 6 runs already done, 1 to run" in r.stdout
        for run, body in kept.items():
            assert (tiny / "runs" / run / "summary.json").read_bytes() == body, run
        assert json.loads((tiny / "runs" / "mutual-01" / "summary.json").read_text())["resumed"] is True
        # continued, not redone
        assert (tiny / "runs" / "mutual-01" / "workers" / "docking" / "curve.jsonl").read_bytes() == curve
        assert json.loads((tiny / "results.json").read_text())["runs_finished"] == 6

        other = coevo_main("compare", "--out", str(tiny), "--resume", *TINY, "--seed", "7")
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
    r = coevo_main("compare", "--out", str(out), "--quiet", *args)
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr
    assert not out.exists()


def test_an_output_directory_that_is_not_a_comparison_is_refused(tmp_path: Path) -> None:
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    r = coevo_main("compare", "--out", str(tmp_path / "busy"), "--quiet")
    assert r.returncode == 2 and "holds no comparison" in r.stderr
    assert [p.name for p in (tmp_path / "busy").iterdir()] == ["notes.txt"]
    (tmp_path / "file").write_text("x")
    r = coevo_main("compare", "--out", str(tmp_path / "file"), "--quiet")
    assert r.returncode == 2 and "is a file" in r.stderr
    r = coevo_main("compare", "--out", str(tmp_path / "nothing"), "--report-only", "--quiet")
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
    assert t.p_value == pytest.approx(stats.mannwhitneyu(hi, lo, alternative="two-sided", method="exact").pvalue)
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


def test_mean_interval_is_the_t_interval_and_says_why_when_there_is_none() -> None:
    rng = np.random.default_rng(5)
    x = rng.normal(0.6, 0.05, 40)
    m = mean_interval(x)
    assert m.n == 40 and m.mean == pytest.approx(x.mean()) and m.low < m.mean < m.high
    half = stats.t.ppf(0.975, 39) * x.std(ddof=1) / np.sqrt(x.size)
    assert (m.low, m.high) == pytest.approx((x.mean() - half, x.mean() + half), rel=1e-12)
    assert m.text() == f"{m.mean:.2f} [{m.low:.2f}, {m.high:.2f}] (n = 40)"
    same = mean_interval([0.5, 0.5, 0.5])  # no spread: the value, and the text says so instead of [0.50, 0.50]
    assert (same.low, same.mean, same.high) == (0.5, 0.5, 0.5) and same.text() == "0.50 (all 3 runs equal)"
    two = mean_interval([0.04, 0.10])  # the "0.07 [0.04, 0.10] (n = 2)": no interval, and why
    assert np.isnan(two.low) and np.isnan(two.high)
    assert two.text() == "0.07 (n = 2: too few runs for an interval)"
    one = mean_interval([0.7, float("nan")])
    assert one.n == 1 and one.mean == 0.7 and np.isnan(one.low) and "n = 1: too few runs" in one.text()
    assert mean_interval([]).n == 0 and mean_interval([]).text() == "–"


#: Shapes like the measures' (fitness and shares in [0, 1], AEL in [4, 10]), with their true means.
COVERAGE_SHAPES = {
    "normal(0.5, 0.1)": (lambda r, size: r.normal(0.5, 0.1, size), 0.5),
    "uniform(4, 10)": (lambda r, size: r.uniform(4, 10, size), 7.0),
    "beta(2, 5)": (lambda r, size: r.beta(2, 5, size), 2 / 7),
}


@pytest.mark.parametrize("shape", list(COVERAGE_SHAPES))
def test_mean_intervals_cover_a_known_mean_95_percent_of_the_time(shape: str) -> None:
    """2,000 samples of n runs from a known distribution: the 95 % interval covers its mean in 93-97 % of them at
    n = 5, 10, 50; at n = 2 there is no interval (and the text says why).  The percentile bootstrap used before
    fails this at n = 5 (about 83 %) and n = 10 (about 90 %)."""
    draw, mu = COVERAGE_SHAPES[shape]
    for n in (5, 10, 50):
        x = draw(np.random.default_rng(n), (n, 2000))  # a column is one sample of n runs
        _, low, high = mean_intervals(x)
        covered = float(np.mean((low <= mu) & (mu <= high)))
        assert 0.93 <= covered <= 0.97, (shape, n, covered)
    first = mean_interval(x[:, 0])
    assert (first.low, first.high) == pytest.approx((low[0], high[0]), rel=1e-12)  # the same interval one at a time
    two = draw(np.random.default_rng(2), (2, 2000))
    _, low, high = mean_intervals(two)
    assert np.isnan(low).all() and np.isnan(high).all()
    assert "too few runs for an interval" in mean_interval(two[:, 0]).text()


def test_difference_interval_covers_a_known_difference_95_percent_of_the_time() -> None:
    from coevo.experiments.study.intervals import difference_interval

    for shape, n in (("beta(2, 5)", 5), ("uniform(4, 10)", 10)):  # one call per sample: two cases keep it quick
        draw = COVERAGE_SHAPES[shape][0]
        rng = np.random.default_rng(100 + n)
        hits = 0
        for _ in range(2000):
            d = difference_interval("a", draw(rng, n), "b", draw(rng, n) + 0.1)
            hits += d.low <= 0.1 <= d.high
        assert 0.93 <= hits / 2000 <= 0.97, (shape, n, hits)
    assert np.isnan(difference_interval("a", [0.1, 0.2], "b", [0.3, 0.4, 0.5]).low)  # too few runs: no interval


def test_small_designs_get_exact_p_values_and_their_smallest_p() -> None:
    from coevo.experiments.compare.stats import smallest_p

    # two runs a regime: fully separated is the most extreme of the C(4, 2) = 6 splits, either way: p = 2/6
    t = compare_samples("x", "a", [0.04, 0.10], "b", [0.20, 0.30])
    assert t.p_value == pytest.approx(1 / 3) and t.min_p == pytest.approx(1 / 3)
    tied = compare_samples("x", "a", [0.0, 0.0], "b", [0.2, 0.2])  # scipy's normal approximation gives 0.12 here
    assert tied.p_value == pytest.approx(1 / 3) and stats.mannwhitneyu([0.2, 0.2], [0.0, 0.0]).pvalue < 1 / 3
    assert smallest_p([3, 3]) == pytest.approx(0.1) and smallest_p([5, 5]) == pytest.approx(2 / 252)
    assert smallest_p([10, 10]) == pytest.approx(2 / 184756)
    assert smallest_p([2, 3]) == pytest.approx(1 / 10) and smallest_p([3, 3, 3]) == pytest.approx(6 / 1680)
    assert compare_samples("x", "a", [0.0, 0.0], "b", [1.0, 1.0, 1.0]).p_value == pytest.approx(1 / 10)  # reached
    assert smallest_p([2, 2, 3]) == pytest.approx(2 / 210)
    assert compare_groups("x", {"r1": [0, 0], "r2": [1, 1], "r3": [2, 2, 2]}).p_value == pytest.approx(2 / 210)
    rng = np.random.default_rng(11)
    for na, nb in ((2, 2), (2, 3), (3, 4), (5, 5)):  # whatever the values, no p below the design's smallest
        for _ in range(20):
            a, b = rng.integers(0, 3, na).astype(float), rng.integers(0, 3, nb).astype(float)
            t = compare_samples("x", "a", a, "b", b)
            assert t.min_p - 1e-12 <= t.p_value <= 1.0
    one = compare_groups("x", {"r1": [0.3], "r2": [0.5]})  # one run a level (a study's --runs 1): p = 1, said
    assert one.p_value == 1.0 and one.min_p == 1.0 and compare_samples("x", "a", [0.3], "b", [0.5]).p_value == 1.0
    g = compare_groups("x", {"r1": [0.1, 0.2], "r2": [0.3, 0.4]})  # the χ² approximation would say 0.12
    assert g.p_value == pytest.approx(1 / 3) and g.min_p == pytest.approx(1 / 3)


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
    assert apart.h == pytest.approx(ref.statistic) and apart.p_value == pytest.approx(6 / 1680)  # exact: 1680 splits
    big = {f"r{i}": list(np.random.default_rng(i).random(12)) for i in range(3)}  # 12 runs a group: approximate
    assert compare_groups("x", big).p_value == pytest.approx(stats.kruskal(*big.values()).pvalue)
    assert apart.epsilon2 == pytest.approx(ref.statistic / 8) and apart.magnitude == "large" and apart.appreciable
    with pytest.raises(ValueError, match="two groups"):
        compare_groups("x", {"r1": [1.0]})


OFFLINE_TINY = ["--regimes", "independent", "independent-offline", "--rates", "0.5", "2", "--runs", "2",
                "--generations", "3", "--population", "4", "--episodes", "4", "--ga", "best_episodes=4",
                "--ga", "initial_rules=8", "--measure-epochs", "2", "--jobs", "2", "--quiet"]  # TINY's, 2 runs


@pytest.mark.slow
def test_independent_offline_learns_the_executive_on_the_live_histories_at_each_rate(tiny: Path,
                                                                                     tmp_path: Path) -> None:
    """Its live Independent runs are the tiny comparison's (the same settings and seeds: a paired design), so the
    first is taken from it, as a resume finds it, and the second is run here: an offline run learns on a history
    that was finished before it started, and on one it has to wait for."""
    import shutil

    from coevo.experiments.compare.experiment import CompareSpec, held_spec, prepare

    out = tmp_path / "offline"
    held = held_spec(tiny)
    assert held is not None
    prepare(out, CompareSpec.make(**{**held.model_dump(mode="json"), "regimes": ["independent", "independent-offline"],
                                     "rates": [0.5, 2.0], "runs": 2}), resume=False)
    shutil.copytree(tiny / "runs" / "independent-00", out / "runs" / "independent-00")
    r = coevo("compare", "--out", str(out), "--resume", *OFFLINE_TINY)  # its settings must be the ones prepared
    assert r.returncode == 0, r.stdout + r.stderr
    assert "1 of 6 runs already done, 5 to run" in r.stdout
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
    assert "(n = 2: too few runs for an interval)" in report  # the Executive's curve of 2 runs a group
    # Resume: an offline run removed is the only one run again.
    shutil.rmtree(out / "runs" / "offline-rate2-01")
    again = coevo("compare", "--out", str(out), "--resume", *OFFLINE_TINY)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "5 of 6 runs already done, 1 to run" in again.stdout


def test_a_history_that_is_incomplete_is_refused(tmp_path: Path) -> None:
    run = tmp_path / "half"
    (run / "workers" / "tracking").mkdir(parents=True)
    RunSettings.make(run="half", regime="independent").save(run / "run.json")
    (run / "workers" / "tracking" / "done.json").write_text(json.dumps({"finished": False, "generations": 12}))
    r = coevo_main("learn", "--behaviour", "executive", "--history", str(run), "--quiet", "--out", str(tmp_path / "x"))
    assert r.returncode == 2 and "is incomplete" in r.stderr and "tracking" in r.stderr and "12 generations" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_every_flag_of_compare_is_described_in_its_help() -> None:
    import argparse

    from coevo.experiments.compare.command import configure_compare

    p = argparse.ArgumentParser()
    configure_compare(p)
    bare = [a.option_strings for a in p._actions if not a.help]
    assert not bare, f"flags without a description in coevo compare --help: {bare}"
