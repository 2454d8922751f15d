"""Batched rule matching and conflict resolution for many policies at once.

A population of ``P`` rule sets is compiled once into bit tables: rules are ranked
by strength (rank 0 = strongest) and ``table[p, s, b]`` is a uint64 whose bit ``k``
is set when the rank-``k`` rule of policy ``p`` accepts bin ``b`` of sensor ``s``.
Matching ``n`` situations is then ``S`` gathers and ``S-1`` ANDs on uint64 arrays,
and conflict resolution by strength is "lowest set bit".

When no rule matches, the best partial match fires *(ours)*: the rule satisfying
the most conditions, ties to the strongest.  It is found with a bit-sliced counter
of satisfied conditions per rule and an MSB-first maximum over the counter planes,
so it too stays on whole-batch uint64 operations.

``conflict="proportional"`` draws among the matching rules with probability
proportional to strength (SAMUEL's bidding) instead of taking the strongest.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet
from coevo.policy.schema import Schema

__all__ = ["CompiledPolicies", "lowest_bit"]

_ONE = np.uint64(1)


def lowest_bit(mask: np.ndarray) -> np.ndarray:
    """Index of the lowest set bit of each uint64 (undefined for 0)."""
    iso = mask & (~mask + _ONE)
    index: np.ndarray = np.bitwise_count(iso - _ONE).astype(np.int64)
    return index


def _interval_bits(lo: np.ndarray, hi: np.ndarray, bit: np.ndarray, bins: int) -> np.ndarray:
    """(P, S, bins) uint64: bit ``bit[p, k]`` set in ``[p, s, b]`` where rank ``k``'s interval ``[lo, hi]`` on
    sensor ``s`` (``lo``, ``hi``: (P, K, S); wrapping through 0 where lo > hi) holds bin ``b``.

    A running XOR over the bins of a table of toggles: a rank's bit toggles on where its interval starts and
    off after it ends (a wrapped one: on at 0, off after hi, on again at lo).  XOR is order-free, so the
    toggles can be scattered in any order (``ufunc.at``); one pass, not a (P, K, S, bins) membership array.
    """
    P, K, S = lo.shape
    toggles = np.zeros((P, S, bins + 1), dtype=np.uint64)
    p = np.broadcast_to(np.arange(P)[:, None, None], lo.shape)
    s = np.broadcast_to(np.arange(S)[None, None, :], lo.shape)
    b = np.broadcast_to(bit[:, :, None], lo.shape)
    np.bitwise_xor.at(toggles, (p, s, lo), b)
    np.bitwise_xor.at(toggles, (p, s, hi + 1), b)
    wrap = lo > hi
    # (numpy's stubs take a tuple index of arrays in ufunc.at, but not one that mixes in a number)
    np.bitwise_xor.at(toggles, (p[wrap], s[wrap], 0), b[wrap])  # type: ignore[arg-type]
    return np.bitwise_xor.accumulate(toggles, axis=2)[..., :bins].copy()


class CompiledPolicies:
    """Match tables for a list of rule sets of one behaviour."""

    def __init__(self, policies: Sequence[RuleSet]) -> None:
        if not policies:
            raise ConfigError("CompiledPolicies needs at least one rule set")
        behaviours = {p.behaviour for p in policies}
        if len(behaviours) != 1:
            raise ConfigError(f"cannot compile rule sets of several behaviours together: {sorted(map(str, behaviours))}")
        self.policies = list(policies)
        self.schema: Schema = policies[0].schema
        sch = self.schema
        P, S, B, K = len(policies), sch.n_sensors, sch.max_bins, 64
        A = len(sch.actions)
        self.n_rules = np.array([len(p) for p in policies], dtype=np.int64)
        self.rank_to_rule = np.zeros((P, K), dtype=np.int64)
        self.actions = np.zeros((P, K, A), dtype=np.int64)
        self.strength = np.zeros((P, K), dtype=np.float64)
        lo = np.zeros((P, K, S), dtype=np.int64)
        hi = np.zeros((P, K, S), dtype=np.int64)
        valid = np.zeros((P, K), dtype=bool)
        for p, rs in enumerate(policies):
            order = np.argsort(-rs.strength, kind="stable")
            r = len(rs)
            self.rank_to_rule[p, :r] = order
            self.actions[p, :r] = rs.action[order]
            self.strength[p, :r] = rs.strength[order]
            lo[p, :r] = rs.lo[order]
            hi[p, :r] = rs.hi[order]
            valid[p, :r] = True
        weights = (_ONE << np.arange(K, dtype=np.uint64))[None, :]
        bit = np.where(valid, weights, np.uint64(0))  # (P, K): the rank's bit, 0 for an empty slot
        self.table = _interval_bits(lo, hi, bit, B)  # (P, S, B)
        self.valid = np.bitwise_or.reduce(bit, axis=1).astype(np.uint64)
        self._flat = self.table.reshape(-1)
        self._stride = S * B
        self._offsets = np.arange(S, dtype=np.int64) * B
        self._planes = int(S).bit_length()

    def __len__(self) -> int:
        return len(self.policies)

    def decide(
        self,
        policy: np.ndarray,
        bins: np.ndarray,
        *,
        conflict: str = "strongest",
        rng: np.random.Generator | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Choose a rule for each situation.

        ``policy`` (n,) indexes the compiled policies, ``bins`` (n, S) are sensor bins.
        Returns ``(rank, full)``: the winning rule's strength rank per situation and
        whether it matched fully (False: it was the best partial match).
        """
        # One (S, n) index array and one gather for all sensors (bins often come as the transpose of
        # an (S, n) array, whose .T is then contiguous), and one AND-reduction over the sensors.
        idx = np.asarray(bins).T.astype(np.int64)
        idx += self._offsets[:, None]
        idx += np.asarray(policy, dtype=np.int64) * self._stride
        per = self._flat.take(idx)
        match = np.bitwise_and.reduce(per, axis=0)
        full = match != 0
        if not full.all():
            miss = np.flatnonzero(~full)
            match[miss] = self._best_partial(list(per[:, miss]), self.valid[policy[miss]])
        if conflict == "strongest":
            return lowest_bit(match), full
        if conflict == "proportional":
            if rng is None:
                raise ConfigError("conflict='proportional' needs an rng")
            return self._draw(policy, match, rng), full
        raise ConfigError(f"unknown conflict resolution {conflict!r} (use 'strongest' or 'proportional')")

    def _best_partial(self, per: list[np.ndarray], valid: np.ndarray) -> np.ndarray:
        """Mask of the rules that satisfy the most conditions (bit-sliced count, MSB-first max)."""
        planes = [np.zeros_like(valid) for _ in range(self._planes)]
        for m in per:
            carry = m & valid
            for i in range(self._planes):
                nxt = planes[i] & carry
                planes[i] ^= carry
                carry = nxt
        cand = valid.copy()
        for plane in reversed(planes):
            narrowed = cand & plane
            cand = np.where(narrowed != 0, narrowed, cand)
        return cand

    def _draw(self, policy: np.ndarray, match: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        bits = ((match[:, None] >> np.arange(64, dtype=np.uint64)[None, :]) & _ONE).astype(bool)
        w = np.where(bits, self.strength[policy] + 1e-6, 0.0)
        c = np.cumsum(w, axis=1)
        u = rng.random(len(match)) * c[:, -1]
        rank: np.ndarray = np.minimum((c < u[:, None]).sum(axis=1), 63)
        return rank

    def action_values(self, policy: np.ndarray, rank: np.ndarray) -> np.ndarray:
        """(n, A) action indices of the chosen rules."""
        actions: np.ndarray = self.actions[policy, rank]
        return actions

    def rule_index(self, policy: np.ndarray, rank: np.ndarray) -> np.ndarray:
        """Original rule indices of ranks."""
        rules: np.ndarray = self.rank_to_rule[policy, rank]
        return rules
