"""Exactness contract of the fuel task's simulation: the same seed gives the same numbers.

``tests/data/exact_curves.json`` was recorded *before* the speed work of issue 27
(branch ``speed``, on top of a8b01d2) and every later optimisation of the batched
world, the runner, the evaluator and the matcher must reproduce it bit for bit.  It was
recorded once more, with the same pre-speed code plus Docking's dock-frame sensors and
selection (branch ``dock``, issue 25: an intended change of Docking's numbers and of the
raw sensor values, which gained two sensors; Tracking's and the Executive's stayed the
same), and the merged, faster code reproduces that recording too.  And once more when the
numbers were made the same on every machine (:mod:`coevo.exactmath`'s sine, cosine and
arctangent instead of numpy's and libm's, and the strength update's sums without BLAS):
every curve, fitness, outcome and measure stayed as recorded; only last bits of rule
strengths, of recorded positions and of raw bearings changed.  ``tests/test_machines.py``
replays this file under other BLAS kernels, without numpy's SIMD code and without libm's FMA
code:

* fixed-seed ``coevo learn`` curves (the GA engine in-process, 3 generations, population 6,
  20 episodes) of Tracking, Docking and the Executive (against the shipped Tracking and
  Docking rules), each with its best rule set and final population (hashed);
* a Tracking curve with ``conflict=proportional`` (the strength-proportional draw);
* the ``learn`` command's final measures of each best;
* all of it again with the world's compiled (numba) sensing and stepping forced on for every batch size;
* ``run_lanes`` outcomes (every array, the learner's trace included, hashed) for
  random 32-rule policies as ``coevo bench`` drives them, an Executive with rules,
  recorded runs (the Recorder's arrays) and raw sensor values of random states.

Floats are stored with ``repr`` (JSON keeps them exact), arrays as SHA-256 of their
bytes.  To record anew (only when a change of behaviour is intended and explained in
its commit): ``python tests/test_exact_curves.py --write``.
"""

from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import fields
from pathlib import Path

import numpy as np

from coevo.config import GAConfig
from coevo.ga import GA
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import random_ruleset
from coevo.tasks import get_task
from coevo.tasks.fuel import default_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.recorder import Recorder
from coevo.tasks.fuel.robot import measure_behaviour
from coevo.tasks.fuel.runner import ALWAYS_DOCK, ALWAYS_TRACK, Rules, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import SENSOR_NAMES, BatchWorld

DATA = Path(__file__).parent / "data" / "exact_curves.json"


def _h(a: np.ndarray) -> str:
    a = np.ascontiguousarray(a)
    return f"{a.dtype.str}{a.shape}:" + hashlib.sha256(a.tobytes()).hexdigest()[:32]


def _rules_hash(rs) -> str:
    return _h(np.concatenate([rs.lo.ravel().astype(np.float64), rs.hi.ravel(), rs.action.ravel(), rs.strength]))


def _outcome(out) -> dict[str, str]:
    d = {f.name: _h(getattr(out, f.name)) for f in fields(out) if f.name != "trace"}
    if out.trace is not None:
        d.update({f"trace.{k}": _h(getattr(out.trace, k)) for k in ("bins", "rule", "full")})
    return d


def _curve(behaviour: str, ga: GAConfig, seed: int, partners: dict) -> dict[str, object]:
    world = WorldConfig(docking_target_sensors=True)  # see compute()
    engine = GA(get_task("fuel"), behaviour, world=world, ga=ga, seed=seed)
    rows = []
    for _ in range(ga.generations):
        r = engine.generation(partners).as_dict()
        r.pop("seconds")
        row = {k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()}
        row["fitness"] = _h(engine.last.fitness)  # the whole population's, and everything its evaluation played
        row["outcome"] = _outcome(engine.last.details)
        rows.append(row)
    m = measure_behaviour(Behaviour(behaviour), engine.best, world=world, tracking=partners.get("tracking"),
                          docking=partners.get("docking"), epochs=12, seed=seed + 1_000_003)
    return {
        "curve": rows,
        "best": _rules_hash(engine.best),
        "population": [_rules_hash(p) for p in engine.population],
        "measures": {k: repr(v) for k, v in m.items()},
    }


