"""The agents' initial behaviours: small human-written default rule sets (SPEC §1, "Initial behaviours").

SAMUEL starts learning from a default rule set rather than from nothing (report
Appendix B: default rules "for moving toward the goal line ... say nothing about
obstacles or the walls").  Tracking and Docking ship one each, in the rule text
format, beside this module: they give the direction to the tracking ring and to
the dock and nothing else.  The Executive has none: a default that already chose
when to dock would pre-empt the very thing the two regimes compare.
"""

from __future__ import annotations

from functools import cache
from importlib import resources

from coevo.behaviours import Behaviour
from coevo.policy.rules import RuleSet
from coevo.policy.text import parse_ruleset

__all__ = ["default_ruleset", "HAS_DEFAULT"]

HAS_DEFAULT = (Behaviour.TRACKING, Behaviour.DOCKING)


@cache
def default_ruleset(behaviour: Behaviour | str) -> RuleSet | None:
    """The shipped default rule set of ``behaviour``, or None (the Executive has none)."""
    behaviour = Behaviour(behaviour)
    if behaviour not in HAS_DEFAULT:
        return None
    text = resources.files(__name__).joinpath(f"{behaviour.value}.rules").read_text(encoding="utf-8")
    return parse_ruleset(text, behaviour)
