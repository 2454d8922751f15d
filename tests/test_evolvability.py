"""Mutation models, the dynamic landscape generator, the bit-string GA and ``coevo evolvability``."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy import stats

from coevo.cli import build_parser, main
from coevo.config import GAConfig
from coevo.console import ga_settings
from coevo.errors import ConfigError
from coevo.experiments.evolvability.bitga import GENOME_BITS, RunParams, breed, decode, gene_of, run_batch
from coevo.experiments.evolvability.experiment import GridSpec
from coevo.experiments.evolvability.landscape import CLASSES, DynamicLandscape, LandscapeSpec
from coevo.experiments.evolvability.report import shift_windows
from coevo.ga import GA
from coevo.ga.mutation import FixedHypermutation, GeneticHypermutation, GeneticRate, control_rate, model_from_config
from coevo.rundir.settings import RunSettings
from coevo.tasks import get_task
from coevo.tasks.fuel.settings import WorldConfig

FUEL = get_task("fuel")

P_MIN = 1e-3  # seeded tests: a correct model fails this only by a 1-in-1000 draw, and the seed fixes the draw


def _popcount(x: np.ndarray) -> int:
    return int(sum(int(v).bit_count() for v in x.ravel()))


def _genome(x1: int, x2: int, k: int) -> np.uint64:
    return np.uint64(x1 | (x2 << 20) | (k << 40))


# -- the bit-string GA's mutation models: a population of one repeated genome, so any change is mutation ---------


def _breed_clones(model: str, rate: float, k: int, *, runs: int = 40, n: int = 100, seed: int = 5) -> tuple[np.ndarray, np.uint64]:
    g0 = _genome(123_456, 654_321, k)
    g = np.full((runs, n), g0, dtype=np.uint64)
    params = RunParams.make([model] * runs, [rate] * runs)
    return breed(g, np.ones((runs, n)), params, np.random.default_rng(seed)), g0


@pytest.mark.parametrize("rate", [0.01, 0.1])
def test_fm_resets_each_bit_with_the_base_rate(rate: float) -> None:
    kids, g0 = _breed_clones("fm", rate, k=5)
    flips = _popcount(kids ^ g0)  # a reset bit changes half the time: flips ~ Binomial(bits, rate / 2)
    bits = kids.size * GENOME_BITS
    assert stats.binomtest(flips, bits, rate / 2).pvalue > P_MIN
    per_position = np.array([int(((kids ^ g0) >> np.uint64(b) & np.uint64(1)).sum()) for b in range(GENOME_BITS)])
    assert stats.chisquare(per_position).pvalue > P_MIN  # no position favoured


@pytest.mark.parametrize("k", [0, 3, 7])
def test_gm_rate_is_alpha_plus_k_over_8_and_ignores_the_base_rate(k: int) -> None:
    kids, g0 = _breed_clones("gm", 0.3, k=k)
    flips = _popcount(kids ^ g0)
    expected = min(0.03 + k / 8, 1.0) / 2
    assert stats.binomtest(flips, kids.size * GENOME_BITS, expected).pvalue > P_MIN


def test_fh_replaces_exactly_the_fraction_hr_by_random_immigrants() -> None:
    kids, g0 = _breed_clones("fh", 0.0, k=2)  # mr = 0: only immigrants differ
    assert ((kids != g0).sum(axis=1) == 20).all()  # round(0.2 * 100) in every run
    x = decode(kids[kids != g0])
    assert stats.kstest(x[:, 0] / 100, "uniform").pvalue > P_MIN  # immigrants are uniform random points


@pytest.mark.parametrize("k", [0, 4])
def test_gh_hypermutates_with_probability_alpha_h_plus_k_over_8(k: int) -> None:
    kids, g0 = _breed_clones("gh", 0.0, k=k)
    changed = int((kids != g0).sum())
    assert stats.binomtest(changed, kids.size, 0.05 + k / 8).pvalue > P_MIN
    assert stats.chisquare(np.bincount(gene_of(kids[kids != g0]), minlength=8)).pvalue > P_MIN  # new gene random


def test_gh_non_hypermutants_mutate_at_the_base_rate() -> None:
    kids, g0 = _breed_clones("gh", 0.02, k=0, runs=60)
    d = kids ^ g0
    small = d[np.array([int(v).bit_count() for v in d.ravel()]).reshape(d.shape) <= 6]  # drop the random resets
    assert abs(_popcount(small) / (small.size * GENOME_BITS) - 0.01) < 0.002


def test_selection_is_proportional_and_crossover_keeps_bits() -> None:
    rng = np.random.default_rng(0)
    runs, n = 200, 10
    g = np.tile(np.arange(n, dtype=np.uint64), (runs, 1))  # distinct genomes differing only in low bits
    fit = np.tile(np.arange(1, n + 1, dtype=float), (runs, 1))
    kids = breed(g, fit, RunParams.make(["fm"] * runs, [0.0] * runs), rng, crossover_rate=0.0)
    counts = np.bincount(kids.ravel().astype(np.int64), minlength=n)
    expected = fit[0] / fit[0].sum() * kids.size
    assert stats.chisquare(counts, expected).pvalue > P_MIN
    kids = breed(g, np.ones((runs, n)), RunParams.make(["fm"] * runs, [0.0] * runs), rng, crossover_rate=1.0)
    assert _popcount(kids) == _popcount(g)  # 2-point crossover swaps bits between mates, never makes or loses ones


# -- the rule-set GA's models -----------------------------------------------------------------------------------


def test_rule_set_control_gene_mutation_and_hypermutation_statistics() -> None:
    rng = np.random.default_rng(3)
    gm = GeneticRate(0.03)
    assert gm.rate(0) == pytest.approx(0.03) and gm.rate(7) == pytest.approx(0.905)
    genes = np.array([gm.mutate_gene(5, rng) for _ in range(4000)])
    flips = _popcount(np.asarray(genes ^ 5, dtype=np.uint64))
    assert stats.binomtest(flips, 4000 * 3, gm.rate(5) / 2).pvalue > P_MIN
    gh = GeneticHypermutation(0.05, 0.1)
    k = np.repeat(np.arange(8), 500)
    hyper = gh.hypermutants(k, rng)
    for level in range(8):
        assert stats.binomtest(int(hyper[k == level].sum()), 500, float(control_rate(level, 0.05))).pvalue > P_MIN
    assert FixedHypermutation(0.2, 0.1).hypermutants(np.zeros(50, np.uint8), rng).sum() == 10


@pytest.mark.parametrize("name", ["gm", "fh", "gh"])
def test_ga_carries_one_control_gene_per_individual(name: str) -> None:
    cfg = GAConfig(population=8, episodes=4, best_episodes=4, lane_episodes=2, initial_rules=4, max_rules=8,
                   mutation_model=name, hypermutation_rate=0.5, min_hypermutation_rate=0.5)
    ga = GA(FUEL, "tracking", world=WorldConfig(), ga=cfg, seed=2)
    assert type(ga.mutation) is type(model_from_config(cfg))
    ga.generation({})
    assert ga.genes.shape == (8,) and ga.genes.dtype == np.uint8 and ga.genes.max() < 8
    if name == "fh":
        assert not ga.genes.any()


def test_mutation_model_flag_sets_the_ga_setting(tmp_path: Path) -> None:
    args = build_parser().parse_args(["learn", "--behaviour", "docking", "--mutation-model", "gh",
                                      "--ga", "min_hypermutation_rate=0.1"])
    ga = ga_settings(args, "fuel")
    assert (ga.mutation_model, ga.min_hypermutation_rate) == ("gh", 0.1)
    assert GAConfig().mutation_model == "fm"
    with pytest.raises(ConfigError, match="mutation_model='gx'"):
        ga_settings(build_parser().parse_args(["run", "--mutation-model", "gx"]), "fuel")
    # coevo run / compare hand their GA settings to each worker process once, in the run's run.json
    f = tmp_path / "run.json"
    RunSettings.make(run="r", regime="mutual", ga=ga).save(f)
    assert RunSettings.load(f).ga == ga


# -- landscapes --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", ["gradual", "abrupt"])
def test_landscape_maximum_is_100_at_all_times(cls: str) -> None:
    land = DynamicLandscape(CLASSES[cls], seed=4, generations=60)
    rng = np.random.default_rng(0)
    grid = np.stack(np.meshgrid(np.linspace(0, 100, 51), np.linspace(0, 100, 51)), axis=-1).reshape(-1, 2)
    for t in range(60):
        assert land.fitness(land.optimum_at(t), t) == pytest.approx(100.0, rel=1e-12)
        pts = np.concatenate([grid, rng.uniform(0, 100, (1000, 2)), land.centres[t]])
        f = land.fitness(pts, t)
        assert f.max() <= 100.0 + 1e-9 and f.min() > 0
        if t % 15 == 0:  # the fast evaluation is the defining formula
            np.testing.assert_allclose(f, land.fitness_direct(pts, t), rtol=1e-10)


def test_gradual_peaks_drift_a_bounded_distance_every_generation() -> None:
    land = DynamicLandscape(CLASSES["gradual"], seed=8, generations=120)
    step = np.linalg.norm(np.diff(land.centres, axis=0), axis=2)
    assert step.max() <= 1.0 + 1e-9
    assert (step > 0).mean() > 0.99  # every peak moves every generation
    assert 0.4 < step.mean() < 0.55  # U[0, 1] (reflection shortens a few steps)
    assert land.centres.min() >= 0 and land.centres.max() <= 100


def test_abrupt_peaks_are_still_then_jump_at_each_punctuation() -> None:
    land = DynamicLandscape(CLASSES["abrupt"], seed=8, generations=200)
    step = np.linalg.norm(np.diff(land.centres, axis=0), axis=2)  # step[t-1]: move into generation t
    moved = np.flatnonzero(step.max(axis=1) > 0) + 1
    assert moved.tolist() == list(range(20, 200, 20)) == land.changes().tolist()
    jumps = step[moved - 1]
    assert jumps.max() <= 50 + 1e-9 and jumps.mean() > 15  # U[0, 50], shortened a little by reflection
    assert land.centres.min() >= 0 and land.centres.max() <= 100


def test_landscapes_are_reproducible_from_their_seed() -> None:
    a, b = (DynamicLandscape(CLASSES["gradual"], seed=11, generations=30) for _ in range(2))
    assert np.array_equal(a.centres, b.centres) and np.array_equal(a.amplitude, b.amplitude)
    c = DynamicLandscape(CLASSES["gradual"], seed=12, generations=30)
    assert not np.array_equal(a.centres, c.centres)
    assert (a.amplitude == 100).sum() == 1 and a.amplitude[1:].min() >= 10 and a.amplitude[1:].max() <= 50
    with pytest.raises(ConfigError):
        LandscapeSpec(amplitude=(10, 150))


def test_run_batch_is_deterministic_and_improves_on_random_search() -> None:
    land = DynamicLandscape(LandscapeSpec(n_peaks=32, max_drift=0.0), seed=1, generations=30)
    params = RunParams.make(["fm", "gm", "fh", "gh"], [0.01] * 4)
    a = run_batch(land, params, population=40, generations=30, seed=9)
    b = run_batch(land, params, population=40, generations=30, seed=9)
    assert np.array_equal(a.best, b.best) and np.array_equal(a.control, b.control, equal_nan=True)
    assert (a.best[:, -5:].mean(axis=1) > a.best[:, 0]).all()  # a static landscape: the GA climbs
    assert np.isnan(a.control[[0, 2]]).all() and not np.isnan(a.control[[1, 3]]).any()


def test_shift_windows_pair_after_and_before() -> None:
    w = shift_windows([20, 40, 60], 70)
    assert [(list(a), list(b)) for a, b in w] == [
        ([20, 21, 22, 23, 24], [35, 36, 37, 38, 39]),
        ([40, 41, 42, 43, 44], [55, 56, 57, 58, 59]),
        ([60, 61, 62, 63, 64], [65, 66, 67, 68, 69]),
    ]


def test_grid_spec_names_bad_values() -> None:
    for bad, match in [({"rates": (0.1, 2.0)}, "2.0"), ({"models": ("fm", "zz")}, "'zz'"),
                       ({"classes": ("wavy",)}, "'wavy'"), ({"runs": 0}, "runs"), ({"population": 7}, "7")]:
        with pytest.raises(ConfigError, match=match):
            GridSpec.make(**bad)


# -- the command, end to end -------------------------------------------------------------------------------------


def _coevo(*argv: str) -> subprocess.CompletedProcess[str]:
    """``coevo evolvability ARGV`` as a real process."""
    return subprocess.run([sys.executable, "-m", "coevo", "evolvability", *argv], capture_output=True, text=True,
                          timeout=120, check=False)


@pytest.mark.service  # a whole command as a process: the whole suite's, not the fast set's
def test_tiny_grid_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "evo"
    r = _coevo("--out", str(out), "--landscapes", "2", "--runs", "2", "--generations", "45", "--rates", "0.3", "0.03",
               "0.1", "--models", "fm", "gh", "--quiet")
    assert r.returncode == 0, r.stderr
    for name in ("report.md", "results.json", "conditions.csv", "runs.csv", "curves.npz", "fig3_tracking_abrupt.png",
                 "fig6_current_best_abrupt.png", "fig8_gh_hypermutation_abrupt.png", "fig9_gh_pre_post.png"):
        assert (out / name).stat().st_size > 0, name
    cond = list(csv.DictReader((out / "conditions.csv").open()))
    runs = list(csv.DictReader((out / "runs.csv").open()))
    assert len(cond) == 2 * 2 * 3 and len(runs) == 2 * 2 * 3 * 2 * 2
    for c in cond:
        mine = [r for r in runs if (r["class"], r["model"], r["rate"]) == (c["class"], c["model"], c["rate"])]
        assert len(mine) == int(c["n"]) == 4
        assert np.mean([float(r["current_best"]) for r in mine]) == pytest.approx(float(c["current_best_mean"]), abs=1e-5)
        assert np.mean([float(r["online"]) for r in mine]) == pytest.approx(float(c["online_mean"]), abs=1e-5)
    for r in runs:
        assert 0 < float(r["online"]) <= float(r["current_best"]) <= 100
    curves = np.load(out / "curves.npz")
    assert curves["best_abrupt"].shape == (2, 3, 2, 2, 45)  # models, rates (sorted), landscapes, runs, generations
    res = json.loads((out / "results.json").read_text())
    assert res["spec"]["rates"] == [0.03, 0.1, 0.3] and res["changes"]["abrupt"] == [20, 40]
    assert {c["id"] for c in res["claims"]} >= {"hyper_beats_plain", "gh_rises_after_shift"}
    report = (out / "report.md").read_text()
    assert "## The report's claims" in report and "![fig8_gh_hypermutation_abrupt.png]" in report
    (out / "report.md").unlink()
    assert main(["evolvability", "--out", str(out), "--report-only"]) == 0  # from the saved curves, same numbers
    assert (out / "report.md").read_text() == report


@pytest.mark.parametrize("argv, named", [
    (["--rates", "0.01", "abc"], "'abc'"),
    (["--rates", "1.5"], "1.5"),
    (["--models", "fm", "xx"], "'xx'"),
    (["--classes", "stormy"], "'stormy'"),
    (["--landscapes", "0"], "--landscapes"),
])
def test_bad_values_exit_2_before_anything_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                argv: list[str], named: str) -> None:
    try:
        code = main(["evolvability", "--out", str(tmp_path / "never"), "--quiet", *argv])
    except SystemExit as exc:  # a flag's bound, refused by the parser
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert named in err and "ConfigError" in err
    assert not (tmp_path / "never").exists()


def test_gm_like_fm_needs_runs_that_could_have_told_them_apart() -> None:
    """"GM performs like FM(0.03)" held whenever p >= 0.05 (issue 55: no evidence is not evidence of likeness): two
    runs each, a fourfold gap, held.  Now it holds only when the design can reach p < 0.05 and the effect is small."""
    from coevo.experiments.evolvability.experiment import GridResults, GridSpec
    from coevo.experiments.evolvability.report import _ranking_claims

    def claim(gm: np.ndarray, fm: np.ndarray) -> dict[str, Any]:
        spec = GridSpec.make(classes=("gradual",), rates=(0.03,), models=("fm", "gm"), landscapes=1, runs=gm.size,
                             generations=1)
        best = np.stack([fm, gm]).reshape(2, 1, 1, gm.size, 1)
        res = GridResults(spec, mean={"gradual": best}, best={"gradual": best}, control={"gradual": best})
        return next(c for c in _ranking_claims(res) if c["id"] == "gm_like_fm003")

    few = claim(np.array([80.0, 90.0]), np.array([20.0, 25.0]))
    assert few["tests"][0]["p"] >= 0.05 and not few["tests"][0]["holds"] and few["verdict"] == "too few runs to tell"
    gm = np.linspace(60, 90, 6)
    apart = claim(gm, gm - 40)  # 6 runs each, fully apart: p < 0.05
    assert apart["tests"][0]["p"] < 0.05 and apart["verdict"] == "does not hold"
    rng = np.random.default_rng(4)
    many = claim(rng.normal(50, 5, 40), rng.normal(50, 5, 40))
    assert many["tests"][0]["holds"] and many["tests"][0]["magnitude"] in ("negligible", "small")
