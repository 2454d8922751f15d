"""Appendix C: the reconstructed worlds, the Q-learner, EARL1 and the experiment's contract (fast)."""

from __future__ import annotations

import argparse
import itertools

import numpy as np
import pytest

from coevo.errors import ConfigError, RunDirError
from coevo.experiments.earl import gridworld, hidden
from coevo.experiments.earl.earl1 import EARL1Config, evolve, implicit_values
from coevo.experiments.earl.experiment import TABLE2, TABLE2_FITNESS, EarlSpec, run_grid, run_hidden
from coevo.experiments.earl.qlearning import QConfig, QLearner, train
from coevo.experiments.earl.report import TABLE1_D, TABLE4

# --- the grid world -------------------------------------------------------------------------

def test_grid_optimum_is_17_along_the_survey_path_by_exhaustive_search() -> None:
    # every policy that matters: the actions of the 8 decisions on any path (2**25 policies share them)
    best, scores = -np.inf, {}
    for moves in itertools.product("RD", repeat=8):
        s, score, path = gridworld.START, 0.0, ""
        for m in moves:
            score += gridworld.PAYOFF[s]
            path += m
            s = int(gridworld.NEXT[s, gridworld.ACTIONS.index(m)])
            if s < 0:
                break
        else:
            score += gridworld.PAYOFF[s]  # e5 (or the last box) before leaving
        scores[path] = score
        best = max(best, score)
    assert best == 17
    assert scores["RDRDDRRD"] == 17
    dp_best, paths = gridworld.optimal_paths()
    assert dp_best == 17 == gridworld.dp_q()[gridworld.START].max()
    # not unique: the reconstruction has four optimal paths (the survey calls its one "an" optimal policy)
    assert paths == ["RDRDDDRR", "RDRDDRRD", "RRDDDDRR", "RRDDDRRD"]


def test_grid_reproduces_table1_table2_and_the_text() -> None:
    q = gridworld.dp_q()
    assert tuple(q[:, gridworld.DOWN].astype(int)) == TABLE1_D
    assert tuple(q[gridworld.STATE_NAMES.index("b2")]) == (15.0, 8.0)  # "15 vs. 8 from Table 1"
    assert gridworld.returns(TABLE2).tolist() == TABLE2_FITNESS.tolist()


def test_implicit_values_reproduce_table4_from_table2() -> None:
    fitness = TABLE2_FITNESS.copy()
    fitness[0] = 7.0  # Table 4 was computed with policy 1 at 7, not Table 2's 8 (docs/earl/reconstruction.md)
    est = np.round(implicit_values(TABLE2, fitness))
    for a in (0, 1):
        for s, v in enumerate(TABLE4[a]):
            if v is not None:
                assert est[s, a] == v, (gridworld.STATE_NAMES[s], a)
    # converged genes have no estimate for the dropped action (the survey's "?")
    for name, dropped in (("a3", 0), ("a5", 1), ("b2", 1), ("b5", 1), ("d3", 1), ("e1", 0), ("e2", 1), ("e4", 0)):
        assert np.isnan(est[gridworld.STATE_NAMES.index(name), dropped])


def test_q_learning_converges_to_the_dp_q_values_on_the_grid() -> None:
    rng = np.random.default_rng(3)
    learner = QLearner(20, gridworld.N_STATES, 2, QConfig(alpha=0.5, epsilon=1.0))
    train(learner, gridworld.GridWorld(20), rng, 1500)
    np.testing.assert_allclose(learner.q, np.broadcast_to(gridworld.dp_q(), learner.q.shape), atol=1e-3)
    assert (gridworld.returns(learner.greedy_policy()) == 17).all()


# --- the hidden-state world -----------------------------------------------------------------

def test_hidden_policy_values() -> None:
    values = dict(zip(map(tuple, hidden.all_policies()), hidden.expected_reward(hidden.all_policies())))
    assert values[hidden.Q_POLICY] == 1.0
    assert values[hidden.OPTIMAL_POLICY] == 1.875 == max(values.values())


def test_q_learner_on_hidden_state_settles_on_red_r_green_l_blue_r() -> None:
    rng = np.random.default_rng(4)
    learner = QLearner(100, 3, 2, QConfig(alpha_schedule="1/n", epsilon=0.2))
    train(learner, hidden.HiddenWorld(100), rng, 4000)
    assert (learner.greedy_policy() == np.array(hidden.Q_POLICY)).all()
    blue = learner.q[:, hidden.BLUE]
    assert abs(blue[:, hidden.L].mean() + 0.5) < 0.05
    np.testing.assert_allclose(blue[:, hidden.R], 1.0)
    np.testing.assert_allclose(hidden.expected_reward(learner.greedy_policy()), 1.0)


