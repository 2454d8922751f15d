"""The compiled agent loop (coevo/tasks/fuel/kernels.py) gives numpy's numbers where the recorded fixture
(tests/test_exact_curves.py) does not look: a Tracking or Docking learner under an Executive with rules (the
Mutual regime: two controllers in one step, one of them logged), several policies per controller, tiny batches."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

import coevo.tasks.fuel.world as world_mod
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import random_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.runner import Rules, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld

pytestmark = pytest.mark.skipif(world_mod._sense_kernel() is None, reason="numba is not installed")


def _play(lanes: int, learner: Behaviour | None, restart: bool, seed: int) -> tuple[dict[str, np.ndarray], BatchWorld]:
    rng = np.random.default_rng(seed)
    ctrl = {b: Rules(CompiledPolicies([random_ruleset(b, int(rng.integers(4, 40)), rng) for _ in range(3)]),
                     np.arange(lanes) % 3) for b in Behaviour}
    world = BatchWorld(WorldConfig(), lanes)
    out = run_lanes(world, lane_episodes=6, executive=ctrl[Behaviour.EXECUTIVE], tracking=ctrl[Behaviour.TRACKING],
                    docking=ctrl[Behaviour.DOCKING], restart_epochs=restart, rng=np.random.default_rng(seed + 1),
                    learner=learner)
    arrays = {f.name: getattr(out, f.name) for f in fields(out) if f.name != "trace"}
    if out.trace is not None:
        arrays.update({f"trace.{k}": getattr(out.trace, k) for k in ("bins", "rule", "full")})
    arrays.update({k: getattr(world, k) for k in ("rx", "ry", "rh", "tx", "ty", "th", "fuel", "speed", "turn")})
    return arrays, world


@pytest.mark.parametrize(("lanes", "learner", "restart"), [
    (40, Behaviour.TRACKING, True), (40, Behaviour.DOCKING, False), (40, None, True), (40, Behaviour.EXECUTIVE, False),
    (3, Behaviour.TRACKING, False), (1, Behaviour.DOCKING, True),
])
def test_compiled_steps_give_numpys_numbers(monkeypatch, lanes: int, learner: Behaviour | None, restart: bool) -> None:
    runs = []
    for threshold in (1 << 62, 0):  # numpy's path, then the compiled one for every batch
        monkeypatch.setattr(world_mod, "COMPILED_MIN_LANES", threshold)
        monkeypatch.setattr(world_mod, "COMPILED_WARM_MIN_LANES", threshold)
        runs.append(_play(lanes, learner, restart, seed=lanes)[0])
    numpy_run, compiled_run = runs
    assert numpy_run.keys() == compiled_run.keys()
    for name, a in numpy_run.items():
        assert np.array_equal(a, compiled_run[name]), name


@pytest.mark.parametrize("behaviour", [Behaviour.TRACKING, Behaviour.DOCKING])
def test_compiled_experiences_are_numpys(monkeypatch, behaviour: Behaviour) -> None:
    """FuelEvaluator's experiences of a population in one compiled pass: the arrays of its per-individual numpy
    code, under an Executive with rules too (where some of a lane's episodes are the other behaviour's)."""
    from coevo.config import GAConfig
    from coevo.tasks.fuel import default_ruleset
    from coevo.tasks.fuel.evaluate import FuelEvaluator

    monkeypatch.setattr(world_mod, "COMPILED_MIN_LANES", 0)
    rng = np.random.default_rng(4)
    pols = [random_ruleset(behaviour, 24, rng) for _ in range(5)]
    other = "docking" if behaviour == Behaviour.TRACKING else "tracking"
    for partners in ({}, {"executive": random_ruleset(Behaviour.EXECUTIVE, 8, rng), other: default_ruleset(other)}):
        ev = FuelEvaluator(behaviour, WorldConfig(), GAConfig(episodes=30))
        out = ev.evaluate(pols, partners, np.random.default_rng(6)).details
        per, K = out.played.shape[0] // len(pols), out.played.shape[1]
        for i, exp in enumerate(ev._experiences(out, len(pols), per, K)):
            ref = ev._experience(out, slice(i * per, (i + 1) * per), K)
            for name in ("fired", "payoff", "bins", "rule", "full", "episode"):
                a, b = getattr(exp, name), getattr(ref, name)
                assert a.dtype == b.dtype and np.array_equal(a, b), (partners.keys(), i, name)
