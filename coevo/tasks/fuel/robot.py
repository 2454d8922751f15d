"""The combined robot: an Executive with its Tracking and Docking policies, measured.

These are the report's measures of a finished policy (Appendix A §6.3), taken on
fresh epochs with their own seed, apart from the GA's evaluations.
"""

from __future__ import annotations

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.measures import Measures, measure
from coevo.tasks.fuel.runner import ALWAYS_DOCK, ALWAYS_TRACK, Rules, Trivial, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld

__all__ = ["controllers", "measure_robot", "docking_from_random_starts", "measure_behaviour"]


def _rules(rs: RuleSet | None, lanes: int) -> Rules | None:
    return None if rs is None else Rules.single(CompiledPolicies([rs]), lanes)


def controllers(
    executive: RuleSet | None, tracking: RuleSet | None, docking: RuleSet | None, lanes: int
) -> tuple[Trivial | Rules, Rules | None, Rules | None]:
    """The run_lanes controllers of a robot on ``lanes`` lanes; ``executive=None`` with only one of
    tracking/docking given means the trivial Executive that always picks it."""
    if executive is None:
        if (tracking is None) == (docking is None):
            raise ConfigError("without an Executive give exactly one of tracking/docking")
        ex: Trivial | Rules = ALWAYS_TRACK if tracking is not None else ALWAYS_DOCK
    else:
        ex = Rules.single(CompiledPolicies([executive]), lanes)
    return ex, _rules(tracking, lanes), _rules(docking, lanes)


def measure_robot(
    world: WorldConfig,
    *,
    executive: RuleSet | None,
    tracking: RuleSet | None,
    docking: RuleSet | None,
    epochs: int,
    seed: int,
) -> Measures:
    """Measures over ``epochs`` fresh epochs; ``executive=None`` with only one of
    tracking/docking given means the trivial Executive that always picks it."""
    if epochs < 1:
        raise ConfigError(f"epochs must be at least 1, got {epochs}")
    ex, tr, dk = controllers(executive, tracking, docking, epochs)
    out = run_lanes(
        BatchWorld(world, epochs), lane_episodes=world.epoch_episodes, executive=ex, tracking=tr, docking=dk,
        restart_epochs=False, rng=np.random.default_rng(seed),
    )
    return measure(out, world.episode_steps)


def docking_from_random_starts(world: WorldConfig, docking: RuleSet, *, episodes: int, seed: int) -> float:
    """% of single episodes, each from a fresh random start, in which the policy docks."""
    out = run_lanes(
        BatchWorld(world, episodes), lane_episodes=1, executive=ALWAYS_DOCK, tracking=None,
        docking=_rules(docking, episodes), restart_epochs=False, rng=np.random.default_rng(seed),
    )
    return float(100.0 * out.docked[:, 0].mean())


def measure_behaviour(
    behaviour: Behaviour,
    best: RuleSet,
    *,
    world: WorldConfig,
    tracking: RuleSet | None = None,
    docking: RuleSet | None = None,
    epochs: int = 100,
    seed: int = 0,
) -> dict[str, float | int]:
    """The measures (docs/spec.md §1) of one learned behaviour, as the ``learn`` command reports them."""
    if behaviour == Behaviour.TRACKING:
        m = measure_robot(world, executive=None, tracking=best, docking=None, epochs=epochs, seed=seed)
        return m.as_dict()
    if behaviour == Behaviour.DOCKING:
        m = measure_robot(world, executive=None, tracking=None, docking=best, epochs=epochs, seed=seed)
        d = m.as_dict()
        d["docking_from_random_starts"] = docking_from_random_starts(world, best, episodes=10 * epochs, seed=seed + 1)
        return d
    m = measure_robot(world, executive=best, tracking=tracking, docking=docking, epochs=epochs, seed=seed)
    return m.as_dict()
