"""The corridor: the smallest task, for tests that the core names no task.

A walker stands in a corridor of ``length`` cells and must reach the last one
within ``steps`` steps; it senses its cell and sets ``move`` to -1, 0 or +1.  Its
payoff is 0 if it does not arrive, else ``1 - steps used / (steps + 1)``; its
measure ``arrived`` is the share of episodes that reach the end.  Every episode
starts on a random cell before the last.  Many lanes play at once on numpy arrays.

Its display (:class:`CorridorDisplay`, the smallest :class:`~coevo.tasks.showing.TaskDisplay`): ``coevo
show`` plays a walker episode by episode (:func:`play_walker`) and draws the corridor's cells with
each episode's walk on a row of its own (:func:`corridor_scene`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from pydantic import Field

from coevo.config import GAConfig, Settings
from coevo.errors import ConfigError
from coevo.ga.operators import Experience
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.policy.schema import Action, Schema, Sensor, register
from coevo.tasks.base import ChildRng, Evaluation, Evaluator, Partners, Task, Tick, check_behaviour
from coevo.tasks.showing import RuleTable, TaskDisplay, rule_rows, run_lengths

if TYPE_CHECKING:
    from coevo.scene import Scene

__all__ = ["CorridorTask", "CorridorDisplay", "CorridorConfig", "CORRIDOR"]

CORRIDOR = "corridor"
_MAX_CELLS = 16  # the cell sensor's bins: the longest corridor


class CorridorConfig(Settings):
    length: int = Field(12, ge=2, le=_MAX_CELLS, description="cells in the corridor")
    steps: int = Field(24, ge=1, le=10_000, description="steps an episode may take")


_MOVE = Action("move", (-1, 0, 1))
register(Schema(CORRIDOR, (Sensor("cell", 1.0, _MAX_CELLS, False, "cells"),), (_MOVE,)))


class CorridorEvaluator(Evaluator):
    def __init__(self, world: CorridorConfig, ga: GAConfig) -> None:
        self.behaviour = CORRIDOR
        self.world, self.ga = world, ga

    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        per = episodes or self.ga.episodes
        P, T, goal = len(policies), self.world.steps, self.world.length - 1
        L = P * per
        compiled = CompiledPolicies(policies)
        lane_policy = np.repeat(np.arange(P), per)
        pos = np.tile(rng.integers(0, goal, per), P)  # common random starts for every individual
        used = np.full(L, T)
        active = np.ones(L, dtype=bool)
        fired = np.zeros(L, dtype=np.uint64)
        log_bins, log_rule, log_full, log_lane = [], [], [], []
        moves = np.array(_MOVE.values, dtype=np.int64)
        for t in range(T):
            lanes = np.flatnonzero(active)
            if lanes.size == 0:
                break
            if tick is not None:
                tick()
            bins = pos[lanes].astype(np.uint8)[:, None]
            rank, full = compiled.decide(lane_policy[lanes], bins, conflict=self.ga.conflict, rng=rng)
            rule = compiled.rule_index(lane_policy[lanes], rank)
            fired[lanes] |= np.uint64(1) << rule.astype(np.uint64)
            log_bins.append(bins)
            log_rule.append(rule)
            log_full.append(full)
            log_lane.append(lanes)
            pos[lanes] = np.clip(pos[lanes] + moves[compiled.action_values(lane_policy[lanes], rank)[:, 0]], 0, goal)
            arrived = lanes[pos[lanes] == goal]
            used[arrived] = t + 1
            active[arrived] = False
        reached = ~active
        payoff = np.where(reached, 1.0 - used / (T + 1), 0.0)
        bins, rule = np.concatenate(log_bins), np.concatenate(log_rule).astype(np.int64)
        full, lane = np.concatenate(log_full), np.concatenate(log_lane)
        exps = []
        for i in range(P):
            mine = (lane >= i * per) & (lane < (i + 1) * per)
            exps.append(Experience(fired[i * per:(i + 1) * per], payoff[i * per:(i + 1) * per], bins[mine], rule[mine],
                                   full[mine], lane[mine] - i * per, self.ga.high_payoff_quantile))
        fitness = payoff.reshape(P, per).mean(axis=1)
        return Evaluation(fitness, np.full(P, per), exps, reached.reshape(P, per))

    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        return {"arrived": float(100.0 * check.details.mean())}


@dataclass(frozen=True)
class Walker:
    """A corridor rule set to show, in its corridor."""

    name: str
    world: CorridorConfig
    rules: RuleSet


@dataclass(frozen=True)
class WalkerPlay:
    """Recorded episodes: per episode the cell at every step (start included) and the rule fired per step (0-based)."""

    robot: Walker
    seed: int
    cells: tuple[np.ndarray, ...]
    fired: tuple[np.ndarray, ...]

    @property
    def episodes(self) -> int:
        return len(self.cells)

    def arrived(self, k: int) -> bool:
        return int(self.cells[k][-1]) == self.robot.world.length - 1


def play_walker(robot: Walker, *, seed: int, episodes: int, conflict: str = "strongest") -> WalkerPlay:
    """Play ``episodes`` episodes in a row from random cells drawn from ``seed``, recording every step."""
    rng = np.random.default_rng(seed)
    compiled = CompiledPolicies([robot.rules])
    goal, moves, lane = robot.world.length - 1, np.array(_MOVE.values, dtype=np.int64), np.zeros(1, np.int64)
    cells, fired = [], []
    for _ in range(episodes):
        pos, path, rules = int(rng.integers(0, goal)), [], []
        path.append(pos)
        for _ in range(robot.world.steps):
            rank, _full = compiled.decide(lane, np.array([[pos]], dtype=np.uint8), conflict=conflict, rng=rng)
            rules.append(int(compiled.rule_index(lane, rank)[0]))
            pos = int(np.clip(pos + moves[compiled.action_values(lane, rank)[0, 0]], 0, goal))
            path.append(pos)
            if pos == goal:
                break
        cells.append(np.array(path))
        fired.append(np.array(rules, dtype=np.int64))
    return WalkerPlay(robot, seed, tuple(cells), tuple(fired))


def corridor_scene(played: WalkerPlay, *, title: str | None = None) -> Scene:
    """The corridor's cells (the last one the goal), each episode's walk on its own row."""
    from coevo.scene.scene import Event, Scene, Shape, Span, Track

    L, K = played.robot.world.length, played.episodes
    H = max(1.0, L / 4)
    box = lambda x0, x1: np.array([[x0, 0], [x1, 0], [x1, H], [x0, H]], float)  # noqa: E731
    statics = [Shape("polygon", box(0, L), "wall"), Shape("polygon", box(L - 1, L), "goal cell", "goal")]
    statics += [Shape("polyline", np.array([[x, 0], [x, H]], float), "mark") for x in range(1, L - 1)]
    xy, rule, spans, events, captions = [], [], [], [], []
    first = 0
    for k, (cells, fired) in enumerate(zip(played.cells, played.fired, strict=True)):
        y = H * (k + 1) / (K + 1)
        pts = np.column_stack([cells + 0.5, np.full(len(cells), y)])
        last = first + len(cells) - 1
        ending = "reached goal" if played.arrived(k) else "ran out of time"
        xy.append(pts)
        rule.append(np.append(fired + 1, 0))
        spans.append(Span(first, last, 0, f"{k + 1:>2}. {ending}: {len(fired)} steps from cell {int(cells[0]) + 1}"))
        (x0, y0), (x1, y1) = pts[0].tolist(), pts[-1].tolist()
        events.append(Event(first, x0, y0, "start", str(k + 1)))
        events.append(Event(last, x1, y1, ending, str(k + 1)))
        captions += [f"episode {k + 1} step {t} cell {int(c) + 1}" for t, c in enumerate(cells)]
        first = last + 1
    return Scene(
        title=title or f"{played.robot.name}: {K} corridor episode{'s' if K != 1 else ''}, seed {played.seed}, "
                       f"{sum(played.arrived(k) for k in range(K))} reached the end",
        extent=(0.0, float(L), 0.0, H), statics=tuple(statics), categories=("walk",),
        tracks=(Track("walker", np.concatenate(xy), None, np.zeros(first, np.int64), 0.2),),
        rings=(), events=tuple(events), spans=tuple(spans), captions=tuple(captions),
        rule=np.concatenate(rule), rule_label="rule fired (C: corridor)",
    )


class CorridorTask(Task[CorridorConfig]):
    name = "corridor"
    behaviours = (CORRIDOR,)
    world_settings = CorridorConfig

    def evaluator(self, behaviour: str, world: CorridorConfig, ga: GAConfig) -> CorridorEvaluator:
        check_behaviour(self, behaviour)
        return CorridorEvaluator(world, ga)

    def status_measures(self, behaviour: str, measures: Mapping[str, float | None]) -> dict[str, float]:
        return {"arrived": float(measures["arrived"] or 0.0)}

    def final_measures(self, behaviour: str, best: RuleSet, *, world: CorridorConfig, partners: Partners,
                       epochs: int, seed: int) -> dict[str, float | int]:
        ev = self.evaluator(behaviour, world, GAConfig()).evaluate([best], {}, np.random.default_rng(seed), episodes=epochs)
        return {"arrived": float(100.0 * ev.details.mean()), "payoff": float(ev.fitness[0])}

    def run_measures(self, policies: Mapping[str, RuleSet], *, world: CorridorConfig, epochs: int,
                     seed: int) -> dict[str, float | int] | None:
        best = policies.get(CORRIDOR)
        return None if best is None else self.final_measures(CORRIDOR, best, world=world, partners={}, epochs=epochs, seed=seed)

    def display(self) -> CorridorDisplay:
        return CorridorDisplay()


class CorridorDisplay(TaskDisplay[CorridorConfig]):
    """The corridor's pictures for ``coevo show``: a walker's episodes, a row each (it draws no best.png)."""

    def show_robot(self, name: str, world: CorridorConfig, rules: Mapping[str, RuleSet]) -> Walker:
        if set(rules) != {CORRIDOR}:
            raise ConfigError(f"{name}: the corridor task shows one {CORRIDOR} rule set, got {', '.join(sorted(rules)) or 'none'}")
        return Walker(name, world, rules[CORRIDOR])

    def show_play(self, robot: Walker, *, seed: int, episodes: int | None) -> WalkerPlay:
        """``episodes`` in a row (None, one epoch: one episode)."""
        return play_walker(robot, seed=seed, episodes=episodes or 1)

    def show_scene(self, played: WalkerPlay, *, title: str | None = None) -> Scene:
        return corridor_scene(played, title=title)

    def show_rules(self, played: WalkerPlay) -> list[RuleTable]:
        rs = played.robot.rules
        counts = np.bincount(np.concatenate(played.fired), minlength=len(rs))[: len(rs)]
        return [RuleTable(f"{CORRIDOR}: {len(rs)} rules by strength; fired = steps it decided in {played.episodes} "
                          "episodes", "C", tuple(rule_rows(rs, counts)))]

    def show_trace(self, played: WalkerPlay) -> list[str]:
        return [f"episode {k + 1}: {run_lengths(f, 'C')} -> {'reached the end' if played.arrived(k) else 'time up'}"
                for k, f in enumerate(played.fired)]