def _lanes_checks() -> dict[str, object]:
    world = WorldConfig()
    out: dict[str, object] = {}
    rng = np.random.default_rng(7)
    for beh, ex in ((Behaviour.TRACKING, ALWAYS_TRACK), (Behaviour.DOCKING, ALWAYS_DOCK)):
        pols = [random_ruleset(beh, 32, rng) for _ in range(10)]
        ctrl = Rules(CompiledPolicies(pols), np.arange(300) % 10)
        kw = dict(tracking=ctrl, docking=None) if beh == Behaviour.TRACKING else dict(tracking=None, docking=ctrl)
        w = BatchWorld(world, 300)
        for restart, k in ((False, 1), (True, 3)):  # the bench's layout, then a GA-like one on the same world
            o = run_lanes(w, lane_episodes=k, executive=ex, restart_epochs=restart, rng=np.random.default_rng(11),
                          learner=beh, scenarios=30 if restart else None, **kw)
            out[f"{beh}-k{k}"] = _outcome(o)
    # An Executive with rules over the shipped Tracking and Docking rules, in epochs, recorded.
    tr, dk = default_ruleset("tracking"), default_ruleset("docking")
    exs = [random_ruleset(Behaviour.EXECUTIVE, 12, rng) for _ in range(4)]
    rec = Recorder()
    o = run_lanes(BatchWorld(world, 40), lane_episodes=10, executive=Rules(CompiledPolicies(exs), np.arange(40) % 4),
                  tracking=Rules.single(CompiledPolicies([tr]), 40), docking=Rules.single(CompiledPolicies([dk]), 40),
                  restart_epochs=False, rng=np.random.default_rng(5), learner="executive", record=rec)
    out["executive-recorded"] = _outcome(o)
    out["executive-recorder"] = {k: _h(getattr(rec, k)) for k in ("rx", "ry", "rh", "tx", "ty", "fuel", "rule", "task",
                                                                    "executive_rule")}
    # A recorded Docking learner with proportional conflict resolution.
    rec = Recorder()
    pols = [random_ruleset(Behaviour.DOCKING, 20, rng) for _ in range(3)]
    o = run_lanes(BatchWorld(world, 6), lane_episodes=4, executive=ALWAYS_DOCK, tracking=None,
                  docking=Rules(CompiledPolicies(pols), np.arange(6) % 3), restart_epochs=True,
                  rng=np.random.default_rng(9), learner="docking", conflict="proportional", record=rec)
    out["docking-proportional-recorded"] = _outcome(o)
    out["docking-proportional-recorder"] = {k: _h(getattr(rec, k)) for k in ("rx", "ry", "rh", "tx", "ty", "fuel", "rule")}
    # Contacts in hand-made situations: a robot kept touching a wall for consecutive steps, put back into
    # contact, in a corner, moving from one wall to another, at the dock, standing or driving.
    w = BatchWorld(world, 6)
    w.reset(np.arange(6), np.random.default_rng(1))
    seq = [(0, (5.0, 150.0)), (0, (5.0, 150.0)), (1, (5.0, 5.0)), (1, (5.0, 5.0)), (1, (5.0, 150.0)),
           (2, (150.0, 12.0)), (2, (150.0, 12.0)), (3, (295.0, 295.0)), (3, (295.0, 150.0)), (4, (-2.0, -2.0)),
           (4, (150.0, 150.0)), (4, (-2.0, -2.0)), (5, (150.0, 19.5)), (5, (150.0, 19.0))]
    events = []
    for t, (lane, pos) in enumerate(seq * 2):
        w.set_state([lane], robot=pos, heading=-90.0)
        ev = w.step(np.full(6, t % 3 == 0), np.full(6, 4.0), np.full(6, 2.0), np.zeros(6))
        events.append(np.concatenate([ev.collided, ev.docked, ev.dry, ev.tracking, w.rx, w.ry, w.rh]))
    out["contacts-scenario"] = _h(np.array(events, dtype=np.float64))
    # Raw sensors of random states (incl. robots near walls and the dock).
    w = BatchWorld(world, 500)
    s = np.random.default_rng(3)
    w.rx[:], w.ry[:] = s.uniform(0, world.arena, 500), s.uniform(0, world.arena, 500)
    w.rh[:], w.th[:] = s.uniform(-np.pi, np.pi, 500), s.uniform(-np.pi, np.pi, 500)
    w.tx[:], w.ty[:] = s.uniform(0, world.arena, 500), s.uniform(0, world.arena, 500)
    w.fuel[:] = s.uniform(-0.1, 1.1, 500)
    obs = w.observe(SENSOR_NAMES)
    out["observe"] = {k: _h(v) for k, v in obs.items()}
    return out


