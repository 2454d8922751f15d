"""The GA: operators, mutation models, evaluation and the generational loop."""

from __future__ import annotations

from coevo.ga.engine import GA, GenerationReport
from coevo.ga.evaluate import Evaluation, Evaluator, Partners
from coevo.ga.mutation import FixedHypermutation, FixedRate, GeneticHypermutation, GeneticRate, MutationModel

__all__ = [
    "GA",
    "GenerationReport",
    "Evaluator",
    "Evaluation",
    "Partners",
    "MutationModel",
    "FixedRate",
    "GeneticRate",
    "FixedHypermutation",
    "GeneticHypermutation",
]
