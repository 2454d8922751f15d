"""The case base (report Appendix B §6, Appendix C §8.3): earlier best strategies indexed by capability list.

"Strategies in the case base are indexed by the capability list in place at the
time the strategy was learned"; a restart seeds the replaced half of the population
with the nearest cases.  Nearness *(ours)*: the Hamming distance between two
capability lists over the seven sonars (how many sonars work in one and not the
other), ties broken by recency (the newest case first).  A cyclic change thus finds
the strategy of the last occurrence of the same condition at distance 0 (Appendix C
§8.3: "seeded with those policies in effect during the last occurrence of the
current environment").

Serialised as JSON lines, one case a line, so that it can later live in the
broker's store (an append-only ``.jsonl`` per key, as policies do)::

    {"schema_version": 1, "seq": 0, "capabilities": ["far_left", ...], "fitness": 0.93,
     "generation": 50, "rules": {"behaviour": "door", "lo": ..., "hi": ..., ...}}
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from coevo.cel.monitor import check_capabilities
from coevo.errors import ConfigError, RuleSetError
from coevo.policy.rules import RuleSet
from coevo.tasks.door.settings import SONARS

__all__ = ["Case", "CaseBase", "distance", "SCHEMA_VERSION"]

SCHEMA_VERSION = 1


def distance(a: Sequence[str], b: Sequence[str]) -> int:
    """Hamming distance of two capability lists over the seven sonars."""
    sa, sb = set(check_capabilities(a)), set(check_capabilities(b))
    return sum((s in sa) != (s in sb) for s in SONARS)


@dataclass(frozen=True)
class Case:
    """A strategy learned under ``capabilities`` (the working sonars): its simulated fitness, the learner's
    generation when it was stored, and ``seq``, its place in the case base (larger is newer)."""

    capabilities: tuple[str, ...]
    rules: RuleSet
    fitness: float
    generation: int
    seq: int

    def to_dict(self) -> dict[str, object]:
        return {"schema_version": SCHEMA_VERSION, "seq": self.seq, "capabilities": list(self.capabilities),
                "fitness": self.fitness, "generation": self.generation, "rules": self.rules.to_dict()}

    @staticmethod
    def from_dict(d: dict[str, Any]) -> Case:
        if not isinstance(d, dict) or d.get("schema_version") != SCHEMA_VERSION:
            raise ConfigError(f"not a case of schema version {SCHEMA_VERSION}: {str(d)[:80]!r}")
        try:
            return Case(check_capabilities(d["capabilities"]), RuleSet.from_dict(d["rules"]),
                        float(d["fitness"]), int(d["generation"]), int(d["seq"]))
        except (KeyError, TypeError, ValueError, RuleSetError) as exc:
            raise ConfigError(f"a malformed case: {exc}") from exc


class CaseBase:
    """Cases in the order they were added; see the module docstring."""

    def __init__(self, cases: Iterable[Case] = ()) -> None:
        self._cases: list[Case] = list(cases)

    def __len__(self) -> int:
        return len(self._cases)

    def __iter__(self) -> Iterator[Case]:
        return iter(self._cases)

    def add(self, capabilities: Sequence[str], rules: RuleSet, *, fitness: float, generation: int) -> Case:
        """Store ``rules`` learned under ``capabilities``; returns the new case."""
        seq = max((c.seq for c in self._cases), default=-1) + 1
        case = Case(check_capabilities(capabilities), rules, float(fitness), int(generation), seq)
        self._cases.append(case)
        return case

    def nearest(self, capabilities: Sequence[str], k: int = 1) -> list[Case]:
        """Up to ``k`` cases nearest to ``capabilities``: smallest distance first, then the newest."""
        if k < 1:
            raise ConfigError(f"k must be at least 1, got {k}")
        want = check_capabilities(capabilities)
        return sorted(self._cases, key=lambda c: (distance(c.capabilities, want), -c.seq))[:k]

    # ------------------------------------------------------------ JSON lines
    def to_jsonl(self) -> str:
        return "".join(json.dumps(c.to_dict(), separators=(",", ":")) + "\n" for c in self._cases)

    @classmethod
    def from_jsonl(cls, text: str) -> CaseBase:
        cases = []
        for no, line in enumerate(text.splitlines(), 1):
            if not line.strip():
                continue
            try:
                cases.append(Case.from_dict(json.loads(line)))
            except (json.JSONDecodeError, ConfigError) as exc:
                raise ConfigError(f"case base line {no}: {exc}") from exc
        return cls(cases)

    def save(self, path: Path) -> None:
        Path(path).write_text(self.to_jsonl(), encoding="utf-8")

    @classmethod
    def load(cls, path: Path) -> CaseBase:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"cannot read the case base {path}: {exc}") from exc
        return cls.from_jsonl(text)
