"""The TD baseline on our own tasks (docs/ea-vs-td.md): encoders, the hashed table, the environments,
determinism, learning on a tiny budget and the checks on input (fast: seconds)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from coevo.errors import ConfigError
from coevo.experiments.earl.qlearning import QConfig
from coevo.experiments.earl.td.command import add_td_arguments, specs_from_args
from coevo.experiments.earl.td.encoders import ENCODERS, Encoder
from coevo.experiments.earl.td.envs import make_env
from coevo.experiments.earl.td.measures import measure_policy, rules_policy
from coevo.experiments.earl.td.qtable import HashedQ
from coevo.experiments.earl.td.runs import robot_steps_of, run_ga, run_task, run_td
from coevo.experiments.earl.td.spec import TDSpec, default_checkpoints

# --- encoders and the table ------------------------------------------------------------------

def test_encoder_codes_are_distinct_for_distinct_merged_bins() -> None:
    enc = Encoder("tracking", (("target_range", 2), ("target_bearing", 6)))
    assert enc.n_states == 16 * 12
    bins = np.zeros((4, 5), dtype=np.uint8)
    bins[1, 3] = 1   # target_range bin 1 merges with 0
    bins[2, 3] = 2   # ... bin 2 does not
    bins[3, 4] = 6   # target_bearing bin 6: the second 30-degree sector
    c = enc.code(bins)
    assert c[0] == c[1] and len({c[0], c[2], c[3]}) == 3
    assert ENCODERS[("docking", "full")].n_states == 31 * 72 * 8 * 31 * 72 * 31 * 72 * 72


def test_hashed_table_allocates_rows_per_run_and_merges_duplicate_updates() -> None:
    q = HashedQ(2, 3, QConfig(alpha=0.5, gamma=1.0, epsilon=0.0))
    rows = q.rows(np.array([0, 0, 1]), np.array([7, 7, 7]))
    assert rows[0] == rows[1] != rows[2]            # the same code is a different row in another run
    assert q.rows(np.array([0]), np.array([9]), allocate=False)[0] == -1
    # two updates of the same pair toward 1.0 in one batch: 1 - (1 - 0.5)**2 of the way
    q.update(rows[:2], np.array([1, 1]), np.ones(2), rows[:2], np.ones(2, dtype=bool))
    assert q.q[rows[0], 1] == pytest.approx(0.75)
    assert q.table_sizes() == [{"observations": 1, "pairs": 1}, {"observations": 1, "pairs": 0}]


def test_greedy_falls_back_where_the_table_has_no_preference() -> None:
    q = HashedQ(1, 4, QConfig(epsilon=0.0))
    rows = q.rows(np.zeros(2, dtype=np.int64), np.array([1, 2]))
    q.q[rows[1], 3] = 1.0
    act = q.act(rows, np.random.default_rng(0), fallback=np.array([2, 2]))
    assert act.tolist() == [2, 3]


# --- the environments ------------------------------------------------------------------------

@pytest.mark.parametrize("task", ["tracking", "docking", "door"])
def test_environment_episodes_end_and_count_their_steps(task: str) -> None:
    rng = np.random.default_rng(1)
    env = make_env(task, 6, rng, restart=False)
    steps = 0
    while env.active.any():
        steps += int(env.active.sum())
        env.step(rng.integers(0, env.n_actions, env.n), rng)
    ep = env.episodes()
    assert ep["steps"].sum() == steps                # every robot-step belongs to an episode
    assert ((ep["payoff"] >= 0) & (ep["payoff"] <= 1)).all()


def test_our_environment_measures_rules_as_the_task_does() -> None:
    # the door runs the same random stream as the task's own measure: the numbers are equal
    from coevo.tasks.door import DoorConfig, default_ruleset
    from coevo.tasks.door.evaluate import measure

    rules = default_ruleset()
    ours = measure_policy("door", rules_policy([rules], 300), groups=1, trials=300, rng=np.random.default_rng(4))
    assert ours[0] == measure(rules, DoorConfig(), trials=300, seed=4)["success"]


def test_shaped_tracking_return_equals_the_sparse_payoff() -> None:
    rng_a, rng_b = np.random.default_rng(2), np.random.default_rng(2)
    shaped, sparse = make_env("tracking", 8, rng_a, reward="shaped"), make_env("tracking", 8, rng_b)
    total_shaped, total_sparse = np.zeros(8), np.zeros(8)
    act_rng = np.random.default_rng(3)
    for _ in range(300):
        a = act_rng.integers(0, 78, 8)
        total_shaped += shaped.step(a, rng_a)[0]
        total_sparse += sparse.step(a, rng_b)[0]
    # the same worlds: returns agree at every episode end (compare whole episodes only)
    ends = shaped.episodes()
    assert ends["payoff"].size > 0
    np.testing.assert_allclose(ends["payoff"], sparse.episodes()["payoff"])


def test_robot_steps_of_the_ga_evaluations() -> None:
    spec = TDSpec(task="door", seeds=1, generations=1, population=4, episodes=3, trials=10)
    curve = run_ga(spec, 0)
    assert curve.robot_steps[0] > 4 * 3                    # at least one decision per trial, best re-evaluated too
    with pytest.raises(ConfigError, match="robot-steps"):
        robot_steps_of(object())


# --- determinism and learning ----------------------------------------------------------------

def _small(task: str, **kw: object) -> TDSpec:
    base = dict(task=task, seeds=2, generations=2, population=4, episodes=4, lanes=16, trials=10)
    return TDSpec(**{**base, **kw})  # type: ignore[arg-type]


@pytest.mark.parametrize("task", ["tracking", "door"])
def test_td_runs_are_identical_for_the_same_seed(task: str) -> None:
    a = run_td(_small(task, prior="default"), [600, 1500])
    b = run_td(_small(task, prior="default"), [600, 1500])
    assert [c.measure for c in a] == [c.measure for c in b]
    assert [c.robot_steps for c in a] == [c.robot_steps for c in b]
    assert [c.extra["table"] for c in a] == [c.extra["table"] for c in b]


def test_whole_comparison_is_identical_for_the_same_seed() -> None:
    spec = _small("door", seeds=1)
    a, b = run_task(spec), run_task(spec)
    for key in ("checkpoint_steps", "ga", "td"):
        strip = (lambda v: [{k: x for k, x in c.items() if k != "seconds"} for c in v]) if key != "checkpoint_steps" \
            else (lambda v: v)
        assert strip(a[key]) == strip(b[key])


def test_q_learning_improves_tracking_on_a_tiny_budget() -> None:
    # the shaped reward on a few thousand robot-steps per run lifts Quality Tracking off the random table's
    spec = TDSpec(task="tracking", seeds=2, lanes=64, trials=30, reward="shaped", alpha=0.2)
    curves = run_td(spec, [64, 60_000])
    before = np.mean([c.measure[0] for c in curves])
    after = np.mean([c.measure[-1] for c in curves])
    assert after > before + 3.0


# --- bad input -------------------------------------------------------------------------------

@pytest.mark.parametrize("kw, name", [
    (dict(task="corridor"), "task='corridor'"), (dict(seeds=0), "seeds=0"), (dict(lanes=-1), "lanes=-1"),
    (dict(alpha=0.0), "alpha=0.0"), (dict(epsilon=2.0), "epsilon=2.0"), (dict(gamma=1.5), "gamma=1.5"),
    (dict(encoder="tiles"), "encoder='tiles'"), (dict(reward="dense"), "reward='dense'"),
    (dict(task="door", reward="shaped"), "reward='shaped'"), (dict(prior="expert"), "prior='expert'"),
    (dict(generations=5, checkpoints=(2, 9)), "checkpoints="), (dict(td_steps=0), "td_steps=0"),
])
def test_bad_settings_raise_naming_the_value(kw: dict, name: str) -> None:
    with pytest.raises(ConfigError, match=name.replace("(", r"\(").replace(")", r"\)")):
        TDSpec(**kw)  # type: ignore[arg-type]


def test_bad_encoders_and_tables_raise() -> None:
    with pytest.raises(ConfigError, match="no sensor 'fuel'"):
        Encoder("tracking", (("fuel", 1),))
    with pytest.raises(ConfigError, match="target_range=0"):
        Encoder("tracking", (("target_range", 0),))
    with pytest.raises(ConfigError, match="runs=0"):
        HashedQ(0, 3, QConfig())
    with pytest.raises(ConfigError, match="task='nowhere'"):
        make_env("nowhere", 2, np.random.default_rng(0))


def test_command_options_are_checked_before_anything_runs() -> None:
    p = argparse.ArgumentParser()
    add_td_arguments(p)
    with pytest.raises(ConfigError, match="--tasks swim"):
        specs_from_args(p.parse_args(["--out", "x", "--tasks", "swim"]))
    with pytest.raises(ConfigError, match="--variants fast"):
        specs_from_args(p.parse_args(["--out", "x", "--variants", "fast"]))
    with pytest.raises(SystemExit):  # --seeds' bound, at parse time
        p.parse_args(["--out", "x", "--seeds", "0"])
    specs = specs_from_args(p.parse_args(["--out", "x", "--generations", "12"]))
    assert [s.task for s, _ in specs] == ["tracking", "docking", "door"]
    assert [v for _, v in specs] == [("shaped", "default-rules"), ("default-rules",), ("default-rules",)]
    assert specs[0][0].checkpoints == default_checkpoints(12) == (1, 2, 5, 10, 12)


def test_report_files_rebuild_from_results_json(tmp_path) -> None:
    from coevo.experiments.earl.td.report import read_results, write_report

    res = {"door": run_task(_small("door", seeds=1, generations=1), variants=("default-rules",))}
    data = write_report(tmp_path, res)
    assert {p.name for p in tmp_path.iterdir()} == {"results.json", "curves.csv", "fig-door.png", "report.md"}
    assert [c["verdict"] for c in data["claims"]][-1] == "consistent, not isolated"
    again = tmp_path / "again"
    again.mkdir()
    write_report(again, read_results(tmp_path / "results.json"))
    assert (again / "report.md").read_text() == (tmp_path / "report.md").read_text()
