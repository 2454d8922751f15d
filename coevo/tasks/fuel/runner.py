"""The epoch runner: an Executive, a Tracking and a Docking policy driving many lanes at once.

A *lane* is one robot's life in its own arena: ``lane_episodes`` episodes in a row.
An epoch starts with random positions and the initial fuel; episodes of an epoch
keep positions and fuel; an epoch ends after ``epoch_episodes`` episodes, on a
collision or on running dry (report Appendix A §6).  With ``restart_epochs`` a
lane starts a new epoch at once, so it always plays all its episodes (how the
Tracking and Docking agents are evaluated); without, a lane is one epoch (how the
Executive and the combined robot are evaluated).

Each controller is either :class:`Trivial` (always the same task) or
:class:`Rules` (compiled rule sets and, per lane, which one to use), so one run can
evaluate a whole population against fixed partners.

Common random numbers: with ``scenarios=g``, lane ``i`` lives scenario ``i % g``:
its ``e``-th epoch starts where every other lane of that scenario starts its
``e``-th epoch, and its Target gets the same heading noise at the same step.  A
population evaluated with ``g`` = lanes per individual thus faces identical
situations, so selection compares policies, not luck.  By default every lane is
its own scenario.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from types import ModuleType

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.schema import schema
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK, Behaviour
from coevo.tasks.fuel.recorder import Recorder
from coevo.tasks.fuel.world import BatchWorld, compiled_loops, sensor_tables

__all__ = ["Trivial", "Rules", "Trace", "Outcome", "run_lanes", "ALWAYS_TRACK", "ALWAYS_DOCK"]

_TURN = np.array(schema(Behaviour.TRACKING).actions[0].values, dtype=np.float64)
_SPEED = np.array(schema(Behaviour.TRACKING).actions[1].values, dtype=np.float64)
_ONE = np.uint64(1)
_RANKS = 64  # rank slots per policy in CompiledPolicies' tables


@dataclass(frozen=True)
class Trivial:
    """An Executive that always picks the same task."""

    task: int


ALWAYS_TRACK = Trivial(TASK_TRACK)
ALWAYS_DOCK = Trivial(TASK_DOCK)


@dataclass(frozen=True)
class Rules:
    """Rule-set policies; lane ``i`` uses ``compiled.policies[lane_policy[i]]``."""

    compiled: CompiledPolicies
    lane_policy: np.ndarray

    @staticmethod
    def single(compiled: CompiledPolicies, lanes: int) -> Rules:
        return Rules(compiled, np.zeros(lanes, dtype=np.int64))

    @cached_property
    def commands(self) -> tuple[np.ndarray, np.ndarray]:
        """Turn rate and speed of every (policy, rank), flat at ``policy * 64 + rank``: one gather per command
        instead of indexing the (P, 64, A) action table and then the value lists; made once per controller."""
        a = self.compiled.actions.reshape(-1, self.compiled.actions.shape[-1])
        return _TURN[a[:, 0]], _SPEED[a[:, 1]]


@dataclass
class Trace:
    """The learner's decisions: sensor bins, fired rule (-1: not the learner's) and full-match flag.

    Indexed ``[episode k, step t, lane]`` for Tracking/Docking, ``[episode k, lane]``
    for the Executive (one decision per episode).
    """

    bins: np.ndarray
    rule: np.ndarray
    full: np.ndarray


@dataclass
class Outcome:
    """Everything that happened, per lane and episode ``(L, K)`` and per epoch ``(E,)``."""

    played: np.ndarray
    task: np.ndarray
    steps: np.ndarray
    tracked: np.ndarray
    collided: np.ndarray
    docked: np.ndarray
    dry: np.ndarray
    payoff: np.ndarray  # payoff of the agent in control (Tracking or Docking)
    epoch_of: np.ndarray  # epoch id (index into the epoch arrays) of each played episode, -1 if not played
    fired: np.ndarray  # (L, K) uint64: the learner's rules (bit = rule index) that fired
    epoch_lane: np.ndarray
    epoch_tracked: np.ndarray
    epoch_penalty: np.ndarray
    epoch_episodes: np.ndarray
    epoch_complete: np.ndarray  # ended by its own rules, not cut off by the lane's last episode
    epoch_payoff: np.ndarray  # Executive payoff t / (e + p)
    trace: Trace | None = field(default=None)


def _check(name: str, c: Trivial | Rules | None, lanes: int, behaviour: Behaviour) -> None:
    if isinstance(c, Rules):
        if c.compiled.schema.behaviour != behaviour:
            raise ConfigError(f"{name} controller holds {c.compiled.schema.behaviour} rules, expected {behaviour}")
        if c.lane_policy.shape != (lanes,):
            raise ConfigError(f"{name} lane_policy has shape {c.lane_policy.shape}, expected ({lanes},)")


_Group = tuple[Behaviour, Rules, np.ndarray | None, np.ndarray]  # a controller, its lanes (None: all), their policies


@dataclass
class _Controls:
    """The controllers of one run and what the learner's decisions are logged into."""

    executive: Trivial | Rules
    roles: list[tuple[int, Behaviour, Rules]]  # (task, behaviour, controller) of Tracking and Docking, if given
    missing: list[tuple[int, Behaviour]]  # (task, behaviour) of those not given: the Executive may not pick them
    learner: Behaviour | None
    conflict: str
    rng: np.random.Generator
    record: Recorder | None


