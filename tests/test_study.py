"""`coevo study`: declarations and every bad input, cells and seeds, the statistics, and a tiny real study killed
with a signal and resumed; the same for a study of learning runs (``learn``)."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import statistics
import subprocess
import sys
import time
import typing
from pathlib import Path

import numpy as np
import pytest
from procs import coevo_main
from scipy import stats

from coevo.errors import ConfigError, RunDirError
from coevo.experiments.study.declaration import (
    LearnCell,
    cell_seed,
    cells,
    declare,
    learn_cells,
    parse_factor,
    read_toml,
    study_cells,
)
from coevo.experiments.study.experiment import (
    COMPLETE,
    held_declaration,
    is_complete,
    mark_complete,
    prepare_study,
    study_jobs,
    study_progress,
)
from coevo.experiments.compare.stats import holm, mean_interval
from coevo.experiments.study.intervals import difference_interval, share_difference, wilson
from coevo.experiments.study.report import strict_json
from coevo.tasks.fuel.settings import WorldConfig

ROOT = Path(__file__).resolve().parent.parent


def coevo(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=timeout,
                          check=False)


# ---------------------------------------------------------------- declarations
def test_a_toml_declaration_and_the_command_line_combine(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text('name = "pace"\nseed = 11\n[settings]\nruns = 3\nga = { generations = 4 }\n'
                 '[factors]\nmax_lead = [1, "off"]\nmodel = ["best", "recent"]\nga.mutation_rate = [0.05, 0.1]\n')
    spec = declare(toml=read_toml(f), factors=["model=current,recent"], settings={"ga.population": 8})
    assert spec.name == "pace" and spec.seed == 11
    assert spec.factors == {"regime": ("mutual", "independent"), "max_lead": (1, None), "model": ("current", "recent"),
                            "ga.mutation_rate": (0.05, 0.1)}  # regime: a comparison's default, inside each cell
    assert spec.fixed["runs"] == 3 and spec.fixed["ga.generations"] == 4 and spec.fixed["ga.population"] == 8
    cs = cells(spec)
    assert len(cs) == 8  # 2 x 2 x 2, in declared order, the first factor slowest
    assert [c.level("max_lead") for c in cs] == [1] * 4 + [None] * 4
    assert cs[0].id == "00-max_lead=1,model=current,ga.mutation_rate=0.05" and cs[-1].id.startswith("07-max_lead=off")
    assert all(c.spec.runs == 3 and c.spec.ga.generations == 4 and c.spec.ga.population == 8 for c in cs)
    assert {c.spec.ga.mutation_rate for c in cs} == {0.05, 0.1}
    assert declare(toml=read_toml(f), seed=99).seed == 99  # --seed wins over the file's


def test_regime_and_rate_vary_inside_a_cell() -> None:
    spec = declare(factors=["regime=independent,independent-offline", "rate=0.5,2"], settings={"runs": 2})
    (c,) = cells(spec)
    assert c.id == "00-all" and c.spec.regimes == ("independent", "independent-offline") and c.spec.rates == (0.5, 2.0)


@pytest.mark.parametrize(("factors", "settings", "message"), [
    (["pacing=1,2"], {}, "unknown factor 'pacing'"),
    (["max_lead=1,-1"], {}, "invalid max lead -1"),
    (["max_lead=1.5"], {}, "invalid max lead '1.5'"),
    (["model=best,bset"], {}, "unknown partner model 'bset'"),
    (["regime=mutual,cooperative"], {}, "unknown regime 'cooperative'"),
    (["regime=mutual,mutual"], {}, "repeats a level"),
    (["rate=0,1"], {}, "invalid number 0"),
    (["rate=nan"], {}, "invalid number nan"),
    (["rate=1,2"], {}, "add it to the regimes"),
    (["regime=mutual,independent-offline"], {}, "add independent to the regimes"),
    (["runs=0,10"], {}, "invalid number 0"),
    (["ga.mutation_rat=0.1"], {}, "did you mean ga.mutation_rate?"),
    (["world.nothing=1"], {}, "unknown world setting 'world.nothing'"),
    (["ga.population=1,50"], {}, "population=1"),
    (["ga.mutation_rate=2"], {}, "mutation_rate=2"),
    (["world.target_speed=nan,2"], {}, "target_speed"),
    (["max_lead"], {}, "expected NAME=VALUE"),
    (["=1,2"], {}, "expected NAME=VALUE"),
    (["max_lead=1,,2"], {}, "an empty level"),
    (["model=best", "model=recent"], {}, "given twice"),
    ([], {"ga.elite": 60}, "elite (60) must be smaller than population"),
    ([f"ga.mutation_rate={','.join(str(i / 1000) for i in range(101))}",
      f"ga.crossover_rate={','.join(str(i / 100) for i in range(101))}"],
     {}, "the factors make 10201 cells (101 x 101); a study may have at most 10000"),
])
def test_every_bad_factor_is_one_line_naming_it(factors: list[str], settings: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=None) as exc:
        declare(factors=factors, settings=settings)
    assert message in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize(("text", "message"), [
    ("[factors]\nmax_lead = [1, -2]\n", "invalid max lead -2"),
    ("[factors]\nmax_lead = [1, true]\n", "max_lead = True: give a number"),
    ("[settings]\nmodel = [\"best\", \"recent\"]\n", "is a list: put it under [factors]"),
    ("[settings]\nruns = 5\n[factors]\nruns = [5, 10]\n", "both a setting and a factor"),
    ("colour = 3\n", "unknown key 'colour'"),
    ("factors = 3\n", "factors must be a table"),
    ("[factors]\nmax_lead = [1, 2\n", "is not valid TOML"),
    ("seed = -1\n", "invalid seed -1"),
    ('name = "a b"\n', "name 'a b'"),
    ("[factors]\nga = { populaton = [4, 8] }\n", "did you mean ga.population?"),
])
def test_a_bad_study_file_is_one_line_naming_it(tmp_path: Path, text: str, message: str) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ConfigError) as exc:
        declare(toml=read_toml(f), source=str(f))
    assert message in str(exc.value)


def test_parse_factor() -> None:
    assert parse_factor("max_lead=1, 2 ,off") == ("max_lead", ["1", "2", "off"])
    assert parse_factor("world.target_speed=3") == ("world.target_speed", ["3"])


@pytest.mark.parametrize(("args", "message"), [
    (["--factor", "max_lead=1,nope"], "invalid max lead 'nope'"),
    (["--factor", "bogus=1"], "unknown factor 'bogus'"),
    (["--runs", "0"], "--runs: invalid number 0"),
    (["--max-lead", "-1"], "-1"),
    (["--jobs", "0"], "--jobs: invalid number 0"),
    (["--ga", "nonsense=1"], "unknown GA setting 'ga.nonsense'"),
    (["--cluster", "local:zero"], "give a number of workers"),
    (["/nonexistent/study.toml"], "No such file"),
    (["--resume"], "need --out"),
    (["--learn", "executive"], "learn = 'executive': it learns against partner rule sets, which a study's cells do not give"),
    (["--learn", "docking", "--factor", "regime=mutual", "--max-lead", "2"],
     "takes no regime (--factor regime=mutual), max_lead (--max-lead): those are a regime comparison's"),
])
def test_the_command_refuses_bad_input_before_anything_runs(tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / "never"
    r = coevo_main("study", "--out", str(out), "--quiet", *args) if "--resume" not in args else coevo_main("study", *args)
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_the_shipped_studies_are_valid_declarations() -> None:
    files = sorted((ROOT / "studies").glob("*.toml"))
    assert len(files) == 4
    for f in files:
        spec = declare(toml=read_toml(f), source=str(f))
        assert study_cells(spec)
    sensors = declare(toml=read_toml(ROOT / "studies" / "docking-sensors.toml"))
    allowed = typing.get_args(WorldConfig.model_fields["docking_sensors"].annotation)  # every set the world has
    assert sensors.learn == "docking" and sensors.factors == {"world.docking_sensors": allowed}
    assert all(c.spec.runs == 10 for c in learn_cells(sensors))


# ---------------------------------------------------------------- cells and seeds
def test_cell_seeds_depend_on_the_base_seed_and_the_cell_only() -> None:
    a = {c.id.split("-", 1)[1]: c.spec.seed for c in cells(declare(factors=["max_lead=1,2"], seed=4))}
    b = {c.id.split("-", 1)[1]: c.spec.seed for c in cells(declare(factors=["max_lead=2,1,4"], seed=4))}
    assert a["max_lead=1"] == b["max_lead=1"] and a["max_lead=2"] == b["max_lead=2"]  # order, other levels: no matter
    assert a["max_lead=1"] != a["max_lead=2"]
    c = {c.id.split("-", 1)[1]: c.spec.seed for c in cells(declare(factors=["max_lead=1,2"], seed=5))}
    assert c["max_lead=1"] != a["max_lead=1"]
    # The documented rule, computed independently: 48 bits of BLAKE2b-64 of "BASE|LEVELS".
    import hashlib

    digest = hashlib.blake2b(b'4|{"max_lead":1}', digest_size=8).digest()
    assert a["max_lead=1"] == int.from_bytes(digest, "big") >> 16 == cell_seed(4, {"max_lead": 1})
    assert 0 <= a["max_lead=1"] < 2**53


def test_the_study_runs_every_cells_comparison_interleaved(tmp_path: Path) -> None:
    spec = declare(factors=["max_lead=1,off", "regime=mutual"], settings={"runs": 2, "ga.generations": 2})
    the_cells = prepare_study(tmp_path / "s", spec, resume=False)
    jobs = study_jobs(tmp_path / "s", the_cells)
    assert [j.name for j in jobs] == ["00-max_lead=1@mutual-00", "01-max_lead=off@mutual-00",
                                      "00-max_lead=1@mutual-01", "01-max_lead=off@mutual-01"]
    assert not any("/" in j.name for j in jobs)  # a name prefixes a Dask worker's temporary folder
    assert jobs[0].output == "cells/00-max_lead=1/runs/mutual-00"
    assert jobs[0].inputs == ("cells/00-max_lead=1/settings/mutual-00.json",)
    held = json.loads((tmp_path / "s" / "cells" / "01-max_lead=off" / "compare.json").read_text())["spec"]
    assert held["max_lead"] is None and held["seed"] == the_cells[1].spec.seed
    settings = json.loads((tmp_path / "s" / "cells" / "01-max_lead=off" / "settings" / "mutual-01.json").read_text())
    assert settings["seed"] == the_cells[1].spec.seed + 1000
    p = study_progress(tmp_path / "s")
    assert (p.cells_total, p.cells_done, p.runs_total, p.runs_done, p.complete) == (2, 0, 4, 0, False)


def test_a_study_folder_is_refused_unless_it_is_this_study(tmp_path: Path) -> None:
    out = tmp_path / "s"
    spec = declare(factors=["max_lead=1,2"], settings={"runs": 1})
    prepare_study(out, spec, resume=False)
    with pytest.raises(RunDirError, match="add --resume"):
        prepare_study(out, spec, resume=False)
    with pytest.raises(RunDirError, match=r"different study \(differs in: max_lead\)"):
        prepare_study(out, declare(factors=["max_lead=1,4"], settings={"runs": 1}), resume=True)
    with pytest.raises(RunDirError, match="differs in: seed"):
        prepare_study(out, declare(factors=["max_lead=1,2"], settings={"runs": 1}, seed=3), resume=True)
    prepare_study(out, spec, resume=True)
    with pytest.raises(RunDirError, match="holds no study"):
        prepare_study(tmp_path / "empty", spec, resume=True)
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "x").write_text("")
    with pytest.raises(RunDirError, match="not empty; choose another"):
        prepare_study(tmp_path / "busy", spec, resume=False)


def test_the_completion_marker_names_its_declaration_and_a_resume_removes_it(tmp_path: Path) -> None:
    out = tmp_path / "s"
    spec = declare(factors=["max_lead=1,2"], settings={"runs": 1})
    prepare_study(out, spec, resume=False)
    assert not is_complete(out, spec)
    mark_complete(out, spec, runs=4)
    assert is_complete(out, spec) and study_progress(out).complete
    # A marker copied from another study, or torn, does not make this one complete.
    assert not is_complete(out, declare(factors=["max_lead=1,4"], settings={"runs": 1}))
    (out / COMPLETE).write_text("{")
    assert not is_complete(out, spec)
    mark_complete(out, spec, runs=4)
    prepare_study(out, spec, resume=True)  # anything that may run removes it first
    assert not (out / COMPLETE).exists()


# ---------------------------------------------------------------- statistics
def test_wilson_against_known_values() -> None:
    # Brown, Cai & DasGupta's formula, computed independently by scipy, and the textbook 9/10 = [0.5958, 0.9821].
    for k, n in ((9, 10), (0, 10), (10, 10), (3, 50), (27, 50), (1, 1), (0, 1)):
        ref = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
        ours = wilson(k, n)
        assert ours.low == pytest.approx(ref.low, abs=1e-9) and ours.high == pytest.approx(ref.high, abs=1e-9)
    assert wilson(9, 10).low == pytest.approx(0.5958, abs=1e-4) and wilson(9, 10).high == pytest.approx(0.9821, abs=1e-4)
    assert wilson(10, 10).high == 1.0 and wilson(0, 10).low == 0.0
    assert math.isnan(wilson(0, 0).low)
    with pytest.raises(ValueError):
        wilson(11, 10)


def test_holm_against_its_definition() -> None:
    p = [0.01, 0.04, 0.03, 0.005]
    # sorted 0.005, 0.01, 0.03, 0.04 -> x4, x3, x2, x1 -> 0.02, 0.03, 0.06, 0.06 (monotone)
    assert holm(p) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])
    assert holm([]) == []


def test_difference_interval_covers_the_difference_and_shrinks_with_n() -> None:
    rng = np.random.default_rng(3)
    small = difference_interval("a", rng.normal(0, 1, 10), "b", rng.normal(1, 1, 10))
    big = difference_interval("a", rng.normal(0, 1, 400), "b", rng.normal(1, 1, 400))
    assert big.low < 1 < big.high and big.high - big.low < small.high - small.low
    assert abs(big.high - big.low - 2 * 1.96 * math.sqrt(2 / 400)) < 0.05  # the normal theory width, ~0.277
    assert math.isnan(difference_interval("a", [1.0], "b", [2.0, 3.0]).low)
    two = difference_interval("a", [0.1, 0.2], "b", [0.3, 0.5])  # two runs a level: too few for an interval
    assert math.isnan(two.low) and two.diff == pytest.approx(0.25)


def _verdict_of(samples: dict[str, list[float]], *, others: int = 0) -> str:
    """The study verdict's line for one factor test on AEL (``others``: that many more tests with p = 0.01 in the
    study, which Holm's correction weighs it against)."""
    from coevo.experiments.study.report import adjust, factor_test, verdict_lines

    t = factor_test("max_lead", "mutual", "average_epoch_length", samples, share=False)
    assert t is not None
    fillers = [{"p": 0.01} for _ in range(others)]
    adjust([t, *fillers])
    (line,) = verdict_lines([t], lambda _: ("average epoch length", " in mutual"), 4, 4)
    return line


