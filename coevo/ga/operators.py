"""GA operators on whole policies (report Appendix A §2, Appendix C §7).

Each operator is a small function of its inputs and an ``np.random.Generator``:

- :func:`select_parents`: the top fraction of the population reproduces *(ours)*.
- :func:`crossover`: SAMUEL's rule exchange. Rules that fired together in one of a
  parent's high-payoff episodes form a cluster and travel to the same offspring;
  the other rules go to either offspring at random.
- Lamarckian operators, driven by a parent's recorded experience, each returning
  one new rule for an offspring: :func:`specialise` (a weak, general rule that fired
  in a high-payoff episode gets a narrowed copy around the sensor values it fired
  on, strength = that payoff), :func:`generalise` (a strong rule gets a widened
  copy), :func:`cover` (a state no rule matched gets a rule of its own),
  :func:`split` (a rule that fired both where episodes paid and where they failed is
  narrowed on the sensor that tells the two apart); and :func:`delete`, which drops a
  rule that never fired.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coevo.policy.rules import MAX_RULES, RuleSet, interval_width
from coevo.policy.strength import fired_matrix

__all__ = [
    "Experience",
    "select_parents",
    "crossover",
    "specialise",
    "generalise",
    "cover",
    "split",
    "delete",
    "trim",
]


@dataclass
class Experience:
    """What one individual did during its evaluation.

    ``fired`` (m,) uint64 and ``payoff`` (m,) per episode it controlled; the
    decision log ``bins`` (N, S), ``rule`` (N,), ``full`` (N,) and ``episode`` (N,)
    (index into the per-episode arrays).
    """

    fired: np.ndarray
    payoff: np.ndarray
    bins: np.ndarray
    rule: np.ndarray
    full: np.ndarray
    episode: np.ndarray
    high_quantile: float = 0.5

    @property
    def high(self) -> np.ndarray:
        """Episodes counted as high payoff: above the quantile and above zero."""
        if self.payoff.size == 0:
            return np.zeros(0, dtype=bool)
        cut = np.quantile(self.payoff, self.high_quantile)
        high: np.ndarray = (self.payoff >= cut) & (self.payoff > 0)
        return high

    def fired_rules(self, n_rules: int) -> np.ndarray:
        """(n_rules,) bool: rules that fired at least once."""
        if self.fired.size == 0:
            return np.zeros(n_rules, dtype=bool)
        fired: np.ndarray = fired_matrix(np.bitwise_or.reduce(self.fired, keepdims=True), n_rules)[0]
        return fired

    @staticmethod
    def empty(n_sensors: int) -> Experience:
        z = np.zeros(0, dtype=np.int64)
        return Experience(np.zeros(0, np.uint64), np.zeros(0), np.zeros((0, n_sensors), np.uint8), z, np.zeros(0, bool), z)


def select_parents(fitness: np.ndarray, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """Indices of the top ``fraction`` by fitness (ties broken at random)."""
    n = max(1, int(len(fitness) * fraction))
    jitter = rng.random(len(fitness))
    order = np.lexsort((jitter, -np.asarray(fitness)))
    return order[:n]


def _units(rs: RuleSet, exp: Experience) -> list[np.ndarray]:
    """Partition a parent's rules into clusters (fired together in a high-payoff episode) and singletons."""
    n = len(rs)
    assigned = np.zeros(n, dtype=bool)
    units: list[np.ndarray] = []
    high = np.flatnonzero(exp.high)
    if high.size:
        f = fired_matrix(exp.fired[high], n)
        for e in high[np.argsort(-exp.payoff[high], kind="stable")]:
            row = f[np.searchsorted(high, e)] & ~assigned
            if row.any():
                units.append(np.flatnonzero(row))
                assigned |= row
    units += [np.array([i]) for i in np.flatnonzero(~assigned)]
    return units


