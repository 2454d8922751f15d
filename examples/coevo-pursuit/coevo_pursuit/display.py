"""The pursuit task's pictures: both bodies' paths in the arena, episode after episode (``coevo show``, best.png)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from coevo.errors import ConfigError
from coevo.policy.rules import RuleSet
from coevo.scene import Scene, draw_png
from coevo.scene.scene import Event, Shape, Span, Track
from coevo.tasks.base import Partners
from coevo.tasks.showing import RuleTable, TaskDisplay, rule_rows, run_lengths

from coevo_pursuit.settings import PursuitConfig
from coevo_pursuit.world import BEHAVIOURS, EVADER, PURSUER, Played, play

__all__ = ["PursuitDisplay", "Game"]


@dataclass(frozen=True)
class Game:
    """A pursuer and an evader to show; a side the source did not give plays its hand-written rules."""

    name: str
    world: PursuitConfig
    rules: dict[str, RuleSet]
    given: tuple[str, ...]


@dataclass(frozen=True)
class GamePlay:
    robot: Game
    seed: int
    played: Played

    @property
    def episodes(self) -> int:
        return len(self.played.captured)


def _broken_at_wraps(xy: np.ndarray, arena: float) -> np.ndarray:
    """A path on the torus with the frame after each wrap-around left out (NaN), so no line crosses the arena."""
    out = xy.copy()
    jump = np.flatnonzero(np.abs(np.diff(xy, axis=0)).max(axis=1) > arena / 2) + 1
    out[jump] = np.nan
    return out


class PursuitDisplay(TaskDisplay[PursuitConfig]):
    def show_robot(self, name: str, world: PursuitConfig, rules: Mapping[str, RuleSet]) -> Game:
        from coevo_pursuit import hand_written

        unknown = sorted(set(rules) - set(BEHAVIOURS))
        if unknown or not rules:
            raise ConfigError(f"{name}: the pursuit task shows pursuer and evader rule sets, got "
                              f"{', '.join(sorted(rules)) or 'none'}")
        return Game(name, world, {b: rules.get(b) or hand_written(b) for b in BEHAVIOURS}, tuple(sorted(rules)))

    def show_play(self, robot: Game, *, seed: int, episodes: int | None) -> GamePlay:
        """``episodes`` games from ``seed`` (None, one epoch: three)."""
        played = play([robot.rules[PURSUER]], PURSUER, robot.rules[EVADER], robot.world, np.random.default_rng(seed),
                      episodes=episodes or 3, record=True)
        return GamePlay(robot, seed, played)

    def show_scene(self, played: GamePlay, *, title: str | None = None) -> Scene:
        p, world = played.played, played.robot.world
        A = world.arena
        statics = (Shape("polyline", np.array([[0, 0], [A, 0], [A, A], [0, A], [0, 0]], float), "mark"),)  # no wall: the arena wraps
        xy: dict[str, list[np.ndarray]] = {b: [] for b in BEHAVIOURS}
        rule, spans, events, captions = [], [], [], []
        first = 0
        for k in range(played.episodes):
            n = int(p.ended[k])
            ending = f"captured at step {n}" if p.captured[k] else f"escaped for {n} steps"
            for b in BEHAVIOURS:
                xy[b].append(p.paths[b][: n + 1, k])  # type: ignore[index]
            rule.append(np.append(p.rules[PURSUER][:n, k] + 1, 0))  # type: ignore[index]
            last = first + n
            spans.append(Span(first, last, 0 if p.captured[k] else 1, f"{k + 1:>2}. {ending}"))
            (x0, y0), (x1, y1) = p.paths[EVADER][0, k], p.paths[EVADER][n, k]  # type: ignore[index]
            events += [Event(first, float(x0), float(y0), "start", str(k + 1)),
                       Event(last, float(x1), float(y1), "captured" if p.captured[k] else "escaped", str(k + 1))]
            captions += [f"game {k + 1} step {t}" for t in range(n + 1)]
            first = last + 1
        caught = int(p.captured.sum())
        return Scene(
            title=title or f"{played.robot.name}: {played.episodes} games, seed {played.seed}, {caught} captured",
            extent=(0.0, A, 0.0, A), statics=statics, categories=("captured", "escaped"),
            tracks=tuple(Track(b, _broken_at_wraps(np.concatenate(xy[b]), A), None, None, world.capture / 2)
                         for b in BEHAVIOURS),
            rings=(), events=tuple(events), spans=tuple(spans), captions=tuple(captions),
            rule=np.concatenate(rule), rule_label="pursuer's rule fired", colours=("tab:red", "tab:green"))

    def show_rules(self, played: GamePlay) -> list[RuleTable]:
        tables = []
        for b in BEHAVIOURS:
            rs = played.robot.rules[b]
            fired = played.played.rules[b]  # type: ignore[index]
            counts = np.bincount(fired[fired >= 0], minlength=len(rs))[: len(rs)]
            whose = "" if b in played.robot.given else " (hand-written)"
            tables.append(RuleTable(f"{b}{whose}: {len(rs)} rules by strength; fired = steps it decided in "
                                    f"{played.episodes} games", b[0].upper(), tuple(rule_rows(rs, counts))))
        return tables

    def show_trace(self, played: GamePlay) -> list[str]:
        p = played.played
        return [f"game {k + 1}: pursuer {run_lengths(p.rules[PURSUER][: int(p.ended[k]), k], 'P')} -> "  # type: ignore[index]
                f"{'captured' if p.captured[k] else 'escaped'}" for k in range(played.episodes)]

    def picture(self, path: Path, behaviour: str, best: RuleSet, *, world: PursuitConfig, partners: Partners, seed: int,
                name: str) -> None:
        robot = self.show_robot(name, world, {behaviour: best, **partners})
        draw_png(self.show_scene(self.show_play(robot, seed=seed, episodes=3)), path)