def test_earl1_puts_most_of_its_population_on_the_best_hidden_policy() -> None:
    rng = np.random.default_rng(5)
    res = evolve(lambda pop, r: hidden.expected_reward(pop), runs=100, genes=3, cfg=EARL1Config(generations=60),
                 rng=rng, target=np.array(hidden.OPTIMAL_POLICY))
    assert res.share[-1].mean() > 0.75
    assert hidden.expected_reward(res.population).mean() > 1.6  # far above the Q-learner's 1.0
    ideal = hidden.expected_reward(np.array(hidden.OPTIMAL_POLICY))
    assert ideal == 1.875


# --- determinism ----------------------------------------------------------------------------

def test_same_seed_gives_identical_results() -> None:
    spec = EarlSpec(runs=4, seed=11, generations=5, grid_episodes=50, hidden_episodes=100, hidden_trials=(0, 1))
    a, b = run_grid(spec), run_grid(spec)
    np.testing.assert_array_equal(a["q_final"], b["q_final"])
    np.testing.assert_array_equal(a["ea"].population, b["ea"].population)
    np.testing.assert_array_equal(a["ea"].best, b["ea"].best)
    c, d = run_hidden(spec), run_hidden(spec)
    np.testing.assert_array_equal(c["q_final"], d["q_final"])
    for t in (0, 1):
        np.testing.assert_array_equal(c["ea"][t].share, d["ea"][t].share)
    other = run_grid(EarlSpec(runs=4, seed=12, generations=5, grid_episodes=50, hidden_episodes=100))
    assert not np.array_equal(a["ea"].population, other["ea"].population)


# --- bad input ------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs", [{"alpha": 0.0}, {"alpha": 1.5}, {"gamma": -0.1}, {"epsilon": 2.0},
                                    {"alpha_schedule": "linear"}, {"max_steps": 0}])
def test_bad_q_settings_raise_config_error(kwargs: dict) -> None:
    with pytest.raises(ConfigError):
        QConfig(**kwargs)


@pytest.mark.parametrize("kwargs", [{"population": 7}, {"population": 0}, {"crossover": 1.2}, {"mutation": -0.1},
                                    {"generations": -1}])
def test_bad_earl1_settings_raise_config_error(kwargs: dict) -> None:
    with pytest.raises(ConfigError):
        EARL1Config(**kwargs)


@pytest.mark.parametrize("kwargs", [{"runs": 0}, {"runs": -5}, {"seed": -1}, {"hidden_trials": ()},
                                    {"grid_epsilon": 3.0}, {"runs": 2.5}])
def test_bad_spec_raises_config_error(kwargs: dict) -> None:
    with pytest.raises(ConfigError):
        EarlSpec(**kwargs)


def test_bad_env_and_policy_shapes_raise_config_error() -> None:
    with pytest.raises(ConfigError):
        gridworld.GridWorld(0)
    with pytest.raises(ConfigError):
        gridworld.returns(np.zeros((3, 24), dtype=int))
    with pytest.raises(ConfigError):
        hidden.HiddenWorld(2, red_l=2.0)
    with pytest.raises(ConfigError):
        hidden.expected_reward(np.zeros(4, dtype=int))
    learner = QLearner(3, 3, 2)
    with pytest.raises(ConfigError):
        learner.run_episode(gridworld.GridWorld(3), np.random.default_rng(0))


def _args(tmp_path, **over) -> argparse.Namespace:
    from coevo.experiments.earl.command import add_arguments

    p = argparse.ArgumentParser()
    add_arguments(p)
    argv = ["--out", str(over.pop("out", tmp_path / "out")), "--quiet"]
    for k, v in over.items():
        argv += [f"--{k}", str(v)]
    return p.parse_args(argv)


def test_command_rejects_negative_runs_and_an_out_that_is_a_file(tmp_path) -> None:
    from coevo.experiments.earl.command import main

    with pytest.raises(SystemExit):  # the flag's bound, at parse time
        _args(tmp_path, runs=-3)
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(RunDirError, match="is a file"):
        main(_args(tmp_path, out=f, runs=2))
    assert not (tmp_path / "out").exists()


def test_command_writes_the_report(tmp_path, capsys) -> None:
    from coevo.experiments.earl.command import main

    out = tmp_path / "earl"
    assert main(_args(tmp_path, out=out, runs=3, generations=3)) == 0
    for name in ("report.md", "results.json", "grid_q.csv", "table4.csv", "hidden_curves.csv", "hidden_policies.csv"):
        assert (out / name).is_file(), name
    assert "| grid |" in (out / "report.md").read_text()
    assert "report:" in capsys.readouterr().out