def crossover(
    a: RuleSet, ea: Experience, b: RuleSet, eb: Experience, rng: np.random.Generator
) -> tuple[tuple[RuleSet, np.ndarray], tuple[RuleSet, np.ndarray]]:
    """Two offspring exchanging rule clusters of ``a`` and ``b`` (each gets at least one rule).

    Each offspring comes with a bool mask of its rules that never fired in their
    parent's evaluation (for :func:`delete`).
    """
    pools: list[list[tuple[RuleSet, np.ndarray]]] = [[], []]
    for rs, exp in ((a, ea), (b, eb)):
        idle = ~exp.fired_rules(len(rs))
        for unit in _units(rs, exp):
            pools[int(rng.integers(2))].append((rs.take(unit), idle[unit]))
    for side in (0, 1):
        if not pools[side]:  # steal one unit so neither child is empty
            other = pools[1 - side]
            pools[side].append(other.pop(int(rng.integers(len(other)))))
    children = []
    for pool in pools:
        idle = np.concatenate([p[1] for p in pool])
        if len(idle) > MAX_RULES:  # concat keeps the strongest, in order: keep the same flags
            strength = np.concatenate([p[0].strength for p in pool])
            idle = idle[np.sort(np.argsort(-strength, kind="stable")[:MAX_RULES])]
        children.append((RuleSet.concat(a.behaviour, [p[0] for p in pool]), idle))
    return children[0], children[1]