def compute() -> dict[str, object]:
    # split_rate=0, symmetric_rules off, 48 rules and (in _curve's world) the Target's sensors: the curves were recorded
    # before Docking split rules (Round 4), before its rules were symmetric (Round 6) and before they left the Target's
    # own sensors out (Round 7, docs/docking-learning.md); this test is about the simulation and the GA staying exact,
    # not about the operators and sensors chosen.
    ga = GAConfig(generations=3, population=6, episodes=20, best_episodes=30, split_rate=0.0, symmetric_rules=False,
                  max_rules=48)
    tr, dk = default_ruleset("tracking"), default_ruleset("docking")
    return {
        "tracking": _curve("tracking", ga, 0, {}),
        "docking": _curve("docking", ga, 0, {}),
        "executive": _curve("executive", ga, 0, {"tracking": tr, "docking": dk}),
        "tracking-proportional": _curve("tracking", ga.model_copy(update={"conflict": "proportional", "generations": 2}), 1, {}),
        "lanes": _lanes_checks(),
    }


def _diff(a: object, b: object, path: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in _diff(a.get(k), b.get(k), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _diff(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: expected {b!r}, got {a!r}"]


def test_same_seed_same_numbers(monkeypatch) -> None:
    """The recorded numbers with numpy's sensing and stepping (the compiled loops kept off)."""
    import coevo.tasks.fuel.world as world_mod

    monkeypatch.setattr(world_mod, "COMPILED_MIN_LANES", 1 << 62)
    monkeypatch.setattr(world_mod, "COMPILED_WARM_MIN_LANES", 1 << 62)
    expected = json.loads(DATA.read_text(encoding="utf-8"))
    got = json.loads(json.dumps(compute()))
    diffs = _diff(got, expected)
    assert not diffs, f"{len(diffs)} differences, first: " + "\n".join(diffs[:15])


def test_compiled_sensing_same_numbers(monkeypatch) -> None:
    """The same numbers with BatchWorld's compiled sensing and stepping (numba) on every batch, however small."""
    import coevo.tasks.fuel.world as world_mod

    if world_mod._sense_kernel() is None:
        import pytest

        pytest.skip("numba is not installed: only numpy's sensing runs")
    monkeypatch.setattr(world_mod, "COMPILED_MIN_LANES", 0)
    monkeypatch.setattr(world_mod, "COMPILED_WARM_MIN_LANES", 0)
    expected = json.loads(DATA.read_text(encoding="utf-8"))
    got = json.loads(json.dumps(compute()))
    diffs = _diff(got, expected)
    assert not diffs, f"{len(diffs)} differences, first: " + "\n".join(diffs[:15])


def test_reused_world_runs_like_a_fresh_one() -> None:
    """Evaluators share worlds (coevo.tasks.fuel.evaluate): a world that already ran gives what a new one gives."""
    world = WorldConfig()
    rng = np.random.default_rng(2)
    for beh, ex in ((Behaviour.TRACKING, ALWAYS_TRACK), (Behaviour.DOCKING, ALWAYS_DOCK)):
        ctrl = Rules(CompiledPolicies([random_ruleset(beh, 24, rng) for _ in range(4)]), np.arange(120) % 4)
        kw = dict(tracking=ctrl, docking=None) if beh == Behaviour.TRACKING else dict(tracking=None, docking=ctrl)
        used = BatchWorld(world, 120)
        run_lanes(used, lane_episodes=4, executive=ex, restart_epochs=True, rng=np.random.default_rng(1), learner=beh, **kw)
        a, b = (run_lanes(w, lane_episodes=3, executive=ex, restart_epochs=False, rng=np.random.default_rng(3),
                          learner=beh, **kw) for w in (used, BatchWorld(world, 120)))
        assert _outcome(a) == _outcome(b)


def _with_paths(compiled: bool) -> dict[str, object]:
    """:func:`compute` with the world's compiled loops forced on for every batch, or kept off for all."""
    import coevo.tasks.fuel.world as world_mod

    saved = world_mod.COMPILED_MIN_LANES, world_mod.COMPILED_WARM_MIN_LANES
    world_mod.COMPILED_MIN_LANES = world_mod.COMPILED_WARM_MIN_LANES = 0 if compiled else 1 << 62
    try:
        return json.loads(json.dumps(compute()))
    finally:
        world_mod.COMPILED_MIN_LANES, world_mod.COMPILED_WARM_MIN_LANES = saved


if __name__ == "__main__":
    if sys.argv[1:] == ["--write"]:
        DATA.parent.mkdir(exist_ok=True)
        DATA.write_text(json.dumps(compute(), indent=1, sort_keys=True) + "\n", encoding="utf-8")
        print(f"wrote {DATA}")
    elif sys.argv[1:2] == ["--paths"]:  # tests/test_machines.py: {"numpy": ..., "compiled": ...} as JSON
        print(json.dumps({p: _with_paths(p == "compiled") for p in sys.argv[2].split(",")}))
    else:
        print(json.dumps(compute(), indent=1, sort_keys=True))
