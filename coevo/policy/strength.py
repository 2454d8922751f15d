"""Strength updates: each rule's strength tracks the payoff of the episodes it fired in.

SAMUEL updates the strengths of all rules that fired in an episode from that
episode's payoff.  Episodes here run in parallel, so the update is applied once per
evaluation *(ours)*: ``s <- s + rate * (mean payoff of the episodes r fired in - s)``.
Rules that never fired keep their strength.
"""

from __future__ import annotations

import numpy as np

from coevo.policy.rules import RuleSet

__all__ = ["fired_matrix", "update_strengths"]


def fired_matrix(fired: np.ndarray, n_rules: int) -> np.ndarray:
    """``(m,)`` uint64 fired-rule masks -> ``(m, n_rules)`` bool."""
    bits = np.unpackbits(fired.astype("<u8").view(np.uint8).reshape(-1, 8), axis=1, bitorder="little")
    return bits[:, :n_rules].astype(bool)


def update_strengths(rs: RuleSet, fired: np.ndarray, payoff: np.ndarray, rate: float) -> RuleSet:
    """A copy of ``rs`` with strengths moved towards the mean payoff of the episodes each rule fired in."""
    if fired.size == 0:
        return rs
    f = fired_matrix(fired, len(rs))
    count = f.sum(axis=0)
    # Not ``payoff @ f``: a matrix product's order of sums is the BLAS kernel's, which the processor picks, so its
    # last bits differ between machines.  numpy's reduction adds in an order fixed by the shapes alone.
    total = np.add.reduce(np.where(f, payoff[:, None], 0.0), axis=0)
    seen = count > 0
    strength = rs.strength.copy()
    mean = np.divide(total, count, out=np.zeros_like(strength), where=seen)
    strength[seen] += rate * (mean[seen] - strength[seen])
    return rs.replace(strength=np.clip(strength, 0.0, 1.0))