class _Lanes:
    """Everything that happens on the lanes of one run: the per-episode arrays, the epoch records
    (keyed by epoch id, handed out as epochs open: at most L*K of them) and the learner's trace."""

    def __init__(self, world: BatchWorld, K: int, g: int, learner: Behaviour | None, rng: np.random.Generator) -> None:
        cfg = world.cfg
        L, T = world.n, cfg.episode_steps
        self.world, self.cfg, self.L, self.K, self.T, self.g = world, cfg, L, K, T, g
        self.slot = np.arange(L) % g
        self.starts = world.random_starts(g * K, rng).reshape(g, K, -1)  # a lane has at most K epochs
        self.epoch_no = np.zeros(L, dtype=np.int64)
        self.played = np.zeros((L, K), dtype=bool)
        self.task = np.full((L, K), -1, dtype=np.int8)
        self.steps = np.zeros((L, K), dtype=np.int32)
        self.tracked = np.zeros((L, K), dtype=np.int32)
        self.collided = np.zeros((L, K), dtype=bool)
        self.docked = np.zeros((L, K), dtype=bool)
        self.dry = np.zeros((L, K), dtype=bool)
        self.payoff = np.zeros((L, K))
        self.epoch_of = np.full((L, K), -1, dtype=np.int64)
        self.fired = np.zeros((L, K), dtype=np.uint64)
        self.e_lane = np.zeros(L * K, dtype=np.int64)
        self.e_tr = np.zeros(L * K, dtype=np.int64)
        self.e_pen = np.zeros(L * K, dtype=np.int64)
        self.e_eps = np.zeros(L * K, dtype=np.int64)
        self.e_cmp = np.zeros(L * K, dtype=bool)
        self.trace: Trace | None = None  # made exactly when there is a learner
        if learner is not None:
            S = schema(learner).n_sensors
            shape = (K, L) if learner == Behaviour.EXECUTIVE else (K, T, L)
            self.trace = Trace(np.zeros(shape + (S,), np.uint8), np.full(shape, -1, np.int16), np.zeros(shape, bool))
        self.alive = np.ones(L, dtype=bool)
        self.ep_tracked = np.zeros(L, dtype=np.int64)
        self.ep_count = np.zeros(L, dtype=np.int64)
        self.ep_id = np.arange(L)
        self.n_epochs = L
        self.min_steps = np.zeros(L)  # per episode: the fewest steps a Docking lane could dock in
        world.reset(np.arange(L), starts=self.starts[:, 0][self.slot])

    def outcome(self) -> Outcome:
        n = self.n_epochs
        e_lane, e_tr, e_pen, e_eps, e_cmp = (a[:n] for a in (self.e_lane, self.e_tr, self.e_pen, self.e_eps, self.e_cmp))
        e_pay = e_tr / (self.T * self.cfg.epoch_episodes + e_pen)
        return Outcome(
            played=self.played, task=self.task, steps=self.steps, tracked=self.tracked, collided=self.collided,
            docked=self.docked, dry=self.dry, payoff=self.payoff, epoch_of=self.epoch_of, fired=self.fired,
            epoch_lane=e_lane, epoch_tracked=e_tr, epoch_penalty=e_pen, epoch_episodes=e_eps, epoch_complete=e_cmp,
            epoch_payoff=e_pay, trace=self.trace,
        )


