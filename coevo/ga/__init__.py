"""The GA: operators, mutation models and the generational loop, for any task's rule sets."""

from __future__ import annotations

from coevo.ga.engine import GA, GenerationReport
from coevo.ga.mutation import FixedHypermutation, FixedRate, GeneticHypermutation, GeneticRate, MutationModel

__all__ = [
    "GA",
    "GenerationReport",
    "MutationModel",
    "FixedRate",
    "GeneticRate",
    "FixedHypermutation",
    "GeneticHypermutation",
]