def specialise(
    rs: RuleSet,
    exp: Experience,
    rng: np.random.Generator,
    *,
    low_strength: float,
    fraction: float = 1.0,
    recency: float = 0.0,
    usable: np.ndarray | None = None,
) -> RuleSet | None:
    """A narrowed copy of a weak general rule of ``rs`` that fired in a high-payoff episode, or None.

    Each condition is narrowed with probability ``fraction`` (at least one is); the
    others keep the parent's interval *(ours)*: narrowing every condition also pins
    the sensors the decision does not depend on, and the copy then rarely fires.
    With ``recency`` > 0 *(ours)* the episode is drawn first and the decision to
    specialise is drawn from it with weight ``recency ** (decisions until the
    episode's end)``: the payoff comes at the end, so the last decisions earn it most
    (a discounted credit, as in profit sharing).
    """
    high = np.flatnonzero(exp.high)
    if high.size == 0:
        return None
    width = interval_width(rs)
    bins = np.array([s.bins for s in rs.schema.sensors])
    cols = slice(None) if usable is None else np.flatnonzero(usable)  # ``usable``: only those sensors count and narrow
    general = (width[:, cols] / bins[cols]).mean(axis=1) > 0.25
    fired_high = fired_matrix(exp.fired[high], len(rs))
    cand = np.flatnonzero((rs.strength < low_strength) & general & fired_high.any(axis=0))
    if cand.size == 0:
        return None
    if recency > 0:
        picked = _recent_decision(exp, high[fired_high[:, cand].any(axis=1)], cand, recency, rng)
        if picked is None:
            return None
        r, e, v = picked
    else:
        r = int(rng.choice(cand))
        e = int(rng.choice(high[fired_high[:, r]]))
        states = exp.bins[(exp.rule == r) & (exp.episode == e)]
        if states.shape[0] == 0:
            return None
        v = states[int(rng.integers(states.shape[0]))].astype(np.int64)
    lo, hi = _interval_around(rs, v, width[r] // 4)  # about half as wide, centred on what was seen
    if fraction < 1.0 or usable is not None:
        if usable is None:
            keep = _kept_conditions(rs.schema.n_sensors, fraction, rng)
        else:
            used = np.flatnonzero(usable)
            keep = np.ones(rs.schema.n_sensors, dtype=bool)
            keep[used] = _kept_conditions(len(used), fraction, rng) if fraction < 1.0 else False
        lo = np.where(keep, rs.lo[r], lo)
        hi = np.where(keep, rs.hi[r], hi)
    return RuleSet(rs.behaviour, lo[None], hi[None], rs.action[r][None], np.array([exp.payoff[e]]).clip(0, 1))


def _recent_decision(
    exp: Experience, episodes: np.ndarray, cand: np.ndarray, recency: float, rng: np.random.Generator
) -> tuple[int, int, np.ndarray] | None:
    """(rule, episode, sensor bins) of a decision by a ``cand`` rule in one of ``episodes``, late ones likelier."""
    if episodes.size == 0:
        return None
    e = int(rng.choice(episodes))
    idx = np.flatnonzero(exp.episode == e)  # this episode's decisions, in time order
    age = idx.size - 1 - np.arange(idx.size)
    ok = np.isin(exp.rule[idx], cand)
    if not ok.any():
        return None
    w = np.where(ok, recency ** age.astype(np.float64), 0.0)
    if w.sum() <= 0:  # underflow far from the end: take the latest candidate decision
        i = int(idx[np.flatnonzero(ok)[-1]])
    else:
        i = int(idx[rng.choice(idx.size, p=w / w.sum())])
    return int(exp.rule[i]), e, exp.bins[i].astype(np.int64)


def _kept_conditions(n: int, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """(n,) bool: conditions left as they were; each is changed with probability ``fraction``, at least one."""
    change = rng.random(n) < fraction
    if not change.any():
        change[int(rng.integers(n))] = True
    return ~change


def generalise(rs: RuleSet, exp: Experience, rng: np.random.Generator, usable: np.ndarray | None = None) -> RuleSet:
    """A widened copy of one of the strongest rules of ``rs`` (its conditions on ``usable`` sensors)."""
    top = np.flatnonzero(rs.strength >= np.quantile(rs.strength, 0.75))
    r = int(rng.choice(top))
    width = interval_width(rs)[r]
    lo = rs.lo[r].astype(np.int64)
    hi = rs.hi[r].astype(np.int64)
    for j, s in enumerate(rs.schema.sensors):
        if usable is not None and not usable[j]:
            continue
        grow = int(rng.integers(1, max(2, s.bins // 10) + 1))
        if s.circular:
            if width[j] + 2 * grow >= s.bins:
                lo[j], hi[j] = 0, s.bins - 1
            else:
                lo[j], hi[j] = (lo[j] - grow) % s.bins, (hi[j] + grow) % s.bins
        else:
            lo[j], hi[j] = max(0, lo[j] - grow), min(s.bins - 1, hi[j] + grow)
    return RuleSet(rs.behaviour, lo[None], hi[None], rs.action[r][None], rs.strength[r][None])


def cover(rs: RuleSet, exp: Experience, rng: np.random.Generator, *, partial: bool = False) -> RuleSet | None:
    """A rule for a state of ``rs``'s evaluation that no rule matched, or None if there was none.

    It prefers states from high-payoff episodes and then keeps the action taken
    there; otherwise the action is random.  Its strength is the episode's payoff.
    With ``partial`` *(ours, after SAMUEL's covering)* the new rule is instead the
    best partial match that fired there, its unmet conditions widened just enough to
    hold the state, with that rule's action and strength.
    """
    unmatched = np.flatnonzero(~exp.full)
    if unmatched.size == 0:
        return None
    good = unmatched[exp.high[exp.episode[unmatched]]]
    pick = int(rng.choice(good if good.size else unmatched))
    v = exp.bins[pick].astype(np.int64)
    if partial:
        return _widened_to(rs, int(exp.rule[pick]), v)
    bins = np.array([s.bins for s in rs.schema.sensors])
    lo, hi = _interval_around(rs, v, np.maximum(bins // 8, 1))
    if good.size:
        action = rs.action[exp.rule[pick]]
    else:
        action = np.array([rng.integers(len(a.values)) for a in rs.schema.actions])
    strength = np.array([exp.payoff[exp.episode[pick]]]).clip(0, 1)
    return RuleSet(rs.behaviour, lo[None], hi[None], np.asarray(action)[None], strength)


def _widened_to(rs: RuleSet, r: int, v: np.ndarray) -> RuleSet:
    """Rule ``r`` of ``rs`` with each condition that ``v`` misses stretched, at its nearer end, to reach ``v``."""
    lo = rs.lo[r].astype(np.int64)
    hi = rs.hi[r].astype(np.int64)
    for j, s in enumerate(rs.schema.sensors):
        a, b, x = lo[j], hi[j], v[j]
        if s.circular:
            if (a <= b and a <= x <= b) or (a > b and (x >= a or x <= b)):
                continue
            if (a - x) % s.bins <= (x - b) % s.bins:
                lo[j] = x
            else:
                hi[j] = x
        else:
            lo[j], hi[j] = min(a, x), max(b, x)
    return RuleSet(rs.behaviour, lo[None], hi[None], rs.action[r][None], rs.strength[r][None])


def split(
    rs: RuleSet, exp: Experience, rng: np.random.Generator, usable: np.ndarray | None = None, *, min_gain: float = 0.2,
) -> tuple[int, RuleSet] | None:
    """``(r, narrowed)``: rule ``r`` of ``rs``, over-general by ``exp``, and its copy narrowed to where it paid; or None.

    *(ours)* A rule that fired both in high-payoff episodes and in zero-payoff ones may be right in one
    place and wrong in another (Docking: "straight ahead at 12 ips" far from the dock and just before
    it).  One such rule is drawn; of every ``usable`` sensor and every cut inside the rule's interval,
    the one whose side holds the largest share of the rule's high-payoff decisions beyond its share of
    the zero-payoff ones wins (by at least ``min_gain``), and that side becomes the copy's interval on
    the sensor.  The copy's strength is the mean payoff of the episodes it fired in on that side.
    """
    if exp.payoff.size == 0 or exp.rule.size == 0:
        return None
    high, zero = exp.high, exp.payoff <= 0
    if not high.any() or not zero.any():
        return None
    in_high, in_zero = high[exp.episode], zero[exp.episode]  # per decision
    both = np.intersect1d(exp.rule[in_high], exp.rule[in_zero])
    if both.size == 0:
        return None
    r = int(rng.choice(both))
    mine = exp.rule == r
    states, h, z = exp.bins[mine].astype(np.int64), in_high[mine], in_zero[mine]
    width = interval_width(rs)[r]
    cols = range(rs.schema.n_sensors) if usable is None else np.flatnonzero(usable)
    best_gain, best = min_gain, None
    for j in cols:
        w = int(width[j])
        if w < 2:
            continue
        pos = (states[:, j] - int(rs.lo[r, j])) % rs.schema.sensors[j].bins  # place inside the interval
        low_h = np.bincount(pos[h], minlength=w)[: w - 1].cumsum() / h.sum()  # share at or below each cut
        low_z = np.bincount(pos[z], minlength=w)[: w - 1].cumsum() / z.sum()
        gain = low_h - low_z  # > 0: keep the low side; < 0: the high side
        c = int(np.argmax(np.abs(gain)))
        if abs(gain[c]) > best_gain:
            best_gain, best = abs(gain[c]), (int(j), c, bool(gain[c] > 0), pos)
    if best is None:
        return None
    j, c, low_side, pos = best
    bins = rs.schema.sensors[j].bins
    lo, hi = rs.lo[r].astype(np.int64), rs.hi[r].astype(np.int64)
    if low_side:
        hi[j], kept = (lo[j] + c) % bins, pos <= c
    else:
        lo[j], kept = (lo[j] + c + 1) % bins, pos > c
    strength = exp.payoff[np.unique(exp.episode[mine][kept])].mean()
    return r, RuleSet(rs.behaviour, lo[None], hi[None], rs.action[r][None], np.array([float(np.clip(strength, 0, 1))]))


def delete(rs: RuleSet, idle: np.ndarray) -> tuple[RuleSet, np.ndarray]:
    """Drop the weakest rule flagged ``idle`` (never fired), keeping at least one rule."""
    cand = np.flatnonzero(idle)
    if len(rs) <= 1 or cand.size == 0:
        return rs, idle
    r = cand[np.argmin(rs.strength[cand])]
    keep = np.delete(np.arange(len(rs)), r)
    return rs.take(keep), idle[keep]


def trim(rs: RuleSet, max_rules: int) -> RuleSet:
    """Keep the ``max_rules`` strongest rules (order otherwise kept)."""
    if len(rs) <= max_rules:
        return rs
    keep = np.sort(np.argsort(-rs.strength, kind="stable")[:max_rules])
    return rs.take(keep)


def _interval_around(rs: RuleSet, v: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = np.empty_like(v)
    hi = np.empty_like(v)
    for j, s in enumerate(rs.schema.sensors):
        if s.circular:
            lo[j], hi[j] = (v[j] - half[j]) % s.bins, (v[j] + half[j]) % s.bins
        else:
            lo[j], hi[j] = max(0, v[j] - half[j]), min(s.bins - 1, v[j] + half[j])
    return lo, hi