def run_lanes(
    world: BatchWorld,
    *,
    lane_episodes: int,
    executive: Trivial | Rules,
    tracking: Rules | None,
    docking: Rules | None,
    restart_epochs: bool,
    rng: np.random.Generator,
    learner: Behaviour | str | None = None,
    conflict: str = "strongest",
    scenarios: int | None = None,
    tick: Callable[[], None] | None = None,
    record: Recorder | None = None,
) -> Outcome:
    """Run every lane of ``world`` for ``lane_episodes`` episodes; see the module docstring.

    ``tick``, if given, is called before every episode round (a fraction of a second
    apart): a worker's heartbeat, so a long evaluation still shows it progressing.
    ``record``, if given, receives every lane's state and fired rules at every step
    (:mod:`coevo.tasks.fuel.recorder`; for a few lanes).  Without it the loop does no extra
    work beyond a test per controller and step.
    """
    L, K, T = world.n, lane_episodes, world.cfg.episode_steps
    g = L if scenarios is None else scenarios
    if not 1 <= g <= L or L % g:
        raise ConfigError(f"scenarios={scenarios} must divide the {L} lanes")
    learner = Behaviour(learner) if learner is not None else None
    s = _Lanes(world, K, g, learner, rng)
    _check("executive", executive, L, Behaviour.EXECUTIVE)
    _check("tracking", tracking, L, Behaviour.TRACKING)
    _check("docking", docking, L, Behaviour.DOCKING)
    roles = [(TASK_TRACK, Behaviour.TRACKING, tracking), (TASK_DOCK, Behaviour.DOCKING, docking)]
    c = _Controls(executive, [(t, b, ctrl) for t, b, ctrl in roles if ctrl is not None],
                  [(t, b) for t, b, ctrl in roles if ctrl is None], learner, conflict, rng, record)
    if record is not None:
        record.open(L, K, T)
    for k in range(K):
        live = np.flatnonzero(s.alive)
        if live.size == 0:
            break
        if tick is not None:
            tick()
        _choose_tasks(s, c, k, live)
        _play_episode(s, c, k, live)
        _pay_episode(s, k, live)
        _close_epochs(s, k, live, restart_epochs)
    return s.outcome()


def _choose_tasks(s: _Lanes, c: _Controls, k: int, live: np.ndarray) -> None:
    """The Executive picks episode ``k``'s task on every live lane."""
    ex = c.executive
    if isinstance(ex, Trivial):
        s.task[live, k] = ex.task
        if c.record is not None:
            c.record.decision(k, live, s.task[live, k], None)
    else:
        sch = ex.compiled.schema
        bins = sch.discretise(s.world.observe(sch.sensor_names))[live]
        pol = ex.lane_policy[live]
        rank, full = ex.compiled.decide(pol, bins, conflict=c.conflict, rng=c.rng)
        s.task[live, k] = ex.compiled.action_values(pol, rank)[:, 0]
        if c.record is not None or c.learner == Behaviour.EXECUTIVE:
            rule = ex.compiled.rule_index(pol, rank)
        if c.record is not None:
            c.record.decision(k, live, s.task[live, k], rule)
        tr = s.trace
        if c.learner == Behaviour.EXECUTIVE and tr is not None:
            tr.bins[k, live], tr.rule[k, live], tr.full[k, live] = bins, rule, full
            s.fired[live, k] |= _ONE << rule.astype(np.uint64)
    lane_task = s.task[:, k].astype(np.int64)
    for role, beh in c.missing:
        if (lane_task[live] == role).any():
            raise ConfigError(f"the Executive picked {beh} but no {beh} policy was given")
    s.played[live, k] = True
    s.epoch_of[live, k] = s.ep_id[live]


