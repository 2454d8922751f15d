"""A TD baseline on our own tasks (docs/ea-vs-td.md): Q-learning on Tracking, Docking and the door task.

The learner sees what the GA's rules see: the task's discretised sensors (its rule schema's bins) and
its joint actions (turn x speed: 13 x 6 = 78 on the fuel task, 7 x 8 = 56 on the door). It is paid what
the GA is paid: the task's own payoff, given at the episode's end (``sparse``); Tracking also has a
``shaped`` variant, +1/T for every step in range, with the episode's return kept equal to its payoff
(a collision takes back what the episode had earned, as the payoff's 0 on collision does).

**Why the table stays tractable** *(ours)*. A dense table over the schemas' bins would have
4.0e7 (Tracking), 6.4e12 (Docking) and 1.1e9 (door) observations, times 56-78 actions. Two things
keep it small:

* the table is *hashed*: a row exists only for an observation some robot has met (a dict from the
  observation's code to a row, rows allocated on first visit), so its size is bounded by the
  experience, not the product of the bins; and
* the observation is an :class:`Encoder`: the sensors that matter for the behaviour, each the
  schema's bins merged ``k`` at a time (e.g. Tracking's Target bearing in 30 degree sectors, the
  schema's 5 degree bins six at a time). The ``full`` encoders keep every sensor at the schema's
  bins; they are there to measure how the table grows without the reduction.

**Many worlds, one table.** Each independent run (a seed) is one table fed by ``lanes`` worlds at
once (Gymnasium's vector environment); several runs share one batched world. :mod:`.qlearning`'s
learner keeps a dense table per lane over synchronised episodes, which fits neither. When several
lanes update the same (observation, action) in one step, the update is the one that ``k``
sequential updates toward the targets' mean would make: ``Q += (1 - (1 - alpha)**k) * (mean - Q)``
(exact when the targets are equal; with ``alpha = 1/n`` it is the running mean, exactly).

**Experience** is counted in robot-steps, one per robot per decision, on both sides: the TD learner's
lanes as they step, the GA's evaluations from what they played (the fuel task's ``Outcome.steps``,
the door's decision log), its best's re-evaluation included (:class:`CountingEvaluator`).
Measurements on fresh trials are not experience for either.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from coevo.errors import ConfigError
from coevo.experiments.earl.qlearning import QConfig
from coevo.policy.schema import Schema, schema

__all__ = [
    "Encoder", "ENCODERS", "HashedQ", "FuelEnv", "DoorEnv", "TASKS", "TDSpec", "Curve",
    "CountingEvaluator", "VARIANTS", "run_td", "run_ga", "run_task", "variant_specs", "checkpoint_marks", "task_results", "default_checkpoints", "measure_policy", "rules_policy",
]

TASKS = ("tracking", "docking", "door")
REWARDS = ("sparse", "shaped")
PRIORS = ("none", "default")
#: Extra TD runs beside the main one, by name: the settings each changes.
VARIANTS: dict[str, dict[str, str]] = {"shaped": {"reward": "shaped"}, "default-rules": {"prior": "default"}}
#: A policy for measurement: (sensor bins (m, S), lane ids (m,), rng) -> joint action indices (m,).
Policy = Callable[[np.ndarray, np.ndarray, np.random.Generator], np.ndarray]
Progress = Callable[[str, int, int], None]


def _quiet(stage: str, done: int, total: int) -> None:
    return None


# ----------------------------------------------------------------------------- observations

@dataclass(frozen=True)
class Encoder:
    """The learner's observation: some of a schema's sensors, each with ``k`` of its bins merged into one.

    ``code`` packs the merged bins into one integer (mixed radix), the key of the hashed table.
    """

    behaviour: str
    keep: tuple[tuple[str, int], ...]
    name: str = "custom"

    def __post_init__(self) -> None:
        sch = schema(self.behaviour)
        if not self.keep:
            raise ConfigError(f"encoder {self.name!r}: keep at least one sensor")
        for sensor, k in self.keep:
            if sch.sensor_index(sensor) is None:
                raise ConfigError(f"encoder {self.name!r}: {self.behaviour} has no sensor {sensor!r} "
                                  f"(it has {', '.join(sch.sensor_names)})")
            if isinstance(k, bool) or not isinstance(k, int) or k < 1:
                raise ConfigError(f"encoder {self.name!r}: merge factor {sensor}={k!r}: give a whole number >= 1")

    @property
    def schema(self) -> Schema:
        return schema(self.behaviour)

    @property
    def columns(self) -> np.ndarray:
        return np.array([self.schema.sensor_index(s) for s, _ in self.keep], dtype=np.int64)

    @property
    def radix(self) -> np.ndarray:
        sch = self.schema
        return np.array([-(-sch.sensors[sch.sensor_index(s)].bins // k) for s, k in self.keep], dtype=np.int64)

    @property
    def n_states(self) -> int:
        """Observations a dense table would need (a Python int: it can exceed int64)."""
        n = 1
        for r in self.radix.tolist():
            n *= r
        return n

    def code(self, bins: np.ndarray) -> np.ndarray:
        """``(n,)`` int64 codes of ``(n, S)`` schema bins."""
        merged = bins[:, self.columns].astype(np.int64) // np.array([k for _, k in self.keep], dtype=np.int64)
        out = np.zeros(len(bins), dtype=np.int64)
        for j, r in enumerate(self.radix.tolist()):
            out = out * r + merged[:, j]
        return out

    def describe(self) -> str:
        sch = self.schema
        parts = []
        for s, k in self.keep:
            sen = sch.sensors[sch.sensor_index(s)]
            parts.append(f"{s} ({-(-sen.bins // k)} bins of {sen.width * k:g} {sen.unit})")
        return ", ".join(parts)


def _full(behaviour: str) -> Encoder:
    """Every sensor at the schema's bins; for Docking its polar set (the figures in docs/td/ were measured
    before the dock-frame sensors, coevo/tasks/fuel/dock_frame.py, joined the schema)."""
    from coevo.tasks.fuel.dock_frame import FRAME_NAMES

    names = [n for n in schema(behaviour).sensor_names if behaviour != "docking" or n not in FRAME_NAMES]
    return Encoder(behaviour, tuple((s, 1) for s in names), "full")


def _encoders() -> dict[tuple[str, str], Encoder]:
    from coevo.tasks.door.sensors import DOOR

    return {
        # Tracking: where the Target is (10 in x 30 deg) and where the nearest thing is (20 in x 45 deg).
        ("tracking", "reduced"): Encoder("tracking", (("target_range", 2), ("target_bearing", 6), ("range", 4),
                                                      ("bearing", 9)), "reduced"),
        ("tracking", "full"): _full("tracking"),
        # Docking: where the dock's front is (10 in x 15 deg) and how the robot is turned to it (15 deg).
        ("docking", "reduced"): Encoder("docking", (("dock_range", 2), ("dock_bearing", 3), ("dock_orientation", 3)),
                                        "reduced"),
        ("docking", "full"): _full("docking"),
        # Door: the five forward sonars at 72 in, the goal 35 in at a time, the heading in 45 deg sectors.
        ("door", "reduced"): Encoder(DOOR, (("left", 3), ("front_left", 3), ("front", 3), ("front_right", 3),
                                            ("right", 3), ("goal_range", 7), ("heading", 2)), "reduced"),
        ("door", "full"): _full(DOOR),
    }


ENCODERS = _encoders()


# ----------------------------------------------------------------------------- the hashed Q-table

class HashedQ:
    """One Q-table per run, rows allocated for observations as they are first met; see the module docstring."""

    def __init__(self, runs: int, n_actions: int, config: QConfig, *, max_rows: int = 2_000_000) -> None:
        for name, v in (("runs", runs), ("n_actions", n_actions), ("max_rows", max_rows)):
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ConfigError(f"{name}={v!r}: give a whole number >= 1")
        self.runs, self.n_actions, self.config, self.max_rows = int(runs), int(n_actions), config, int(max_rows)
        self._index: dict[int, int] = {}
        self._run_of_row = np.zeros(1024, dtype=np.int64)
        self.q = np.full((1024, self.n_actions), float(config.initial_q))
        self.visits = np.zeros((1024, self.n_actions), dtype=np.int64)
        self.n_rows = 0
        self.overflow = 0  # observations met after the table was full (played, not learned)

    def _grow(self, need: int) -> None:
        cap = len(self.q)
        while cap < need:
            cap *= 2
        if cap != len(self.q):
            extra = cap - len(self.q)
            self.q = np.concatenate([self.q, np.full((extra, self.n_actions), float(self.config.initial_q))])
            self.visits = np.concatenate([self.visits, np.zeros((extra, self.n_actions), dtype=np.int64)])
            self._run_of_row = np.concatenate([self._run_of_row, np.zeros(extra, dtype=np.int64)])

    def rows(self, run: np.ndarray, codes: np.ndarray, *, allocate: bool = True) -> np.ndarray:
        """The row of each (run, observation code); new ones get a row (``allocate``) or -1."""
        keys = (codes * self.runs + run).tolist()
        get = self._index.get
        out = np.fromiter((get(k, -1) for k in keys), dtype=np.int64, count=len(keys))
        if allocate and (out < 0).any():
            for i in np.flatnonzero(out < 0).tolist():
                k = keys[i]
                r = self._index.get(k, -1)
                if r < 0 and self.n_rows < self.max_rows:
                    r = self.n_rows
                    self._grow(r + 1)
                    self._index[k] = r
                    self._run_of_row[r] = int(run[i])
                    self.n_rows += 1
                elif r < 0:
                    self.overflow += 1
                out[i] = r
        return out

    def act(self, rows: np.ndarray, rng: np.random.Generator, *, explore: bool = True,
            fallback: np.ndarray | None = None) -> np.ndarray:
        """Epsilon-greedy (or greedy) joint actions, ties broken at random; an unknown row (-1) acts at random,
        or, given ``fallback`` actions, rows with no preference yet (every action's value equal) take those.

        The same random numbers are drawn whatever the Q-values, so the stream does not depend on them.
        """
        qo = np.where((rows >= 0)[:, None], self.q[np.maximum(rows, 0)], self.config.initial_q)
        top = qo.max(axis=1, keepdims=True)
        ties = qo == top
        greedy = np.argmax(np.where(ties, rng.random(qo.shape), -1.0), axis=1)
        if fallback is not None:
            greedy = np.where(ties.all(axis=1), fallback, greedy)
        if not explore:
            return greedy
        random = rng.integers(0, self.n_actions, size=len(rows))
        return np.where(rng.random(len(rows)) < self.config.epsilon, random, greedy)

    def update(self, rows: np.ndarray, actions: np.ndarray, rewards: np.ndarray, next_rows: np.ndarray,
               done: np.ndarray) -> None:
        """One-step Q-learning on a batch of transitions (duplicates merged, see the module docstring)."""
        ok = rows >= 0
        rows, actions, rewards, next_rows, done = rows[ok], actions[ok], rewards[ok], next_rows[ok], done[ok]
        if rows.size == 0:
            return
        future = np.where((next_rows >= 0) & ~done, self.q[np.maximum(next_rows, 0)].max(axis=1), 0.0)
        target = rewards + self.config.gamma * future
        pair, inverse, count = np.unique(rows * self.n_actions + actions, return_inverse=True, return_counts=True)
        mean = np.bincount(inverse, weights=target, minlength=pair.size) / count
        r, a = pair // self.n_actions, pair % self.n_actions
        n_before = self.visits[r, a]
        if self.config.alpha_schedule == "1/n":
            step = count / (n_before + count)
        else:
            step = 1.0 - (1.0 - self.config.alpha) ** count
        self.q[r, a] += step * (mean - self.q[r, a])
        self.visits[r, a] = n_before + count

    def table_sizes(self) -> list[dict[str, int]]:
        """Per run: observations with a row, and (observation, action) pairs ever updated."""
        run = self._run_of_row[: self.n_rows]
        pairs = (self.visits[: self.n_rows] > 0).sum(axis=1)
        return [{"observations": int((run == r).sum()), "pairs": int(pairs[run == r].sum())} for r in range(self.runs)]


# ----------------------------------------------------------------------------- environments

class FuelEnv:
    """Tracking or Docking with the trivial Executive that always picks it, on ``n`` robots of a BatchWorld.

    It follows the epoch runner (:mod:`coevo.tasks.fuel.runner`): an epoch starts from a random
    placement with the initial fuel and lasts ``epoch_episodes`` episodes of up to T steps, ending
    early on a collision or running dry; after a docking the robot is put in front of the dock,
    tank full. ``epoch_episodes=1`` is Docking's training on fresh random starts. Each robot restarts
    a new epoch at once (``restart``) or retires after its first (a measurement).
    """

    def __init__(self, behaviour: str, n: int, rng: np.random.Generator, *, world: Any = None,
                 epoch_episodes: int | None = None, restart: bool = True, reward: str = "sparse") -> None:
        from coevo.tasks.fuel.behaviours import SPEED, TURN, Behaviour
        from coevo.tasks.fuel.settings import WorldConfig
        from coevo.tasks.fuel.world import BatchWorld

        if behaviour not in ("tracking", "docking"):
            raise ConfigError(f"behaviour={behaviour!r}: the fuel task's TD baseline has tracking or docking")
        if reward not in REWARDS:
            raise ConfigError(f"reward={reward!r}: choose one of {', '.join(REWARDS)}")
        if reward == "shaped" and behaviour != "tracking":
            raise ConfigError(f"reward='shaped' is Tracking's (+1/T per step in range); {behaviour} has only 'sparse'")
        self.behaviour = Behaviour(behaviour)
        self.cfg = world if world is not None else WorldConfig()
        self.schema = schema(self.behaviour)
        self.n = int(n)
        self.world = BatchWorld(self.cfg, self.n)
        self.epoch_episodes = int(epoch_episodes or self.cfg.epoch_episodes)
        self.restart, self.reward = restart, reward
        self._turn = np.array(TURN.values, dtype=np.float64)
        self._speed = np.array(SPEED.values, dtype=np.float64)
        self.n_actions = len(TURN.values) * len(SPEED.values)
        self.active = np.ones(self.n, dtype=bool)
        self.t = np.zeros(self.n, dtype=np.int64)
        self.tracked = np.zeros(self.n, dtype=np.int64)
        self.ep_count = np.zeros(self.n, dtype=np.int64)
        self.min_steps = np.zeros(self.n)
        self._log: dict[str, list[np.ndarray]] = {k: [] for k in ("lane", "payoff", "steps", "tracked", "collided",
                                                                  "docked", "dry")}
        self._new_epoch(np.arange(self.n), rng)

    def _new_epoch(self, lanes: np.ndarray, rng: np.random.Generator) -> None:
        self.world.reset(lanes, starts=self.world.random_starts(lanes.size, rng))
        self.ep_count[lanes] = 0
        self._new_episode(lanes)

    def _new_episode(self, lanes: np.ndarray) -> None:
        self.t[lanes] = 0
        self.tracked[lanes] = 0
        if self.behaviour == "docking":
            self.min_steps[lanes] = self.world.min_dock_steps(lanes)

    def bins(self) -> np.ndarray:
        return self.schema.discretise(self.world.observe(self.schema.sensor_names))

    def step(self, actions: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Move the active robots; returns (reward, done) per robot (0 / False for the inactive)."""
        c, act = self.cfg, self.active
        n_speed = len(self._speed)
        turn, speed = self._turn[actions // n_speed], self._speed[actions % n_speed]
        noise = rng.normal(0.0, c.target_turn_sd, self.n)
        ev = self.world.step(act, turn, speed, noise)
        self.t += act
        self.tracked += ev.tracking
        T = c.episode_steps
        done = act & (ev.collided | ev.docked | ev.dry | (self.t >= T))
        if self.behaviour == "tracking":
            payoff = np.where(ev.collided, 0.0, self.tracked / T)
        else:
            payoff = np.where(ev.docked, 0.5 + 0.5 * np.minimum(1.0, self.min_steps / np.maximum(self.t, 1)), 0.0)
        if self.reward == "shaped":
            # +1/T per step in range; a collision takes back what the episode earned (return = payoff).
            reward = np.where(ev.collided, -(self.tracked - ev.tracking) / T, ev.tracking / T)
        else:
            reward = np.where(done, payoff, 0.0)
        reward = np.where(act, reward, 0.0)
        if done.any():
            self._end_episodes(np.flatnonzero(done), payoff, ev, rng)
        return reward, done

    def _end_episodes(self, lanes: np.ndarray, payoff: np.ndarray, ev: Any, rng: np.random.Generator) -> None:
        for key, v in (("lane", lanes), ("payoff", payoff[lanes]), ("steps", self.t[lanes]),
                       ("tracked", self.tracked[lanes]), ("collided", ev.collided[lanes]),
                       ("docked", ev.docked[lanes]), ("dry", ev.dry[lanes])):
            self._log[key].append(np.array(v, copy=True))
        self.ep_count[lanes] += 1
        ends = ev.collided[lanes] | ev.dry[lanes] | (self.ep_count[lanes] >= self.epoch_episodes)
        self.world.place_at_dock(lanes[ev.docked[lanes] & ~ends])
        self._new_episode(lanes[~ends])
        if self.restart:
            self._new_epoch(lanes[ends], rng)
        else:
            self.active[lanes[ends]] = False

    def episodes(self) -> dict[str, np.ndarray]:
        """Every finished episode, in the order they ended: lane, payoff, steps, tracked, collided, docked, dry."""
        return {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in self._log.items()}


class DoorEnv:
    """Door trials on ``n`` robots; when every trial of a batch has ended, a fresh batch is drawn (``restart``).

    A :class:`~coevo.tasks.door.world.DoorWorld` counts decisions for the whole batch, so trials
    start together; a robot whose trial ended waits, inactive, for the rest (no robot-steps are spent).
    """

    def __init__(self, n: int, rng: np.random.Generator, *, world: Any = None, restart: bool = True,
                 reward: str = "sparse") -> None:
        from coevo.tasks.door.sensors import DOOR, SPEED, TURN
        from coevo.tasks.door.settings import DoorConfig

        if reward != "sparse":
            raise ConfigError(f"reward={reward!r}: the door task has only 'sparse' (its payoff at the trial's end)")
        self.cfg = world if world is not None else DoorConfig()
        self.schema = schema(DOOR)
        self.n, self.restart = int(n), restart
        self._turn = np.array(TURN.values, dtype=np.float64)
        self._speed = np.array(SPEED.values, dtype=np.float64)
        self.n_actions = len(TURN.values) * len(SPEED.values)
        self._log: dict[str, list[np.ndarray]] = {"lane": [], "payoff": [], "outcome": [], "steps": []}
        self._batch(rng)

    def _batch(self, rng: np.random.Generator) -> None:
        from coevo.tasks.door.world import DoorWorld, draw_trials

        self.world = DoorWorld(self.cfg, draw_trials(self.cfg, self.n, rng), rng=rng)
        self.active = np.ones(self.n, dtype=bool)
        self.t = np.zeros(self.n, dtype=np.int64)

    def bins(self) -> np.ndarray:
        from coevo.tasks.door.sensors import sense

        return sense(self.world, np.arange(self.n))

    def step(self, actions: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        from coevo.tasks.door.evaluate import payoff

        lanes = np.flatnonzero(self.active)
        n_speed = len(self._speed)
        a = actions[lanes]
        self.world.act(lanes, self._speed[a % n_speed], self._turn[a // n_speed])
        self.t[lanes] += 1
        done = np.zeros(self.n, dtype=bool)
        done[lanes] = self.world.outcome[lanes] != 0
        reward = np.zeros(self.n)
        ended = np.flatnonzero(done)
        if ended.size:
            pay = payoff(self.cfg, self.world.outcome[ended], self.world.time[ended])
            reward[ended] = pay
            for key, v in (("lane", ended), ("payoff", pay), ("outcome", self.world.outcome[ended]),
                           ("steps", self.t[ended])):
                self._log[key].append(np.array(v, copy=True))
            self.active[ended] = False
        if self.restart and not self.active.any():
            self._batch(rng)
        return reward, done

    def episodes(self) -> dict[str, np.ndarray]:
        return {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in self._log.items()}


def make_env(task: str, n: int, rng: np.random.Generator, *, restart: bool = True, reward: str = "sparse",
             world: Any = None) -> FuelEnv | DoorEnv:
    """The TD environment of ``task``: Tracking's epochs, Docking's fresh random starts, or door trials."""
    if task == "tracking":
        return FuelEnv("tracking", n, rng, world=world, restart=restart, reward=reward)
    if task == "docking":
        return FuelEnv("docking", n, rng, world=world, epoch_episodes=1, restart=restart, reward=reward)
    if task == "door":
        return DoorEnv(n, rng, world=world, restart=restart, reward=reward)
    raise ConfigError(f"task={task!r}: choose one of {', '.join(TASKS)}")


# ----------------------------------------------------------------------------- measures

MEASURE_NAMES = {"tracking": "quality_tracking", "docking": "docking_from_random", "door": "success"}


def measure_policy(task: str, policy: Policy, *, groups: int, trials: int, rng: np.random.Generator,
                   world: Any = None) -> np.ndarray:
    """The task's measure (in %) of ``groups`` policies at once on fresh trials, played greedily.

    Lanes ``[g*trials, (g+1)*trials)`` are group g's; ``policy`` gets the lane ids. ``trials`` is
    epochs for Tracking (Quality Tracking: % of their episodes with >= 80 % of the steps in range),
    random starts for Docking (% that dock), trials for the door (% that reach the goal).
    """
    env = make_env(task, groups * trials, rng, restart=False, world=world)
    while env.active.any():
        lanes = np.flatnonzero(env.active)
        actions = np.zeros(env.n, dtype=np.int64)
        actions[lanes] = policy(env.bins()[lanes], lanes, rng)
        env.step(actions, rng)
    ep = env.episodes()
    group = ep["lane"].astype(np.int64) // trials
    if task == "tracking":
        from coevo.tasks.fuel.measures import QUALITY_FRACTION

        hit = ep["tracked"] >= QUALITY_FRACTION * env.cfg.episode_steps
    elif task == "docking":
        hit = ep["docked"].astype(bool)
    else:
        from coevo.tasks.door.world import GOAL

        hit = ep["outcome"] == GOAL
    n = np.bincount(group, minlength=groups)
    return 100.0 * np.bincount(group, weights=hit.astype(float), minlength=groups) / np.maximum(n, 1)


def rules_policy(rulesets: list[Any], trials: int, *, conflict: str = "strongest") -> Policy:
    """A measurement policy from rule sets (group g plays ``rulesets[g]``), as the GA's rules act."""
    from coevo.policy.matcher import CompiledPolicies

    compiled = CompiledPolicies(rulesets)
    n_speed = len(compiled.schema.actions[1].values)

    def policy(bins: np.ndarray, lanes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        pol = lanes // trials
        rank, _ = compiled.decide(pol, bins, conflict=conflict, rng=rng)
        act = compiled.action_values(pol, rank)
        return act[:, 0].astype(np.int64) * n_speed + act[:, 1]

    return policy


# ----------------------------------------------------------------------------- the runs

@dataclass(frozen=True, kw_only=True)
class TDSpec:
    """One task's comparison; '(ours)' everywhere the issue leaves a number open."""

    task: str = "tracking"
    seeds: int = 3
    """Independent runs of each learner (GA seeds seed .. seed+seeds-1; the TD runs share one batched world)."""
    seed: int = 0
    generations: int = 50
    """GA generations (the report's 50); the TD budget is the GA's mean robot-steps over them."""
    population: int = 50
    episodes: int = 90
    checkpoints: tuple[int, ...] | None = None
    """GA generations at which both learners are measured (TD at the GA's mean robot-steps there);
    None: :func:`default_checkpoints` (1, 2, 5, 10, 20, ... up to ``generations``)."""
    lanes: int = 256
    """(ours) robots feeding each TD run's table at once."""
    encoder: str = "reduced"
    reward: str = "sparse"
    prior: str = "none"
    """``default``: where the table has no preference yet, act as the task's shipped default rules (the GA's
    starting point) instead of at random (ours)."""
    alpha: float = 0.1
    gamma: float = 1.0
    """1: the undiscounted episode payoff the GA maximises is the return."""
    epsilon: float = 0.1
    trials: int = 100
    """Fresh trials per measurement: epochs (Tracking; ~1,000 episodes), random starts x5 (Docking), trials x5 (door)."""
    td_steps: int | None = None
    """TD robot-steps per run; None: match the GA's."""
    max_rows: int = 2_000_000

    def __post_init__(self) -> None:
        if self.task not in TASKS:
            raise ConfigError(f"task={self.task!r}: choose one of {', '.join(TASKS)}")
        for name, low in (("seeds", 1), ("seed", 0), ("generations", 1), ("population", 2), ("episodes", 1),
                          ("lanes", 1), ("trials", 1), ("max_rows", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise ConfigError(f"{name}={v!r}: give a whole number >= {low}")
        if self.td_steps is not None and (isinstance(self.td_steps, bool) or not isinstance(self.td_steps, int)
                                          or self.td_steps < 1):
            raise ConfigError(f"td_steps={self.td_steps!r}: give a whole number >= 1 (or None to match the GA)")
        if (self.task, self.encoder) not in ENCODERS:
            raise ConfigError(f"encoder={self.encoder!r}: choose reduced or full")
        if self.reward not in REWARDS:
            raise ConfigError(f"reward={self.reward!r}: choose one of {', '.join(REWARDS)}")
        if self.prior not in PRIORS:
            raise ConfigError(f"prior={self.prior!r}: choose one of {', '.join(PRIORS)}")
        if self.reward == "shaped" and self.task != "tracking":
            raise ConfigError(f"reward='shaped' for task={self.task!r}: only Tracking has a natural shaped reward")
        if self.checkpoints is None:
            object.__setattr__(self, "checkpoints", default_checkpoints(int(self.generations)))
        object.__setattr__(self, "checkpoints", tuple(self.checkpoints))
        marks = self.checkpoints
        if (not marks or list(marks) != sorted(set(marks))
                or any(isinstance(g, bool) or not isinstance(g, int) or not 1 <= g <= self.generations for g in marks)):
            raise ConfigError(f"checkpoints={self.checkpoints!r}: give increasing generations in 1..{self.generations}")
        QConfig(alpha=self.alpha, gamma=self.gamma, epsilon=self.epsilon)  # raises on a bad one

    @property
    def q_config(self) -> QConfig:
        return QConfig(alpha=self.alpha, gamma=self.gamma, epsilon=self.epsilon)

    @property
    def measure_trials(self) -> int:
        return self.trials if self.task == "tracking" else 5 * self.trials

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["checkpoints"] = list(self.checkpoints)
        return d


@dataclass
class Curve:
    """One run of one learner: its measure (%) against its robot-steps at each checkpoint."""

    learner: str  # "ga" or "td"
    seed: int
    robot_steps: list[int] = field(default_factory=list)
    measure: list[float] = field(default_factory=list)
    seconds: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _prior(task: str, prior: str) -> Policy | None:
    """The default rules as a policy on any lanes (``prior='default'``), else None."""
    if prior == "none":
        return None
    if task == "door":
        from coevo.tasks.door import default_ruleset as door_default

        rules = door_default()
    else:
        from coevo.tasks.fuel import default_ruleset

        rules = default_ruleset(task)
    one = rules_policy([rules], 1)
    return lambda bins, lanes, rng: one(bins, np.zeros(len(bins), dtype=np.int64), rng)


def _td_policy(learner: HashedQ, encoder: Encoder, trials: int, prior: Policy | None) -> Policy:
    def policy(bins: np.ndarray, lanes: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        rows = learner.rows(lanes // trials, encoder.code(bins), allocate=False)
        fallback = None if prior is None else prior(bins, lanes, rng)
        return learner.act(rows, rng, explore=False, fallback=fallback)

    return policy


class _Distinct:
    """Distinct observation codes met per run: buffered, merged (sorted, unique) when counted."""

    def __init__(self, runs: int) -> None:
        self.known = [np.zeros(0, dtype=np.int64) for _ in range(runs)]
        self.buffer: list[tuple[np.ndarray, np.ndarray]] = []

    def add(self, run: np.ndarray, codes: np.ndarray) -> None:
        self.buffer.append((run.astype(np.int16), codes))

    def counts(self) -> list[int]:
        if self.buffer:
            run = np.concatenate([b[0] for b in self.buffer])
            codes = np.concatenate([b[1] for b in self.buffer])
            self.buffer = []
            for r in range(len(self.known)):
                self.known[r] = np.union1d(self.known[r], codes[run == r])
        return [int(k.size) for k in self.known]


def run_td(spec: TDSpec, checkpoint_steps: list[int], *, progress: Progress = _quiet) -> list[Curve]:
    """``spec.seeds`` TD runs on one batched world, measured when their robot-steps pass each checkpoint."""
    enc = ENCODERS[(spec.task, spec.encoder)]
    R, M = spec.seeds, spec.lanes
    rng = np.random.default_rng(np.random.SeedSequence([spec.seed, 19, 3]))
    measure_rng = np.random.default_rng(np.random.SeedSequence([spec.seed, 19, 4]))
    env = make_env(spec.task, R * M, rng, reward=spec.reward)
    learner = HashedQ(R, env.n_actions, spec.q_config, max_rows=spec.max_rows)
    run_of_lane = np.arange(R * M) // M
    curves = [Curve("td", spec.seed + r, extra={"table": []}) for r in range(R)]
    steps = np.zeros(R, dtype=np.int64)
    budget = checkpoint_steps[-1]
    todo = list(checkpoint_steps)
    t0 = time.perf_counter()
    full = ENCODERS[(spec.task, "full")]
    seen = _Distinct(R)  # what a table over every sensor at the schema's bins would have grown to
    bins = env.bins()
    rows = learner.rows(run_of_lane, enc.code(bins))
    prior = _prior(spec.task, spec.prior)
    lanes = np.arange(R * M)
    while todo:
        act = learner.act(rows, rng, fallback=None if prior is None else prior(bins, lanes, rng))
        was = env.active.copy()
        seen.add(run_of_lane[was], full.code(bins[was]))
        reward, done = env.step(act, rng)
        bins = env.bins()
        nxt = learner.rows(run_of_lane, enc.code(bins))
        learner.update(rows[was], act[was], reward[was], nxt[was], done[was])
        steps += np.bincount(run_of_lane[was], minlength=R)
        rows = nxt
        if steps.min() >= todo[0]:
            todo.pop(0)
            full_sizes = seen.counts()
            got = measure_policy(spec.task, _td_policy(learner, enc, spec.measure_trials, prior), groups=R,
                                 trials=spec.measure_trials, rng=measure_rng)
            sizes = learner.table_sizes()
            for r, c in enumerate(curves):
                c.robot_steps.append(int(steps[r]))
                c.measure.append(float(got[r]))
                c.extra["table"].append({**sizes[r], "full_observations": full_sizes[r]})
            progress(f"{spec.task}: TD", int(steps.min()), budget)
    seconds = time.perf_counter() - t0
    for c in curves:
        c.seconds = seconds / R  # one batched world for all runs: each run's share
        c.extra["overflow"] = learner.overflow
    return curves


class CountingEvaluator:
    """Wraps a task's evaluator and counts the robot-steps of every evaluation the GA asks for."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.behaviour = inner.behaviour
        self.robot_steps = 0

    def evaluate(self, policies: list[Any], partners: Any, rng: np.random.Generator, **kw: Any) -> Any:
        ev = self.inner.evaluate(policies, partners, rng, **kw)
        self.robot_steps += robot_steps_of(ev.details)
        return ev

    def measures(self, *args: Any, **kw: Any) -> Any:
        return self.inner.measures(*args, **kw)


def robot_steps_of(details: Any) -> int:
    """Robot-steps an evaluation played: the fuel runner's per-episode steps, or the door's decisions."""
    if hasattr(details, "steps") and hasattr(details, "played"):  # coevo.tasks.fuel.runner.Outcome
        return int(np.asarray(details.steps).sum())
    if hasattr(details, "lane") and hasattr(details, "outcome"):  # coevo.tasks.door.evaluate.Played
        return int(len(details.lane))
    raise ConfigError(f"cannot count the robot-steps of a {type(details).__name__} evaluation")


def run_ga(spec: TDSpec, seed: int, *, progress: Progress = _quiet) -> Curve:
    """The GA on the task (report settings; ``coevo learn``'s), its best so far measured at the checkpoints."""
    from coevo.config import GAConfig, build
    from coevo.ga import GA
    from coevo.tasks import get_task

    if spec.task == "door":
        from coevo.tasks.door import DoorConfig, door_ga

        task, behaviour, world = get_task("door"), "door", DoorConfig()
        ga_cfg = door_ga(generations=spec.generations, population=spec.population, episodes=spec.episodes)
    else:
        from coevo.tasks.fuel.settings import WorldConfig

        task, behaviour, world = get_task("fuel"), spec.task, WorldConfig()
        ga_cfg = build(GAConfig, generations=spec.generations, population=spec.population, episodes=spec.episodes)
    ga = GA(task, behaviour, world=world, ga=ga_cfg, seed=seed)
    counter = CountingEvaluator(ga.evaluator)
    ga.evaluator = counter
    measure_rng = np.random.default_rng(np.random.SeedSequence([seed, 19, 5]))
    curve = Curve("ga", seed, extra={"rules": []})
    learn_seconds = 0.0
    for g in range(1, spec.generations + 1):
        t0 = time.perf_counter()
        ga.generation({})
        learn_seconds += time.perf_counter() - t0
        if g in spec.checkpoints:
            trials, best = spec.measure_trials, ga.played(ga.best)
            got = measure_policy(spec.task, rules_policy([best], trials, conflict=ga_cfg.conflict), groups=1,
                                 trials=trials, rng=measure_rng)
            curve.robot_steps.append(counter.robot_steps)
            curve.measure.append(float(got[0]))
            curve.extra["rules"].append(len(best))
        progress(f"{spec.task}: GA seed {seed}", g, spec.generations)
    curve.seconds = learn_seconds
    return curve


def default_checkpoints(generations: int) -> tuple[int, ...]:
    """Generations 1, 2, 5, 10, 20, 30, ... up to and including ``generations``."""
    marks = [g for g in (1, 2, 5) if g < generations] + list(range(10, generations, 10)) + [generations]
    return tuple(sorted(set(marks)))


def variant_specs(spec: TDSpec, variants: tuple[str, ...]) -> dict[str, TDSpec]:
    """The TD spec of each extra run in ``variants`` (a ConfigError naming one the task does not have)."""
    specs = {}
    for v in variants:
        if v not in VARIANTS:
            raise ConfigError(f"variant {v!r}: choose from {', '.join(VARIANTS)}")
        specs[v] = replace(spec, **VARIANTS[v])  # raises where the task has no such setting
    return specs


def checkpoint_marks(spec: TDSpec, ga_steps: list[list[int]]) -> list[int]:
    """The TD runs' checkpoints: the GA runs' mean robot-steps at each (scaled to ``td_steps`` if given)."""
    marks = np.mean(ga_steps, axis=0)
    if spec.td_steps is not None:
        marks = marks * (spec.td_steps / marks[-1])
    return [max(1, int(round(m))) for m in marks]


def task_results(spec: TDSpec, marks: list[int], ga: list[dict[str, Any]], td: list[dict[str, Any]],
                 variants: dict[str, list[dict[str, Any]]], seconds: dict[str, float]) -> dict[str, Any]:
    """One task's results as plain data (what the report reads), from its runs' curves."""
    enc = ENCODERS[(spec.task, spec.encoder)]
    return {
        "task": spec.task, "measure": MEASURE_NAMES[spec.task], "spec": spec.as_dict(),
        "encoder": {"name": enc.name, "sensors": enc.describe(), "dense_observations": float(enc.n_states),
                    "actions": 56 if spec.task == "door" else 78},
        "checkpoint_steps": marks, "ga": ga, "td": td, "variants": variants, "seconds": seconds,
    }


def run_task(spec: TDSpec, *, variants: tuple[str, ...] = (), progress: Progress = _quiet) -> dict[str, Any]:
    """The GA's runs, then the TD runs at the GA's mean robot-steps per checkpoint, then a TD run per
    extra reward in ``variants`` (e.g. Tracking's ``shaped``); results as plain data, in this process
    (``coevo td-baseline`` runs the same pieces as replicates: :mod:`.td_replicates`)."""
    specs = variant_specs(spec, variants)
    t0 = time.perf_counter()
    ga = [run_ga(spec, spec.seed + i, progress=progress) for i in range(spec.seeds)]
    t1 = time.perf_counter()
    marks = checkpoint_marks(spec, [c.robot_steps for c in ga])
    td = run_td(spec, marks, progress=progress)
    t2 = time.perf_counter()
    extra = {v: [c.as_dict() for c in run_td(vs, marks, progress=progress)] for v, vs in specs.items()}
    t3 = time.perf_counter()
    return task_results(spec, marks, [c.as_dict() for c in ga], [c.as_dict() for c in td], extra,
                        {"ga": t1 - t0, "td": t2 - t1, "variants": t3 - t2})
