"""Mutation models: pluggable, so hypermutation models can join them.

A model turns one rule set into a mutated copy.  ``FixedRate`` is the report's FM:
every rule mutates with the same probability each generation.  A mutation moves
one end of one condition by a few bins, or changes one action to a neighbouring
or random value *(ours)*.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet

__all__ = ["MutationModel", "FixedRate", "mutate_rules"]


@runtime_checkable
class MutationModel(Protocol):
    """What the GA asks of a mutation model."""

    name: str

    def mutate(self, rs: RuleSet, rng: np.random.Generator, *, generation: int) -> RuleSet: ...


def mutate_rules(rs: RuleSet, which: np.ndarray, rng: np.random.Generator) -> RuleSet:
    """Mutate the rules flagged in ``which`` (bool, per rule): one change each."""
    idx = np.flatnonzero(which)
    if idx.size == 0:
        return rs
    sch = rs.schema
    lo = rs.lo.astype(np.int64)
    hi = rs.hi.astype(np.int64)
    act = rs.action.astype(np.int64)
    S, A = sch.n_sensors, len(sch.actions)
    for i in idx:
        if rng.random() < 0.5:
            j = int(rng.integers(S))
            s = sch.sensors[j]
            delta = int(rng.integers(1, max(2, s.bins // 8) + 1)) * (1 if rng.random() < 0.5 else -1)
            end = lo if rng.random() < 0.5 else hi
            if s.circular:
                end[i, j] = (end[i, j] + delta) % s.bins
            else:
                end[i, j] = np.clip(end[i, j] + delta, 0, s.bins - 1)
                if lo[i, j] > hi[i, j]:
                    lo[i, j], hi[i, j] = hi[i, j], lo[i, j]
        else:
            k = int(rng.integers(A))
            nv = len(sch.actions[k].values)
            if rng.random() < 0.5:
                act[i, k] = int(np.clip(act[i, k] + (1 if rng.random() < 0.5 else -1), 0, nv - 1))
            else:
                act[i, k] = int(rng.integers(nv))
    return rs.replace(lo=lo, hi=hi, action=act)


class FixedRate:
    """FM(mr): each rule mutates with probability ``rate``."""

    name = "FM"

    def __init__(self, rate: float) -> None:
        if not 0.0 <= rate <= 1.0:
            raise ConfigError(f"mutation rate {rate!r} is not in [0, 1]")
        self.rate = rate

    def mutate(self, rs: RuleSet, rng: np.random.Generator, *, generation: int) -> RuleSet:
        return mutate_rules(rs, rng.random(len(rs)) < self.rate, rng)

    def __repr__(self) -> str:
        return f"FM({self.rate})"