def test_the_verdict_never_calls_an_effect_absent_beside_a_large_one_or_a_difference_that_excludes_0() -> None:
    # The case: AEL 3.67 [2.85, 4.50] and 4.75 [4.65, 4.85] from two runs a level, ε² 0.80, called
    # "No detectable effect ... a difference beyond 0.06 is excluded by every pair's 95 % interval".
    line = _verdict_of({"1": [3.2, 4.1], "off": [4.7, 4.8]})
    assert line.startswith("- **Not established**: an effect of max_lead on average epoch length in mutual")
    assert "the effect size is large (ε² = 0.80)" in line and "No detectable" not in line
    assert "no p below 0.33 is possible" in line and "too few runs for an interval" in line
    assert "excluded" not in line  # no interval of the difference from two runs, so nothing is excluded
    # Five runs a level, far apart, tested among many: Holm's correction keeps p above 5 %.
    apart = {"1": [4.0, 4.1, 4.2, 4.3, 4.4], "off": [4.8, 4.9, 5.0, 5.1, 5.2]}
    line = _verdict_of(apart, others=20)
    assert line.startswith("- **Not established**") and "No detectable" not in line
    assert "the 95 % interval of the difference off − 1 = +0.80 [+0.57, +1.03] excludes 0" in line
    assert "the smallest p possible with 10 runs in 2 levels is 0.0079" in line
    # Two runs a level, levels alike: not "no detectable effect" from a test that can detect none.
    line = _verdict_of({"1": [4.0, 5.0], "off": [4.5, 4.6]})
    assert line.startswith("- Too few runs to test max_lead on average epoch length in mutual: 4 runs in 2 levels "
                           "cannot give p below 0.33 (1: 4.50 (too few runs for an interval)"), line
    # Levels alike, with an interval each: "no detectable effect" and the difference the data exclude.
    rng = np.random.default_rng(1)
    same = {"1": list(rng.normal(5, 0.5, 8)), "off": list(rng.normal(5, 0.5, 8))}
    line = _verdict_of(same)
    assert line.startswith("- No detectable effect of max_lead") and "is excluded by every pair's 95 % interval" in line