def _play_episode(s: _Lanes, c: _Controls, k: int, live: np.ndarray) -> None:
    """Episode ``k``: Tracking and Docking drive their lanes step by step until each lane's episode ends."""
    L, T, world = s.L, s.T, s.world
    lane_task = s.task[:, k].astype(np.int64)
    s.min_steps[:] = 0.0
    dock_lanes = live[lane_task[live] == TASK_DOCK]
    s.min_steps[dock_lanes] = world.min_dock_steps(dock_lanes)
    # Which controllers run, on which lanes (all lanes at once when one controller has them all); a task without
    # its controller has no lanes (_choose_tasks refuses it).
    groups: list[_Group] = []
    for role, beh, ctrl in c.roles:
        lanes = np.flatnonzero(lane_task == role)
        if lanes.size:
            sel = None if lanes.size == L else lanes
            groups.append((beh, ctrl, sel, ctrl.lane_policy if sel is None else ctrl.lane_policy[sel]))
    active = s.alive.copy()
    kernels = compiled_loops(L) if c.conflict == "strongest" and c.record is None else None
    if kernels is not None:
        _play_compiled(s, c, k, groups, active, kernels)
        return
    names = tuple(dict.fromkeys(n for beh, *_ in groups for n in schema(beh).sensor_names))
    if c.record is not None:
        c.record.state(world, k, 0, live)
    turn = np.zeros(L)
    speed = np.zeros(L)
    # One controller on every lane, strongest-rule conflict resolution, nothing recorded: only the active
    # lanes are sensed and decide (a standing lane's command is never used, and 'strongest' draws no
    # random numbers); the same decisions, fewer of them.
    only_active = len(groups) == 1 and groups[0][2] is None and c.conflict == "strongest" and c.record is None
    for t in range(T):
        if not active.any():
            break
        if only_active:
            beh, ctrl, _, pol = groups[0]
            sensed = None if active.all() else np.flatnonzero(active)
            bins = world._sense_bins(ctrl.compiled.schema, sensed)
            _decide(s, c, k, t, active, beh, ctrl, sensed, pol if sensed is None else pol[sensed], bins, turn, speed,
                    all_active=True)
        else:
            obs = world.observe(names)
            for beh, ctrl, sel, pol in groups:
                bins = ctrl.compiled.schema.discretise(obs)
                _decide(s, c, k, t, active, beh, ctrl, sel, pol, bins if sel is None else bins[sel], turn, speed)
        noise = c.rng.normal(0.0, s.cfg.target_turn_sd, s.g)[s.slot]
        ev = world.step(active, turn, speed, noise)
        s.steps[:, k] += active
        s.tracked[:, k] += ev.tracking
        s.collided[:, k] |= ev.collided
        s.docked[:, k] |= ev.docked
        s.dry[:, k] |= ev.dry
        if c.record is not None:
            c.record.state(world, k, t + 1, active)
        active &= ~(ev.collided | ev.docked | ev.dry)


_DIRECTIONS = (  # the directions kernels.active_lanes prepares arctangents for, and the sensors that need them
    frozenset({"range", "bearing", "heading", "target_bearing"}),  # to the Target
    frozenset({"bearing"}),  # to the dock's nearest point
    frozenset({"dock_bearing"}),  # to the middle of the dock's front
)
_NO_TRACE = (np.zeros((0, 0, 0, 0), np.uint8), np.zeros((0, 0, 0), np.int16), np.zeros((0, 0, 0), bool),
             np.zeros((0, 0), np.uint64))


def _play_compiled(s: _Lanes, c: _Controls, k: int, groups: list[_Group], active: np.ndarray,
                   kernels: ModuleType) -> None:
    """Episode ``k``'s steps in compiled loops (:mod:`.kernels`): with strongest-rule conflict resolution and
    nothing recorded, each controller senses and decides on its active lanes only (a standing lane's command is
    never used, and 'strongest' draws no random numbers): the same decisions as :func:`_decide`'s, the same
    numbers, without numpy's fixed cost of ~90 calls a step."""
    L, world = s.L, s.world
    group = np.full(L, -1, dtype=np.int64)
    for g, (_, _, sel, _) in enumerate(groups):
        group[slice(None) if sel is None else sel] = g
    names = {n for beh, *_ in groups for n in schema(beh).sensor_names}
    need = [bool(names & d) for d in _DIRECTIONS]
    slots, nd = np.where(need, np.cumsum(need) - 1, -1).astype(np.int64), sum(need)
    tr = s.trace
    per_group = [(sensor_tables(ctrl.compiled.schema), _policy_tables(ctrl), c.learner == beh,
                  (tr.bins, tr.rule, tr.full, s.fired) if c.learner == beh and tr is not None else _NO_TRACE)
                 for beh, ctrl, _, _ in groups]
    idx, bounds = np.empty(L, dtype=np.int64), np.empty(len(groups) + 1, dtype=np.int64)
    dy, dx, ang = np.empty(3 * L), np.empty(3 * L), np.empty(3 * L)
    turn, speed, events = np.zeros(L), np.zeros(L), np.zeros((4, L), dtype=np.bool_)
    state = world.sensing_state()
    rx, ry, _, tx, ty, _, _, geom = state
    for t in range(s.T):
        m = kernels.active_lanes(active, group, len(groups), slots, rx, ry, tx, ty, geom, idx, bounds, dy, dx)
        if m == 0:
            break
        n = nd * m
        kernels.atan2_into(dy[:n], dx[:n], ang[:n])
        for g, (sensors, policy, logged, trace) in enumerate(per_group):
            a0 = bounds[g]
            kernels.decide_lanes(idx[a0:bounds[g + 1]], a0, m, ang, slots, state, sensors, policy, turn, speed, logged,
                                 trace, k, t)
        noise = c.rng.normal(0.0, s.cfg.target_turn_sd, s.g)[s.slot]
        world.step_compiled(kernels, events, active, turn, speed, noise)
        kernels.tally(k, active, events, s.steps, s.tracked, s.collided, s.docked, s.dry)


