"""Rules: SAMUEL-style rule sets, their batched matcher, and their text form."""

from __future__ import annotations

from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import MAX_RULES, RuleSet, random_ruleset
from coevo.policy.text import format_ruleset, parse_ruleset

__all__ = ["RuleSet", "MAX_RULES", "random_ruleset", "CompiledPolicies", "format_ruleset", "parse_ruleset"]