def test_the_verdict_decides_on_the_pairs_differences_not_on_whether_the_levels_intervals_overlap() -> None:
    """Two levels whose own 95 % intervals overlap while their difference's excludes 0, with a medium effect size,
    tested among many: the levels' intervals alone said "No detectable effect"; the difference says otherwise."""
    from coevo.experiments.study.report import excluding_zero, factor_test

    low = [round(4 + 2 * i / 29, 4) for i in range(30)]  # 30 runs a level, evenly spread over 4..6
    high = [round(x + 0.36, 4) for x in low]
    t = factor_test("max_lead", "mutual", "average_epoch_length", {"1": low, "off": high}, share=False)
    assert t is not None and t["magnitude"] == "medium"
    one, off = t["levels"]
    assert one["high"] > off["low"]  # the levels' intervals overlap ...
    (d,) = excluding_zero(t)  # ... and the interval of their difference lies above 0
    assert 0 < d["low"] < d["diff"] < d["high"] and d["diff"] == pytest.approx(0.36)
    line = _verdict_of({"1": low, "off": high}, others=20)
    assert line.startswith("- **Not established**: an effect of max_lead"), line
    assert "the 95 % interval of the difference off − 1 = +0.36 [+0.05, +0.67] excludes 0" in line
    assert "No detectable" not in line and "excluded by every pair" not in line
    # the same levels moved together: the difference's interval holds 0, and "no detectable effect" is said with
    # the largest difference every pair's interval excludes
    near = [round(x + 0.05, 4) for x in low]
    t = factor_test("max_lead", "mutual", "average_epoch_length", {"1": low, "off": near}, share=False)
    assert t is not None and excluding_zero(t) == []
    line = _verdict_of({"1": low, "off": near}, others=20)
    big = max(abs(t["differences"][0]["low"]), abs(t["differences"][0]["high"]))
    assert line.startswith("- No detectable effect of max_lead"), line
    assert f"a difference between two levels beyond {big:.2f} is excluded by every pair's 95 % interval" in line


