"""Mutation models (report Appendix D §2.2): FM, GM, FH and GH, pluggable in the GA.

A model decides, per offspring, how strongly it mutates, and which offspring are
hypermutated (replaced by a random individual: a random immigrant).

==========  ==========================================================================
FM(mr)      every individual mutates at the base rate ``mr``
GM(αM)      an individual's rate is ``αM + k/8``, k = its 3-bit control gene (0..7)
FH(hr, mr)  each generation a fixed fraction ``hr`` of the offspring is replaced by
            random individuals; the others mutate at ``mr``
GH(αH, mr)  an offspring is replaced by a random individual with probability
            ``αH + k/8``; if it is not, it mutates at ``mr``
==========  ==========================================================================

The control gene is part of the genome: offspring inherit it, and each of its three
bits is *reset* (set to a random value, so it changes half the time) with the
individual's own mutation probability (``αM + k/8`` under GM, ``mr`` under GH).  A
hypermutated individual gets a random control gene too.  GH's hypermutation chance
is read from the gene the offspring inherited, before that gene mutates.  Rates are
clipped to 1.

On rule sets the probability applies per rule (a mutated rule gets one change, see
:func:`mutate_rules`); on the bit strings of :mod:`coevo.experiments.evolvability.bitga` it applies
per bit.  Models without a control gene (FM, FH) draw no random numbers for it, so
an FM GA consumes its generator exactly as before these models existed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet

if TYPE_CHECKING:
    from coevo.config import GAConfig

__all__ = [
    "CONTROL_BITS",
    "CONTROL_LEVELS",
    "MODEL_NAMES",
    "MutationModel",
    "FixedRate",
    "GeneticRate",
    "FixedHypermutation",
    "GeneticHypermutation",
    "control_rate",
    "mutate_rules",
    "model_from_config",
]

CONTROL_BITS = 3
CONTROL_LEVELS = 1 << CONTROL_BITS  # k in 0..7
MODEL_NAMES = ("fm", "gm", "fh", "gh")


def control_rate(k: np.ndarray | int, minimum: float) -> np.ndarray:
    """The rate a control gene value ``k`` (0..7) stands for: ``minimum + k/8``, at most 1."""
    return np.minimum(minimum + np.asarray(k, dtype=np.float64) / CONTROL_LEVELS, 1.0)


def _check_rate(name: str, value: float) -> float:
    if not 0.0 <= value <= 1.0:
        raise ConfigError(f"{name} {value!r} is not in [0, 1]")
    return float(value)


@runtime_checkable
class MutationModel(Protocol):
    """What the GA asks of a mutation model."""

    name: str
    controlled: bool  # individuals carry a 3-bit control gene

    def rate(self, gene: int) -> float:
        """Per-rule (per-bit) mutation probability of an individual carrying ``gene``."""
        ...

    def mutate(self, rs: RuleSet, rng: np.random.Generator, *, generation: int, gene: int = 0) -> RuleSet:
        """A mutated copy (the built-in models also take ``usable``: (S,) bool, the sensors a condition change may touch)."""
        ...

    def mutate_gene(self, gene: int, rng: np.random.Generator) -> int: ...

    def hypermutants(self, genes: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        """Bool mask of the offspring (given their control genes) to replace by random individuals, or None."""
        ...


def mutate_rules(rs: RuleSet, which: np.ndarray, rng: np.random.Generator, usable: np.ndarray | None = None) -> RuleSet:
    """Mutate the rules flagged in ``which`` (bool, per rule): one change each (conditions on ``usable`` sensors only)."""
    idx = np.flatnonzero(which)
    if idx.size == 0:
        return rs
    sch = rs.schema
    lo = rs.lo.astype(np.int64)
    hi = rs.hi.astype(np.int64)
    act = rs.action.astype(np.int64)
    cols = np.arange(sch.n_sensors) if usable is None else np.flatnonzero(usable)
    S, A = cols.size, len(sch.actions)
    for i in idx:
        if rng.random() < 0.5:
            j = int(cols[int(rng.integers(S))])
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


class _Model:
    name = ""
    controlled = False

    def rate(self, gene: int) -> float:
        raise NotImplementedError

    def mutate(self, rs: RuleSet, rng: np.random.Generator, *, generation: int, gene: int = 0,
               usable: np.ndarray | None = None) -> RuleSet:
        return mutate_rules(rs, rng.random(len(rs)) < self.rate(gene), rng, usable)

    def mutate_gene(self, gene: int, rng: np.random.Generator) -> int:
        if not self.controlled:
            return gene
        reset = rng.random(CONTROL_BITS) < self.rate(gene)
        fresh = int(rng.integers(CONTROL_LEVELS))
        mask = int(np.dot(reset, 1 << np.arange(CONTROL_BITS)))
        return (gene & ~mask) | (fresh & mask)

    def hypermutants(self, genes: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        return None


class FixedRate(_Model):
    """FM(mr): each rule mutates with probability ``rate``."""

    name = "FM"

    def __init__(self, rate: float) -> None:
        self.base = _check_rate("mutation rate", rate)

    def rate(self, gene: int = 0) -> float:
        return self.base

    def __repr__(self) -> str:
        return f"FM({self.base})"


class GeneticRate(_Model):
    """GM(αM): the rate is ``αM + k/8``, k the individual's control gene."""

    name = "GM"
    controlled = True

    def __init__(self, minimum: float = 0.03) -> None:
        self.minimum = _check_rate("minimum mutation rate", minimum)

    def rate(self, gene: int) -> float:
        return float(control_rate(gene, self.minimum))

    def __repr__(self) -> str:
        return f"GM({self.minimum})"


class FixedHypermutation(_Model):
    """FH(hr, mr): a fixed fraction ``hr`` of each generation's offspring are random immigrants."""

    name = "FH"

    def __init__(self, fraction: float = 0.2, rate: float = 0.1) -> None:
        self.fraction = _check_rate("hypermutation fraction", fraction)
        self.base = _check_rate("mutation rate", rate)

    def rate(self, gene: int = 0) -> float:
        return self.base

    def hypermutants(self, genes: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        n = len(genes)
        out = np.zeros(n, dtype=bool)
        out[rng.permutation(n)[: int(round(self.fraction * n))]] = True
        return out

    def __repr__(self) -> str:
        return f"FH({self.fraction}, {self.base})"


class GeneticHypermutation(_Model):
    """GH(αH, mr): hypermutation with probability ``αH + k/8``, else mutation at ``mr``."""

    name = "GH"
    controlled = True

    def __init__(self, minimum: float = 0.05, rate: float = 0.1) -> None:
        self.minimum = _check_rate("minimum hypermutation rate", minimum)
        self.base = _check_rate("mutation rate", rate)

    def rate(self, gene: int = 0) -> float:
        return self.base

    def hypermutants(self, genes: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        return rng.random(len(genes)) < control_rate(genes, self.minimum)

    def __repr__(self) -> str:
        return f"GH({self.minimum}, {self.base})"


def model_from_config(cfg: GAConfig) -> MutationModel:
    """The model a :class:`~coevo.config.GAConfig` selects (``mutation_model`` and its parameters)."""
    name, mr = cfg.mutation_model, cfg.mutation_rate
    if name == "fm":
        return FixedRate(mr)
    if name == "gm":
        return GeneticRate(cfg.min_mutation_rate)
    if name == "fh":
        return FixedHypermutation(cfg.hypermutation_rate, mr)
    if name == "gh":
        return GeneticHypermutation(cfg.min_hypermutation_rate, mr)
    raise ConfigError(f"mutation model {name!r} is not one of {', '.join(MODEL_NAMES)}")
