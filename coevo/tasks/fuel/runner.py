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

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.schema import schema
from coevo.tasks.fuel.behaviours import TASK_DOCK, TASK_TRACK, Behaviour
from coevo.tasks.fuel.recorder import Recorder
from coevo.tasks.fuel.world import BatchWorld

__all__ = ["Trivial", "Rules", "Trace", "Outcome", "run_lanes", "ALWAYS_TRACK", "ALWAYS_DOCK"]

_TURN = np.array(schema(Behaviour.TRACKING).actions[0].values, dtype=np.float64)
_SPEED = np.array(schema(Behaviour.TRACKING).actions[1].values, dtype=np.float64)
_ONE = np.uint64(1)


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
    cfg = world.cfg
    L, K, T = world.n, lane_episodes, cfg.episode_steps
    g = L if scenarios is None else scenarios
    if not 1 <= g <= L or L % g:
        raise ConfigError(f"scenarios={scenarios} must divide the {L} lanes")
    slot = np.arange(L) % g
    starts = world.random_starts(g * K, rng).reshape(g, K, -1)  # a lane has at most K epochs
    epoch_no = np.zeros(L, dtype=np.int64)
    _check("executive", executive, L, Behaviour.EXECUTIVE)
    _check("tracking", tracking, L, Behaviour.TRACKING)
    _check("docking", docking, L, Behaviour.DOCKING)
    learner = Behaviour(learner) if learner is not None else None
    roles = [(TASK_TRACK, Behaviour.TRACKING, tracking), (TASK_DOCK, Behaviour.DOCKING, docking)]

    played = np.zeros((L, K), dtype=bool)
    task = np.full((L, K), -1, dtype=np.int8)
    steps = np.zeros((L, K), dtype=np.int32)
    tracked = np.zeros((L, K), dtype=np.int32)
    collided = np.zeros((L, K), dtype=bool)
    docked = np.zeros((L, K), dtype=bool)
    dry = np.zeros((L, K), dtype=bool)
    payoff = np.zeros((L, K))
    epoch_of = np.full((L, K), -1, dtype=np.int64)
    fired = np.zeros((L, K), dtype=np.uint64)
    # Epoch records keyed by epoch id; ids are handed out as epochs open (at most L*K of them).
    e_lane = np.zeros(L * K, dtype=np.int64)
    e_tr = np.zeros(L * K, dtype=np.int64)
    e_pen = np.zeros(L * K, dtype=np.int64)
    e_eps = np.zeros(L * K, dtype=np.int64)
    e_cmp = np.zeros(L * K, dtype=bool)

    trace = None
    if learner is not None:
        S = schema(learner).n_sensors
        shape = (K, L) if learner == Behaviour.EXECUTIVE else (K, T, L)
        trace = Trace(np.zeros(shape + (S,), np.uint8), np.full(shape, -1, np.int16), np.zeros(shape, bool))

    if record is not None:
        record.open(L, K, T)
    alive = np.ones(L, dtype=bool)
    world.reset(np.arange(L), starts=starts[:, 0][slot])
    ep_tracked = np.zeros(L, dtype=np.int64)
    ep_count = np.zeros(L, dtype=np.int64)
    ep_id = np.arange(L)
    n_epochs = L

    for k in range(K):
        live = np.flatnonzero(alive)
        if live.size == 0:
            break
        if tick is not None:
            tick()
        # The Executive picks this episode's task.
        if isinstance(executive, Trivial):
            task[live, k] = executive.task
            if record is not None:
                record.decision(k, live, task[live, k], None)
        else:
            sch = executive.compiled.schema
            bins = sch.discretise(world.observe(sch.sensor_names))[live]
            pol = executive.lane_policy[live]
            rank, full = executive.compiled.decide(pol, bins, conflict=conflict, rng=rng)
            task[live, k] = executive.compiled.action_values(pol, rank)[:, 0]
            if record is not None or learner == Behaviour.EXECUTIVE:
                rule = executive.compiled.rule_index(pol, rank)
            if record is not None:
                record.decision(k, live, task[live, k], rule)
            if learner == Behaviour.EXECUTIVE:
                trace.bins[k, live], trace.rule[k, live], trace.full[k, live] = bins, rule, full
                fired[live, k] |= _ONE << rule.astype(np.uint64)
        lane_task = task[:, k].astype(np.int64)
        for role, beh, ctrl in roles:
            if ctrl is None and (lane_task[live] == role).any():
                raise ConfigError(f"the Executive picked {beh} but no {beh} policy was given")
        played[live, k] = True
        epoch_of[live, k] = ep_id[live]
        min_steps = np.zeros(L)
        dock_lanes = live[lane_task[live] == TASK_DOCK]
        min_steps[dock_lanes] = world.min_dock_steps(dock_lanes)
        # Which controllers run, on which lanes (all lanes at once when one controller has them all).
        groups = []
        for role, beh, ctrl in roles:
            lanes = np.flatnonzero(lane_task == role)
            if lanes.size:
                sel = None if lanes.size == L else lanes
                groups.append((beh, ctrl, sel, ctrl.lane_policy if sel is None else ctrl.lane_policy[sel]))
        names = tuple(dict.fromkeys(n for beh, *_ in groups for n in schema(beh).sensor_names))

        active = alive.copy()
        if record is not None:
            record.state(world, k, 0, live)
        turn = np.zeros(L)
        speed = np.zeros(L)
        for t in range(T):
            if not active.any():
                break
            obs = world.observe(names)
            for beh, ctrl, sel, pol in groups:
                bins = ctrl.compiled.schema.discretise(obs)
                if sel is not None:
                    bins = bins[sel]
                rank, full = ctrl.compiled.decide(pol, bins, conflict=conflict, rng=rng)
                act = ctrl.compiled.action_values(pol, rank)
                where = slice(None) if sel is None else sel
                turn[where] = _TURN[act[:, 0]]
                speed[where] = _SPEED[act[:, 1]]
                if record is None and learner is not beh:
                    continue
                lanes = np.arange(L) if sel is None else sel
                mine = active[lanes]
                lanes, rule = lanes[mine], ctrl.compiled.rule_index(pol[mine], rank[mine])
                if record is not None:
                    record.fired(k, t, lanes, rule)
                if learner is beh:
                    bins, full = bins[mine], full[mine]
                    trace.bins[k, t, lanes], trace.rule[k, t, lanes], trace.full[k, t, lanes] = bins, rule, full
                    fired[lanes, k] |= _ONE << rule.astype(np.uint64)
            noise = rng.normal(0.0, cfg.target_turn_sd, g)[slot]
            ev = world.step(active, turn, speed, noise)
            steps[:, k] += active
            tracked[:, k] += ev.tracking
            collided[:, k] |= ev.collided
            docked[:, k] |= ev.docked
            dry[:, k] |= ev.dry
            if record is not None:
                record.state(world, k, t + 1, active)
            active &= ~(ev.collided | ev.docked | ev.dry)

        # Episode payoffs (report Appendix A §6.1).
        lk = live
        track_pay = np.where(collided[lk, k], 0.0, tracked[lk, k] / T)
        ratio = np.minimum(1.0, min_steps[lk] / np.maximum(steps[lk, k], 1))
        dock_pay = np.where(docked[lk, k], 0.5 + 0.5 * ratio, 0.0)
        payoff[lk, k] = np.where(lane_task[lk] == TASK_DOCK, dock_pay, track_pay)

        # Epoch bookkeeping.
        ep_tracked[lk] += tracked[lk, k]
        ep_count[lk] += 1
        ends = collided[lk, k] | dry[lk, k] | (ep_count[lk] >= cfg.epoch_episodes)
        last = k == K - 1
        closing = lk[ends | last]
        ids = ep_id[closing]
        e_lane[ids] = closing
        e_tr[ids] = ep_tracked[closing]
        e_pen[ids] = np.where(dry[closing, k], cfg.towing_penalty, 0)
        e_eps[ids] = ep_count[closing]
        e_cmp[ids] = ends[ends | last]
        ended = lk[ends]
        world.place_at_dock(lk[docked[lk, k] & ~ends])
        if restart_epochs and not last:
            epoch_no[ended] += 1
            world.reset(ended, starts=starts[slot[ended], epoch_no[ended]])
            ep_tracked[ended] = 0
            ep_count[ended] = 0
            ep_id[ended] = n_epochs + np.arange(ended.size)
            n_epochs += ended.size
        else:
            alive[ended] = False

    e_lane, e_tr, e_pen, e_eps, e_cmp = (a[:n_epochs] for a in (e_lane, e_tr, e_pen, e_eps, e_cmp))
    e_pay = e_tr / (T * cfg.epoch_episodes + e_pen)
    return Outcome(
        played=played, task=task, steps=steps, tracked=tracked, collided=collided, docked=docked, dry=dry,
        payoff=payoff, epoch_of=epoch_of, fired=fired, epoch_lane=e_lane, epoch_tracked=e_tr,
        epoch_penalty=e_pen, epoch_episodes=e_eps, epoch_complete=e_cmp, epoch_payoff=e_pay, trace=trace,
    )
