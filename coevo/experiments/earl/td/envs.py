"""The tasks as batched environments for the TD learner: Tracking and Docking (the fuel world), the door."""

from __future__ import annotations

from typing import Any

import numpy as np

from coevo.errors import ConfigError
from coevo.experiments.earl.td.spec import REWARDS, TASKS
from coevo.policy.schema import schema

__all__ = ["FuelEnv", "DoorEnv", "make_env"]


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