def test_a_levels_fitness_interval_is_cut_at_0_and_the_report_says_so() -> None:
    """The Executive's end is a payoff, 0 to 1: three runs at 0, 0 and 0.3 give a t interval reaching to -0.33; the
    level's summary is cut at 0, and its text in the verdict and the tables says "clipped at 0"."""
    from coevo.experiments.glossary import bounds_of
    from coevo.experiments.study.report import factor_test, format_mean

    assert bounds_of("executive_end") == (0.0, 1.0) and bounds_of("average_epoch_length") is None
    t = factor_test("max_lead", "mutual", "executive_end", {"1": [0.0, 0.0, 0.3], "off": [0.3, 0.35, 0.4]},
                    share=False, bounds=bounds_of("executive_end"))
    assert t is not None
    one, off = t["levels"]
    assert one["low"] == 0.0 and one["clipped"] == (0.0,) and 0 < off["low"] and off["clipped"] == ()
    assert format_mean(one, False) == f"0.10 [0.00, {one['high']:.2f}] (clipped at 0)"
    assert format_mean(off, False) == f"0.35 [{off['low']:.2f}, {off['high']:.2f}]"
    assert format_mean({**one, "clipped": [0.0]}, False) == format_mean(one, False)  # as read from results.json


def test_shares_are_decided_on_newcombes_interval_of_their_difference() -> None:
    """A share (Good Docking) at 2 of 20 and 9 of 20 runs: the Wilson intervals [3-30 %] and [26-66 %] overlap,
    Newcombe's interval of the difference lies above 0, so among many tests it is "not established", in points."""
    from coevo.experiments.study.report import adjust, factor_test, verdict_lines

    t = factor_test("model", "mutual", "good_docking", {"best": [1.0] * 2 + [0.0] * 18,
                                                        "current": [1.0] * 9 + [0.0] * 11}, share=True)
    assert t is not None
    best, current = t["levels"]
    assert best["high"] > current["low"]
    adjust([t, *({"p": 0.01} for _ in range(20))])
    (line,) = verdict_lines([t], lambda _: ("good docking", " in mutual"), 40, 40)
    assert line.startswith("- **Not established**"), line
    assert re.search(r"the difference current − best = \+35 percentage points \[\+\d+, \+\d+\] excludes 0", line), line


