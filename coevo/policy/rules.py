"""Rule sets: SAMUEL-style policies of condition-action rules with strengths.

A rule set holds ``R`` rules over a behaviour's ``S`` sensors and ``A`` actions as
arrays (bin and value indices), which is what the batched matcher and the GA
operators work on::

    lo, hi     (R, S) uint8   inclusive interval of bins; on a circular sensor
                              lo > hi means the interval wraps through 0
    action     (R, A) uint8   index into each action's values
    strength   (R,)   float64 in [0, 1]

Rule sets are immutable values: operators return new ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from coevo.errors import RuleSetError
from coevo.policy.schema import Schema, Sensor, schema

__all__ = ["RuleSet", "MAX_RULES", "random_ruleset", "interval_width", "mirror_image"]

MAX_RULES = 64  # matching packs one rule per bit of a uint64
_FIELDS = ("behaviour", "lo", "hi", "action", "strength")  # a rule set's whole dict form


@dataclass(frozen=True, eq=False)
class RuleSet:
    behaviour: str
    lo: np.ndarray
    hi: np.ndarray
    action: np.ndarray
    strength: np.ndarray
    _schema: Schema = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        sch = schema(self.behaviour)
        object.__setattr__(self, "behaviour", sch.behaviour)
        object.__setattr__(self, "_schema", sch)
        lo = np.asarray(self.lo)
        hi = np.asarray(self.hi)
        act = np.asarray(self.action)
        st = np.asarray(self.strength, dtype=np.float64)
        r = lo.shape[0] if lo.ndim == 2 else -1
        if lo.ndim != 2 or lo.shape != hi.shape or lo.shape[1] != sch.n_sensors:
            raise RuleSetError(f"{self.behaviour} rule conditions must have shape (rules, {sch.n_sensors}); got {lo.shape} and {hi.shape}")
        if act.shape != (r, len(sch.actions)) or st.shape != (r,):
            raise RuleSetError(f"{self.behaviour} actions/strengths must have shapes ({r}, {len(sch.actions)}) and ({r},); got {act.shape}, {st.shape}")
        if not 1 <= r <= MAX_RULES:
            raise RuleSetError(f"a rule set holds 1 to {MAX_RULES} rules; got {r}")
        bins = np.array([s.bins for s in sch.sensors])
        if (lo < 0).any() or (hi < 0).any() or (lo >= bins).any() or (hi >= bins).any():
            i, j = np.argwhere((lo < 0) | (hi < 0) | (lo >= bins) | (hi >= bins))[0]
            s = sch.sensors[j]
            raise RuleSetError(f"rule {i}: {s.name} interval [{lo[i, j]}, {hi[i, j]}] (bins) is outside 0..{s.bins - 1}")
        circular = np.array([s.circular for s in sch.sensors])
        empty = (lo > hi) & ~circular
        if empty.any():
            i, j = np.argwhere(empty)[0]
            s = sch.sensors[j]
            raise RuleSetError(
                f"rule {i}: {s.name} = [{s.label(int(lo[i, j]))}, {s.label(int(hi[i, j]))}] is empty (lower bound above upper)"
            )
        # Canonical form: a wrapped interval that covers every bin is [0, bins-1].
        full_wrap = circular & (lo.astype(np.int64) == hi.astype(np.int64) + 1)
        if full_wrap.any():
            lo = np.where(full_wrap, 0, lo)
            hi = np.where(full_wrap, bins - 1, hi)
        nvals = np.array([len(a.values) for a in sch.actions])
        if (act < 0).any() or (act >= nvals).any():
            i, j = np.argwhere((act < 0) | (act >= nvals))[0]
            raise RuleSetError(f"rule {i}: {sch.actions[j].name} index {act[i, j]} is outside 0..{nvals[j] - 1}")
        if not np.isfinite(st).all() or (st < 0).any() or (st > 1).any():
            i = int(np.argwhere(~np.isfinite(st) | (st < 0) | (st > 1))[0][0])
            raise RuleSetError(f"rule {i}: strength {st[i]} is not in [0, 1]")
        for name, arr, dt in (("lo", lo, np.uint8), ("hi", hi, np.uint8), ("action", act, np.uint8), ("strength", st, np.float64)):
            a = np.array(arr, dtype=dt)
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    @property
    def schema(self) -> Schema:
        return self._schema

    def __len__(self) -> int:
        return int(self.lo.shape[0])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RuleSet):
            return NotImplemented
        return (
            self.behaviour == other.behaviour
            and np.array_equal(self.lo, other.lo)
            and np.array_equal(self.hi, other.hi)
            and np.array_equal(self.action, other.action)
            and np.array_equal(self.strength, other.strength)
        )

    def __hash__(self) -> int:
        return hash((self.behaviour, self.lo.tobytes(), self.hi.tobytes(), self.action.tobytes(), self.strength.tobytes()))

    def replace(self, **arrays: np.ndarray) -> RuleSet:
        """A copy with some arrays replaced (validated again)."""
        kw = {k: getattr(self, k) for k in ("lo", "hi", "action", "strength")}
        kw.update(arrays)
        return RuleSet(self.behaviour, **kw)

    def take(self, idx: np.ndarray | list[int]) -> RuleSet:
        """The rules at ``idx``, in that order."""
        idx = np.asarray(idx, dtype=np.int64)
        return RuleSet._of_valid_rules(self._schema, self.lo[idx], self.hi[idx], self.action[idx], self.strength[idx])

    @staticmethod
    def concat(behaviour: str, parts: list[RuleSet], max_rules: int = MAX_RULES) -> RuleSet:
        """The rules of ``parts`` in order; past ``max_rules`` only the strongest stay (order kept)."""
        lo, hi, action, strength = (np.concatenate([getattr(p, k) for p in parts]) for k in ("lo", "hi", "action", "strength"))
        if len(strength) > max_rules:
            keep = np.sort(np.argsort(-strength, kind="stable")[:max_rules])
            lo, hi, action, strength = lo[keep], hi[keep], action[keep], strength[keep]
        sch = schema(behaviour)
        if all(isinstance(p, RuleSet) and p._schema is sch for p in parts):
            return RuleSet._of_valid_rules(sch, lo, hi, action, strength)
        return RuleSet(behaviour, lo, hi, action, strength)

    @staticmethod
    def _of_valid_rules(sch: Schema, lo: np.ndarray, hi: np.ndarray, action: np.ndarray, strength: np.ndarray) -> RuleSet:
        """A rule set of rules taken from valid rule sets of ``sch``'s behaviour (new arrays of theirs):
        each rule is valid and canonical already, so only the count is checked.  The GA's crossover
        makes thousands per generation, and the full check cost ~40 us each (a third of a Docking
        generation's time)."""
        r = len(strength)
        if not 1 <= r <= MAX_RULES:
            raise RuleSetError(f"a rule set holds 1 to {MAX_RULES} rules; got {r}")
        rs = object.__new__(RuleSet)
        object.__setattr__(rs, "behaviour", sch.behaviour)
        object.__setattr__(rs, "_schema", sch)
        for name, a in (("lo", lo), ("hi", hi), ("action", action), ("strength", strength)):
            a.flags.writeable = False
            object.__setattr__(rs, name, a)
        return rs

    def matches(self, bins: np.ndarray) -> np.ndarray:
        """Reference matcher, (n, S) sensor bins -> (n, R) bool; the batched one must agree."""
        b = np.asarray(bins)[:, None, :]
        inside = (b >= self.lo) & (b <= self.hi)
        wrapped = (self.lo > self.hi) & ((b >= self.lo) | (b <= self.hi))
        matched = np.asarray((inside | wrapped).all(axis=2))
        return matched

    def to_dict(self) -> dict[str, object]:
        """Plain lists, for msgpack/JSON; :meth:`from_dict` validates on the way back."""
        return {
            "behaviour": self.behaviour,
            "lo": self.lo.tolist(),
            "hi": self.hi.tolist(),
            "action": self.action.tolist(),
            "strength": self.strength.tolist(),
        }

    @staticmethod
    def from_dict(d: dict[str, object]) -> RuleSet:
        if not isinstance(d, dict):
            raise RuleSetError(f"not a rule set: expected a map, got {type(d).__name__}")
        extra = sorted(str(k) for k in d if k not in _FIELDS)
        if extra:  # nothing rides along inside a policy (a store would keep it, fsynced)
            raise RuleSetError(f"rule set has unknown fields {', '.join(repr(k) for k in extra[:5])}; "
                               f"only {', '.join(_FIELDS)}")
        try:
            behaviour = d["behaviour"]
            arrays = {k: np.asarray(d[k]) for k in ("lo", "hi", "action", "strength")}
        except (KeyError, ValueError, TypeError) as exc:
            raise RuleSetError(f"not a rule set: {exc!r}") from exc
        if not isinstance(behaviour, str):
            raise RuleSetError(f"rule set behaviour must be a name, got {behaviour!r}")
        for k in ("lo", "hi", "action"):
            a = arrays[k]
            if a.size and (a.dtype.kind not in "iu"):
                raise RuleSetError(f"rule set field {k!r} must hold integers, got {a.dtype}")
            if a.size and ((a < 0).any() or (a > 255).any()):
                raise RuleSetError(f"rule set field {k!r} holds a value outside 0..255")
        if arrays["strength"].dtype.kind not in "iuf":
            raise RuleSetError(f"rule set strengths must be numbers, got {arrays['strength'].dtype}")
        return RuleSet(behaviour, **arrays)


def interval_width(rs: RuleSet) -> np.ndarray:
    """Number of bins each condition covers, (R, S)."""
    bins = np.array([s.bins for s in rs.schema.sensors])
    lo = rs.lo.astype(np.int64)
    hi = rs.hi.astype(np.int64)
    return np.where(lo <= hi, hi - lo + 1, bins - lo + hi + 1)


def mirror_image(rs: RuleSet) -> RuleSet:
    """The rules as they would be written for the world's mirror image (:attr:`Sensor.mirrored` conditions and
    :attr:`Action.mirrored` actions reflected, the rest as they are; strengths kept).  In a world that is its
    own mirror image a rule and its image are equally right, each on its own side."""
    sch = rs.schema
    lo, hi, action = rs.lo.copy(), rs.hi.copy(), rs.action.copy()
    for j, s in enumerate(sch.sensors):
        if s.mirrored:  # [lo, hi] -> [last - hi, last - lo], wrapping where the interval wraps
            lo[:, j], hi[:, j] = s.bins - 1 - rs.hi[:, j], s.bins - 1 - rs.lo[:, j]
    for k, a in enumerate(sch.actions):
        if a.mirrored:
            action[:, k] = len(a.values) - 1 - rs.action[:, k]
    return rs.replace(lo=lo, hi=hi, action=action)


def random_ruleset(behaviour: str, n_rules: int, rng: np.random.Generator, usable: np.ndarray | None = None) -> RuleSet:
    """A random policy: each condition a random interval, often the full range (SAMUEL-like generality).

    ``usable`` (S,) bool: conditions only on those sensors, the others ANY (the same draws as a
    schema of the usable sensors alone)."""
    sch = schema(behaviour)
    if usable is not None and not np.all(usable):
        u = np.flatnonzero(usable)
        bins_all = np.array([s.bins for s in sch.sensors])
        lo_u, hi_u, action = _random_parts([sch.sensors[j] for j in u], sch, n_rules, rng)
        lo = np.zeros((n_rules, sch.n_sensors), dtype=np.int64)
        hi = np.tile(bins_all - 1, (n_rules, 1))
        lo[:, u], hi[:, u] = lo_u, hi_u
        return RuleSet(sch.behaviour, lo, hi, action, np.full(n_rules, 0.5))
    lo, hi, action = _random_parts(list(sch.sensors), sch, n_rules, rng)
    return RuleSet(sch.behaviour, lo, hi, action, np.full(n_rules, 0.5))


def _random_parts(sensors: list[Sensor], sch: Schema, n_rules: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    bins = np.array([s.bins for s in sensors])
    circular = np.array([s.circular for s in sensors])
    S = len(sensors)
    width = np.maximum(1, np.ceil(rng.uniform(0.1, 1.0, (n_rules, S)) * bins)).astype(np.int64)
    full = rng.random((n_rules, S)) < 0.5  # half the conditions say "any"
    width = np.where(full, bins, width)
    start = np.floor(rng.random((n_rules, S)) * bins).astype(np.int64)
    start = np.where(circular, start, np.minimum(start, bins - width))
    start = np.where(full, 0, start)
    lo = start
    hi = np.where(circular, (start + width - 1) % bins, start + width - 1)
    nvals = np.array([len(a.values) for a in sch.actions])
    action = np.floor(rng.random((n_rules, len(sch.actions))) * nvals).astype(np.int64)
    return lo, hi, action
