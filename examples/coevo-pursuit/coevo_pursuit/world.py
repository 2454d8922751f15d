"""The pursuit world, batched: many episodes at once on numpy arrays, a pursuer and an evader in each.

The arena is a square with no walls: it wraps around (a torus, as in the classic pursuit grids), so neither side
can be cornered and the game is decided by how the two move.  Both sense the same things about the other, in the
arena's frame: the ``bearing`` to it (eight 45-degree bins, 0 = east, counter-clockwise) and the ``range`` to it
(eight bins of 2 units), both the shortest way round.  Each sets a ``heading`` (the middle of one of the eight
bearing bins), and both move at once, at their own speeds.  The pursuer captures the evader when they come within
the capture distance; otherwise the episode ends after ``steps`` steps.

Why a torus: in a walled arena the hand-written evader (head straight away) reached a wall and was caught in
2,000 of 2,000 games even when faster than the pursuer (measured: evader speed 1.0 to 1.5, pursuer 1.0), so the
game was one-sided before anyone learned.

Payoffs in [0, 1]: the pursuer is paid by how soon it captures (``1 - t / (steps + 1)``, 0 if it does not), the
evader by how long it stays free (``t / (steps + 1)`` if captured at step ``t``, 1 if never).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.policy.schema import Action, Schema, Sensor, register

from coevo_pursuit.settings import PursuitConfig

__all__ = ["PURSUER", "EVADER", "BEHAVIOURS", "Played", "play", "starts"]

PURSUER, EVADER = "pursuer", "evader"
BEHAVIOURS = (PURSUER, EVADER)
HEADINGS = tuple(22.5 + 45.0 * k for k in range(8))  # the middle of each bearing bin

_SENSORS = (Sensor("bearing", 45.0, 8, True, "deg"), Sensor("range", 2.0, 8, False, "units"))
SCHEMAS = {b: Schema(b, _SENSORS, (Action("heading", HEADINGS),)) for b in BEHAVIOURS}
register(*SCHEMAS.values())


@dataclass(frozen=True)
class Played:
    """What a batch of episodes did, per lane: captured or not, the step it ended at, each side's payoff; the
    learner's decisions (for the GA's credit) and, when recorded, both bodies' paths."""

    captured: np.ndarray  # (L,) bool
    ended: np.ndarray  # (L,) steps played
    payoff: dict[str, np.ndarray]  # behaviour -> (L,) payoff
    fired: np.ndarray  # (L,) uint64: the learner's rules that fired in each lane
    log: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # the learner's bins, rule, full, lane per decision
    paths: dict[str, np.ndarray] | None = None  # behaviour -> (steps + 1, L, 2) positions (NaN after the end)
    rules: dict[str, np.ndarray] | None = None  # behaviour -> (steps, L) rule fired (-1 after the end)


def starts(world: PursuitConfig, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` starts: the pursuer anywhere, the evader at least ``min_start`` away (drawn again until it is)."""
    p = rng.uniform(0.0, world.arena, (n, 2))
    e = rng.uniform(0.0, world.arena, (n, 2))
    for _ in range(100):
        near = np.linalg.norm(offset(p, e, world), axis=1) < min(world.min_start, world.arena * 0.7)
        if not near.any():
            break
        e[near] = rng.uniform(0.0, world.arena, (int(near.sum()), 2))
    return p, e


def offset(me: np.ndarray, other: np.ndarray, world: PursuitConfig) -> np.ndarray:
    """(n, 2) from ``me`` to ``other`` the shortest way round the arena."""
    half = world.arena / 2
    return np.mod(other - me + half, world.arena) - half


def _sense(me: np.ndarray, other: np.ndarray, world: PursuitConfig, schema: Schema) -> np.ndarray:
    d = offset(me, other, world)
    return schema.discretise({"bearing": np.degrees(np.arctan2(d[:, 1], d[:, 0])), "range": np.hypot(d[:, 0], d[:, 1])})


def play(learners: list[RuleSet], learner: str, opponent: RuleSet, world: PursuitConfig, rng: np.random.Generator, *,
         episodes: int, conflict: str = "strongest", record: bool = False) -> Played:
    """``episodes`` episodes for each of ``learners`` (rule sets of ``learner``) against one ``opponent``, from
    common random starts (every learner meets the same ones): lanes ``i * episodes ... (i + 1) * episodes - 1``
    are learner ``i``'s."""
    P, T = len(learners), world.steps
    L = P * episodes
    p0, e0 = starts(world, episodes, rng)
    pos = {PURSUER: np.tile(p0, (P, 1)), EVADER: np.tile(e0, (P, 1))}
    speed = {PURSUER: world.pursuer_speed, EVADER: world.evader_speed}
    other = EVADER if learner == PURSUER else PURSUER
    compiled = {learner: CompiledPolicies(learners), other: CompiledPolicies([opponent])}
    lane_policy = {learner: np.repeat(np.arange(P), episodes), other: np.zeros(L, np.int64)}
    headings = np.radians(np.array(HEADINGS))
    ended, active = np.full(L, T), np.ones(L, dtype=bool)
    captured, fired = np.zeros(L, dtype=bool), np.zeros(L, dtype=np.uint64)
    logs: list[list[np.ndarray]] = [[], [], [], []]
    paths = {b: np.full((T + 1, L, 2), np.nan) for b in BEHAVIOURS} if record else None
    rules = {b: np.full((T, L), -1, np.int64) for b in BEHAVIOURS} if record else None
    if paths is not None:
        for b in BEHAVIOURS:
            paths[b][0] = pos[b]
    for t in range(T):
        lanes = np.flatnonzero(active)
        if lanes.size == 0:
            break
        moves = {}
        for b in BEHAVIOURS:
            bins = _sense(pos[b][lanes], pos[EVADER if b == PURSUER else PURSUER][lanes], world, SCHEMAS[b])
            rank, full = compiled[b].decide(lane_policy[b][lanes], bins, conflict=conflict, rng=rng)
            rule = compiled[b].rule_index(lane_policy[b][lanes], rank)
            moves[b] = headings[compiled[b].action_values(lane_policy[b][lanes], rank)[:, 0]]
            if b == learner:
                fired[lanes] |= np.uint64(1) << rule.astype(np.uint64)
                for log, x in zip(logs, (bins, rule, full, lanes), strict=True):
                    log.append(x)
            if rules is not None:
                rules[b][t, lanes] = rule
        for b in BEHAVIOURS:
            step = speed[b] * np.column_stack([np.cos(moves[b]), np.sin(moves[b])])
            pos[b][lanes] = np.mod(pos[b][lanes] + step, world.arena)
            if paths is not None:
                paths[b][t + 1, lanes] = pos[b][lanes]
        caught = lanes[np.hypot(*offset(pos[PURSUER][lanes], pos[EVADER][lanes], world).T) <= world.capture]
        captured[caught], ended[caught], active[caught] = True, t + 1, False
    payoff = {PURSUER: np.where(captured, 1.0 - ended / (T + 1), 0.0),
              EVADER: np.where(captured, ended / (T + 1), 1.0)}
    log = tuple(np.concatenate(x) if x else np.zeros(0, np.int64) for x in logs)
    return Played(captured, ended, payoff, fired, log, paths, rules)  # type: ignore[arg-type]