# ---------------------------------------------------------------- a tiny real study, killed and resumed
TINY = ["--factor", "max_lead=1,off", "--factor", "regime=mutual", "--runs", "2", "--generations", "3",
        "--population", "6", "--episodes", "10", "--ga", "best_episodes=10", "--ga", "initial_rules=8",
        "--measure-epochs", "5", "--jobs", "2", "--seed", "3"]


def _summaries(out: Path) -> dict[str, bytes]:
    return {str(f.relative_to(out)): f.read_bytes() for f in out.glob("cells/*/runs/*/summary.json")}


def _resume_keeps_what_was_done(out: Path, kept: dict[str, bytes], *, timeout: float) -> None:
    """``coevo study --resume`` of a 2 x 2 study (its declaration, held) runs only what is missing and completes it."""
    r = coevo("study", "--out", str(out), "--resume", "--quiet", "--jobs", "2", timeout=timeout)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"{len(kept)} of 4 runs already done, {4 - len(kept)} to run" in r.stdout
    assert "These settings are below the report's" in r.stdout  # the smoke-test warning with the printed verdict
    for name, body in kept.items():  # finished runs are not redone
        assert (out / name).read_bytes() == body, name
    progress = study_progress(out)
    assert progress.complete and (progress.cells_done, progress.runs_done) == (2, 4)