def _policy_tables(ctrl: Rules) -> tuple:
    """What :func:`.kernels.decide_lanes` reads of a controller: the flat bit table, its stride per policy and per
    sensor, valid rules, each lane's policy, turn and speed of every (policy, rank), rank -> rule."""
    cp = ctrl.compiled
    _, S, B = cp.table.shape
    turn_of, speed_of = ctrl.commands
    return (cp.table.reshape(-1), S * B, B, cp.valid, ctrl.lane_policy.astype(np.int64, copy=False), turn_of, speed_of,
            cp.rank_to_rule)


def _decide(s: _Lanes, c: _Controls, k: int, t: int, active: np.ndarray, beh: Behaviour, ctrl: Rules,
            sel: np.ndarray | None, pol: np.ndarray, bins: np.ndarray, turn: np.ndarray, speed: np.ndarray, *,
            all_active: bool = False) -> None:
    """One controller's decisions at step ``t`` on its lanes (``sel``; None: all); the learner's are logged.

    ``bins`` are the sensor bins of the lanes of ``sel`` (None: all lanes); with ``all_active`` all of
    them are active."""
    rank, full = ctrl.compiled.decide(pol, bins, conflict=c.conflict, rng=c.rng)
    turn_of, speed_of = ctrl.commands
    where = slice(None) if sel is None else sel
    flat = pol * _RANKS + rank
    turn[where] = turn_of.take(flat)
    speed[where] = speed_of.take(flat)
    if c.record is None and c.learner != beh:
        return
    lanes = np.arange(s.L) if sel is None else sel
    if all_active:
        rule = ctrl.compiled.rule_index(pol, rank)
    else:
        mine = active[lanes]
        lanes, rule, bins, full = lanes[mine], ctrl.compiled.rule_index(pol[mine], rank[mine]), bins[mine], full[mine]
    if c.record is not None:
        c.record.fired(k, t, lanes, rule)
    tr = s.trace
    if c.learner == beh and tr is not None:
        tr.bins[k, t, lanes], tr.rule[k, t, lanes], tr.full[k, t, lanes] = bins, rule, full
        s.fired[lanes, k] |= _ONE << rule.astype(np.uint64)


def _pay_episode(s: _Lanes, k: int, lk: np.ndarray) -> None:
    """Episode payoffs of the agent in control (report Appendix A §6.1)."""
    T = s.T
    lane_task = s.task[:, k].astype(np.int64)
    track_pay = np.where(s.collided[lk, k], 0.0, s.tracked[lk, k] / T)
    ratio = np.minimum(1.0, s.min_steps[lk] / np.maximum(s.steps[lk, k], 1))
    dock_pay = np.where(s.docked[lk, k], 0.5 + 0.5 * ratio, 0.0)
    s.payoff[lk, k] = np.where(lane_task[lk] == TASK_DOCK, dock_pay, track_pay)


def _close_epochs(s: _Lanes, k: int, lk: np.ndarray, restart_epochs: bool) -> None:
    """Record the epochs that end with episode ``k`` (a collision, running dry, the epoch's last episode or
    the lane's); with ``restart_epochs`` their lanes start a new epoch, else they retire."""
    cfg, world = s.cfg, s.world
    s.ep_tracked[lk] += s.tracked[lk, k]
    s.ep_count[lk] += 1
    ends = s.collided[lk, k] | s.dry[lk, k] | (s.ep_count[lk] >= cfg.epoch_episodes)
    last = k == s.K - 1
    closing = lk[ends | last]
    ids = s.ep_id[closing]
    s.e_lane[ids] = closing
    s.e_tr[ids] = s.ep_tracked[closing]
    s.e_pen[ids] = np.where(s.dry[closing, k], cfg.towing_penalty, 0)
    s.e_eps[ids] = s.ep_count[closing]
    s.e_cmp[ids] = ends[ends | last]
    ended = lk[ends]
    world.place_at_dock(lk[s.docked[lk, k] & ~ends])
    if restart_epochs and not last:
        s.epoch_no[ended] += 1
        world.reset(ended, starts=s.starts[s.slot[ended], s.epoch_no[ended]])
        s.ep_tracked[ended] = 0
        s.ep_count[ended] = 0
        s.ep_id[ended] = s.n_epochs + np.arange(ended.size)
        s.n_epochs += ended.size
    else:
        s.alive[ended] = False
