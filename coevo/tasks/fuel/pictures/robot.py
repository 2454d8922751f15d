"""A fuel-task robot to show: the three controllers and the world they were learned in.

A Tracking or Docking rule set alone drives the trivial Executive that always picks
it; an Executive needs its partners, checked here so that the error names what is missing.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["Robot", "robot_from_rules", "ROLES"]

ROLES = (Behaviour.EXECUTIVE, Behaviour.TRACKING, Behaviour.DOCKING)


@dataclass(frozen=True)
class Robot:
    """A robot to play: an Executive (None: the trivial one) and the policies it can pick."""

    name: str
    world: WorldConfig
    executive: RuleSet | None
    tracking: RuleSet | None
    docking: RuleSet | None

    @property
    def combined(self) -> bool:
        """True when an Executive chooses between Tracking and Docking."""
        return self.executive is not None

    def rulesets(self) -> dict[Behaviour, RuleSet]:
        pairs = ((Behaviour.EXECUTIVE, self.executive), (Behaviour.TRACKING, self.tracking), (Behaviour.DOCKING, self.docking))
        return {b: rs for b, rs in pairs if rs is not None}


def robot_from_rules(name: str, world: WorldConfig, rules: Mapping[Behaviour | str, RuleSet]) -> Robot:
    """A robot from whichever rule sets are given; an Executive needs both partners."""
    by = {Behaviour(b): rs for b, rs in rules.items()}
    ex, tr, do = (by.get(b) for b in ROLES)
    if ex is not None and (tr is None or do is None):
        missing = " and ".join(b.value for b, rs in ((Behaviour.TRACKING, tr), (Behaviour.DOCKING, do)) if rs is None)
        raise ConfigError(f"{name}: an Executive needs its partners; missing {missing} "
                          "(give --tracking FILE --docking FILE)")
    if ex is None and tr is not None and do is not None:
        raise ConfigError(f"{name}: Tracking and Docking without an Executive: show them one at a time, or add an Executive")
    if ex is None and tr is None and do is None:
        raise ConfigError(f"{name}: no policies to show")
    return Robot(name=name, world=world, executive=ex, tracking=tr, docking=do)