@pytest.mark.service
@pytest.mark.slow
def test_a_tiny_study_killed_with_a_signal_resumes_and_reports(tmp_path: Path) -> None:
    out = tmp_path / "study"
    p = subprocess.Popen([sys.executable, "-m", "coevo", "study", "--out", str(out), "--quiet", *TINY],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 300
    while not _summaries(out) and time.monotonic() < deadline and p.poll() is None:
        time.sleep(0.5)
    assert p.poll() is None, p.communicate()
    os.killpg(p.pid, signal.SIGKILL)  # the study and every run under it, as a crash or a lost host
    p.wait()
    kept = _summaries(out)
    assert 1 <= len(kept) < 4
    progress = study_progress(out)
    assert not progress.complete and progress.runs_done == len(kept) and progress.runs_total == 4
    assert not (out / COMPLETE).exists() and not (out / "report.md").exists()

    again = coevo_main("study", "--out", str(out), "--quiet", *TINY)
    assert again.returncode == 2 and "add --resume" in again.stderr
    other = coevo_main("study", "--out", str(out), "--resume", "--quiet", *TINY[:-1], "4")
    assert other.returncode == 2 and "differs in: seed" in other.stderr
    _resume_keeps_what_was_done(out, kept, timeout=400)
    res = json.loads((out / "results.json").read_text())
    assert res["runs_finished"] == res["runs_expected"] == 4
    assert {r["cell"] for r in res["cell_rows"]} == {"00-max_lead=1", "01-max_lead=off"}
    for row in res["cell_rows"]:
        assert row["n"] == 2 and sum(v["k"] for v in row["table1"].values()) == 2
        nd = row["no_docking"]
        ref = stats.binomtest(nd["k"], 2).proportion_ci(method="wilson")
        assert nd["low"] == pytest.approx(ref.low) and nd["high"] == pytest.approx(ref.high)
    tests = {(t["factor"], t["measure"]): t for t in res["tests"]}
    assert ("max_lead", "executive_end") in tests
    t = tests[("max_lead", "executive_end")]
    assert t["min_p"] == pytest.approx(1 / 3)  # two runs a level: no exact p below 1/3, and none given
    assert t["min_p"] <= t["p"] <= t["p_holm"]
    assert "No detectable effect" not in res["verdict"]  # 2 runs a level: "too few runs to test" or "not established"
    md = (out / "report.md").read_text()
    for part in ("# Study `study`", "## Verdict", "## Table 1 per cell, with 95 % Wilson intervals",
                 "## Factor tests", "effect-max_lead.png", "cells.png"):
        assert part in md, part
    for png in ("effect-max_lead.png", "cells.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    # --report-only rewrites the report and keeps the study complete.
    r = coevo_main("study", "--out", str(out), "--report-only", "--quiet")  # a reader of files: in this process
    assert r.returncode == 0, r.stdout + r.stderr
    assert study_progress(out).complete


def test_newcombe_difference_of_two_shares() -> None:
    # Newcombe (1998), Table II, example (a): 56/70 - 48/80 = 0.2000, method 10: [0.0524, 0.3339].
    d = share_difference("b", 48, 80, "a", 56, 70)
    assert d.diff == pytest.approx(0.2) and d.low == pytest.approx(0.0524, abs=1e-4)
    assert d.high == pytest.approx(0.3339, abs=1e-4)
    same = share_difference("a", 0, 10, "b", 0, 10)  # both 0 of 10: not a point, a range either way
    assert same.low < -0.2 and same.high > 0.2


def test_study_help_loads_no_statistics_or_plotting() -> None:
    code = ("import sys\nfrom coevo.cli import main\ntry:\n    main(['study', '--help'])\nexcept SystemExit:\n    pass\n"
            "print(' '.join(sorted(m for m in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    loaded = set(out.strip().splitlines()[-1].split())
    assert not {"matplotlib", "scipy", "zenoh", "coevo.experiments.study.report"} & loaded


def test_progress_of_a_folder_that_holds_no_study_is_one_error(tmp_path: Path) -> None:
    with pytest.raises(RunDirError, match="holds no study"):
        study_progress(tmp_path)
    (tmp_path / "study.json").write_text("{")
    with pytest.raises(RunDirError, match="cannot be read"):
        study_progress(tmp_path)


@pytest.mark.service
@pytest.mark.slow
def test_a_tiny_study_runs_on_a_local_dask_cluster(tmp_path: Path) -> None:
    """On Dask each replicate runs in a worker's temporary folder and comes back as a tar (no shared directory)."""
    out = tmp_path / "dask"
    r = coevo("study", "--out", str(out), "--quiet", "--factor", "regime=independent", "--factor", "max_lead=1,off",
              "--runs", "1", "--generations", "2", "--population", "6", "--episodes", "10", "--ga", "best_episodes=10",
              "--ga", "initial_rules=8", "--measure-epochs", "5", "--cluster", "local:2", timeout=400)
    assert r.returncode == 0, r.stdout + r.stderr
    p = study_progress(out)
    assert p.complete and (p.cells_done, p.runs_done) == (2, 2)
    assert sorted(f.name for f in (out / "logs").iterdir()) == ["00-max_lead=1@independent-00.log",
                                                                "01-max_lead=off@independent-00.log"]


# ---------------------------------------------------------------- studies of learning runs
def test_a_learning_study_is_declared_in_a_file_or_on_the_command_line(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text('name = "sensors"\nseed = 5\n[settings]\nlearn = "docking"\nruns = 3\nmeasure_epochs = 2\n'
                 'ga = { generations = 4 }\n[factors]\nworld.docking_sensors = ["polar", "both"]\n')
    spec = declare(toml=read_toml(f))
    assert spec.learn == "docking" and spec.factors == {"world.docking_sensors": ("polar", "both")}
    assert not {"regime", "max_lead", "model", "rate"} & set(dict(spec.levels))  # a comparison's defaults dropped
    line = declare(factors=["world.docking_sensors=polar,both"], seed=5,
                   settings={"learn": "docking", "runs": 3, "measure_epochs": 2, "ga.generations": 4})
    assert [c.args for c in learn_cells(line)] == [c.args for c in learn_cells(spec)]  # the same study either way
    a, b = learn_cells(spec)
    assert isinstance(a, LearnCell) and a.id == "00-world.docking_sensors=polar" and b.spec.world.docking_sensors == "both"
    assert a.spec.runs == 3 and a.spec.measure_epochs == 2 and a.spec.ga.generations == 4
    # what coevo learn is given: the declared settings only (JSON values), so its own defaults stay its own
    assert a.args == ("--ga=generations=4", '--world=docking_sensors="polar"', "--measure-epochs=2")
    with pytest.raises(ConfigError, match="a study of learning runs"):
        cells(spec)
    # a comparison study's declaration has no learn: its study.json, seeds and completion digest are as they were
    assert "learn" not in dict(declare(factors=["max_lead=1,2"]).as_dict()["levels"])
    assert declare(settings={"learn": "tracking"}).learn == "tracking"


@pytest.mark.parametrize(("toml", "factors", "settings", "message"), [
    ("", ["regime=mutual,independent"], {"learn": "docking"},
     "learn = docking: a study of learning runs takes no regime (--factor regime=mutual,independent): that is a "
     "regime comparison's; remove it"),
    ("", ["rate=1,2"], {"learn": "docking"}, "takes no rate (--factor rate=1,2)"),
    ("", [], {"learn": "docking", "model": "best"}, "takes no model (--model)"),
    ("", ["max_lead=1,2", "model=best,recent"], {"learn": "tracking"},
     "takes no max_lead (--factor max_lead=1,2), model (--factor model=best,recent)"),
    ('[settings]\nlearn = "docking"\n[factors]\nmodel = ["best", "recent"]\n', [], {},
     "takes no model (the study file, [factors])"),
    ('[settings]\nmax_lead = 2\n', [], {"learn": "docking"}, "takes no max_lead (the study file, [settings])"),
    ("", [], {"learn": "executive"}, "learn = 'executive': it learns against partner rule sets"),
    ("", [], {"learn": "nosuch"}, "learn = 'nosuch': not a behaviour of an installed task (coevo plugins lists them)"),
    ('[settings]\nlearn = 3\n', [], {}, "learn = 3: not a behaviour of an installed task"),
    ('[settings]\nlearn = ["docking"]\n', [], {}, "is a list: put it under [factors]"),
    ("", ["learn=docking,tracking"], {}, "a study learns one behaviour"),
    ("", ["ga.population=1,8"], {"learn": "docking"}, "cell 00-ga.population=1: GAConfig: population=1"),
    ("", [], {"learn": "docking", "ga.elite": 60}, "elite (60) must be smaller than population"),
])
def test_a_bad_learning_study_is_one_line_naming_it(tmp_path: Path, toml: str, factors: list[str],
                                                    settings: dict[str, object], message: str) -> None:
    f = tmp_path / "s.toml"
    f.write_text(toml)
    with pytest.raises(ConfigError) as exc:
        declare(toml=read_toml(f), factors=factors, settings=settings)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_learning_cells_take_their_seeds_as_comparison_cells_do_and_run_through_the_same_runner(tmp_path: Path) -> None:
    spec = declare(factors=["world.docking_sensors=polar,both"], settings={"learn": "docking", "runs": 2}, seed=4)
    the_cells = learn_cells(spec)
    polar = cell_seed(4, {"world.docking_sensors": "polar"})
    assert the_cells[0].spec.seed == polar and the_cells[0].spec.seeds == [polar, polar + 1000]
    assert polar == cells(declare(factors=["world.docking_sensors=polar,both"], seed=4))[0].spec.seed  # the one rule
    more = learn_cells(declare(factors=["world.docking_sensors=both,dock-frame,polar"],
                               settings={"learn": "docking", "runs": 2}, seed=4))
    assert {c.id.split("-", 1)[1]: c.spec.seeds for c in more}["world.docking_sensors=polar"] == [polar, polar + 1000]
    assert len({s for c in the_cells for s in c.spec.seeds}) == 4

    out = tmp_path / "s"
    prepare_study(out, spec, resume=False)
    jobs = study_jobs(out, the_cells)
    (p0, p1), (b0, b1) = (the_cells[0].spec.seeds, the_cells[1].spec.seeds)
    assert [j.name for j in jobs] == [f"00-world.docking_sensors=polar@docking-seed{p0}",
                                      f"01-world.docking_sensors=both@docking-seed{b0}",
                                      f"00-world.docking_sensors=polar@docking-seed{p1}",
                                      f"01-world.docking_sensors=both@docking-seed{b1}"]  # interleaved, run 0 first
    assert jobs[0].output == f"cells/00-world.docking_sensors=polar/runs/docking-seed{p0}" and jobs[0].weight == 1
    argv = jobs[0].command(out) if jobs[0].command is not None else []
    assert argv[1:] == ["-m", "coevo", "learn", "--behaviour", "docking", "--seed", str(p0), "--out",
                        str(out / jobs[0].output), "--quiet", '--world=docking_sensors="polar"', "--measure-epochs=100"]
    held = json.loads((out / "cells" / "01-world.docking_sensors=both" / "learn.json").read_text())
    assert held["spec"]["seed"] == b0 and held["spec"]["behaviour"] == "docking"
    p = study_progress(out)
    assert (p.cells_total, p.cells_done, p.runs_total, p.runs_done, p.complete) == (2, 0, 4, 0, False)
    with pytest.raises(RunDirError, match="differs in: learn"):
        prepare_study(out, declare(factors=["world.docking_sensors=polar,both"],
                                   settings={"learn": "tracking", "runs": 2}, seed=4), resume=True)


def test_a_half_written_learning_run_is_never_finished_and_is_run_again(tmp_path: Path) -> None:
    out = tmp_path / "s"
    spec = declare(settings={"learn": "tracking", "runs": 2}, seed=1)
    the_cells = prepare_study(out, spec, resume=False)
    first, second = study_jobs(out, the_cells)
    torn = out / first.output  # as a copy cut short would leave it: some files, not its measures and timing both
    torn.mkdir(parents=True)
    (torn / "curve.csv").write_text("generation,best_fitness\n0,0.5\n")
    (torn / "measures.json").write_text("{}")
    assert not first.finished(out) and study_progress(out).runs_done == 0
    assert first.command is not None and first.command(out)[3] == "learn"  # what runs it removes the torn copy first
    assert not torn.exists()
    whole = out / second.output
    whole.mkdir(parents=True)
    (whole / "measures.json").write_text('{"quality_tracking": 50.0}')
    (whole / "timing.json").write_text('{"seconds": 1.0}')
    assert second.finished(out) and study_progress(out).runs_done == 1
    assert second.command is not None and second.command(out) and (whole / "measures.json").exists()  # kept


TINY_LEARN = ["--learn", "docking", "--factor", "world.docking_sensors=polar,both", "--runs", "2", "--generations", "2",
              "--population", "4", "--episodes", "4", "--ga", "best_episodes=4", "--measure-epochs", "1", "--seed", "9"]


@pytest.mark.service
@pytest.mark.slow
def test_a_tiny_learning_study_killed_resumes_and_reports_its_runs_measures(tmp_path: Path) -> None:
    """2 cells x 2 runs of coevo learn --behaviour docking: killed after its first run, a run's folder torn, resumed;
    the report's numbers per cell are the runs' measures.json, and the dashboard reads the same."""
    out = tmp_path / "learn"
    p = subprocess.Popen([sys.executable, "-m", "coevo", "study", "--out", str(out), "--quiet", "--jobs", "1",
                          *TINY_LEARN], stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    def runs_done() -> int:
        return study_progress(out).runs_done if (out / "study.json").exists() else 0

    deadline = time.monotonic() + 120
    while runs_done() == 0:  # a study's --jobs 1 runs two learning runs at once (half a slot each): two more wait
        assert p.poll() is None and time.monotonic() < deadline, p.communicate()
        time.sleep(0.1)
    os.killpg(p.pid, signal.SIGKILL)  # the study and the run under way, as a crash would
    p.wait()
    progress = study_progress(out)
    # (a run killed while coevo learn wrote it is a hidden .NAME.*.partial folder: never counted)
    kept = {str(f.relative_to(out)): f.read_bytes() for f in out.glob("cells/*/runs/[!.]*/measures.json")}
    assert 1 <= progress.runs_done == len(kept) < 4 and not progress.complete and not (out / "report.md").exists()
    held = held_declaration(out)
    assert held is not None and held.learn == "docking"
    torn = next(j for j in study_jobs(out, learn_cells(held)) if not j.finished(out))
    (out / torn.output).mkdir(parents=True)
    (out / torn.output / "config.json").write_text("{")  # a half-written run: not counted, run again
    assert study_progress(out).runs_done == len(kept)

    _resume_keeps_what_was_done(out, kept, timeout=300)

    res = json.loads((out / "results.json").read_text())
    assert res["kind"] == "learn" and res["runs_finished"] == res["runs_expected"] == 4
    assert res["measures"][0] == "docking_from_random_starts"
    for row in res["cell_rows"]:
        folder = out / "cells" / row["cell"] / "runs"
        runs = [json.loads((folder / f"docking-seed{s}" / "measures.json").read_text()) for s in row["seeds"]]
        assert row["n"] == 2 and len(runs) == 2
        for key in res["measures"]:
            values = [float(m[key]) for m in runs]
            want = mean_interval(values).as_dict()
            got = row["measures"][key]
            assert got["mean"] == pytest.approx(want["mean"]) and got["median"] == pytest.approx(statistics.median(values))
            assert (got["low"], got["high"]) == (None, None) and math.isnan(want["low"])  # 2 runs: no interval
    for run in res["runs"]:  # every run's measures, exactly as coevo learn wrote them
        assert run["measures"] == json.loads((out / "cells" / run["cell"] / "runs" / run["run"] / "measures.json")
                                             .read_text())
    tests = {t["measure"]: t for t in res["tests"]}
    assert set(tests) == set(res["measures"]) and all(t["factor"] == "world.docking_sensors" for t in tests.values())
    md = (out / "report.md").read_text()
    for part in ("# Study `study`", "A study of learning runs", "## Verdict", "## Cells", "## Factor tests",
                 "Docking from random starts (%) mean [95 %]", "effect-world.docking_sensors.png", "cells.png"):
        assert part in md, part
    for png in ("effect-world.docking_sensors.png", "cells.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    from coevo.dashboard.model import Dashboard

    dash = Dashboard(target=out, stale=60)
    dash.refresh()
    s = dash.current()[1].study
    assert s["kind"] == "learn" and s["state"] == "finished" and s["shown"] == {}  # no cell is a comparison
    # the page's rows are the report's (NaN there, null in results.json: no interval from two runs)
    assert [strict_json(c["rows"][0]["measures"]) for c in s["cells"]] == [r["measures"] for r in res["cell_rows"]]
