"""Pictures of door trials: the counterparts of the report's Figures 4 and 5 (Appendix B §8.2).

A figure has two panels, like the report's: (a) the robot during the run, with its
path so far and its seven sonar beams (a failed sonar drawn red at its reading of 0),
and (b) the robot at the end of the trial with its whole path.  The trial shown is
the first of ``candidates`` fresh trials that reached the goal *(ours)*, so the
picture shows how the rules succeed; if none did, or with ``prefer_success=False``
(how rules fail, e.g. right after a sonar failure), the first trial.

``coevo show`` draws door trials as a task-agnostic :class:`~coevo.scene.Scene` instead
(:func:`play_trials`, :func:`scene_of`): the room, each trial's wall faint and its opening's two
posts solid in that trial's colour (its path's: a path crosses between its own trial's posts, and the
walls of the other trials, which were not there, show through), the goal and starting lines, the robot's path
at every substep, the sonars at the last trial's start (failed ones as red stubs) and how each trial
ended.  Both reach the commands through :class:`DoorDisplay` (``DoorTask.display()``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from coevo.errors import ConfigError
from coevo.ga.evaluator import Partners
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.scene.scene import Event, Scene, Shape, Span, Track
from coevo.tasks.door.evaluate import play
from coevo.tasks.door.sensors import DOOR
from coevo.tasks.door.settings import SONAR_ANGLES, SONARS, DoorConfig, capability_label
from coevo.tasks.door.world import COLLISION, GOAL, TIMEOUT, DoorWorld, Trials, draw_trials
from coevo.tasks.showing import RuleTable, TaskDisplay, rule_rows, run_lengths

__all__ = ["DoorDisplay", "trial_path", "path_figure", "DoorRobot", "DoorPlay", "door_robot", "play_trials", "scene_of",
           "rule_tables", "trace_lines"]

_OUTCOME = {1: "reached the goal", 2: "collided", 3: "ran out of time"}


def trial_path(rules: RuleSet, cfg: DoorConfig, *, seed: int, candidates: int = 20, prefer_success: bool = True
               ) -> tuple[Trials, np.ndarray, int]:
    """(the trial, its poses ``(k, 3)`` at every substep, its outcome) of the trial to show."""
    rng = np.random.default_rng(seed)
    trials = draw_trials(cfg, candidates, rng)
    out = play(cfg, CompiledPolicies([rules]), np.zeros(candidates, dtype=np.int64), trials, rng, record=True)
    won = np.flatnonzero(out.outcome == GOAL)
    i = int(won[0]) if won.size and prefer_success else 0
    steps = int(round(out.time[i] / cfg.decision_seconds * cfg.substeps))
    poses = np.stack([p[i] for p in out.world.path])[: steps + 1]  # type: ignore[union-attr]
    one = Trials(trials.x[i:i + 1], trials.heading[i:i + 1], trials.opening[i:i + 1])
    return one, poses, int(out.outcome[i])


def _room(ax: object, cfg: DoorConfig, opening: float) -> None:
    from matplotlib.patches import Rectangle

    W, D = cfg.room_width, cfg.room_depth
    ax.add_patch(Rectangle((0, 0), W, D, fill=False, lw=2, ec="black"))  # type: ignore[attr-defined]
    for x0, x1 in ((0.0, opening), (opening + cfg.opening, W)):
        if x1 > x0:
            ax.add_patch(Rectangle((x0, cfg.wall_near), x1 - x0, cfg.wall_thickness, color="0.35"))  # type: ignore[attr-defined]
    ax.axhline(cfg.goal_line, color="tab:green", ls="--", lw=1)  # type: ignore[attr-defined]
    ax.axhline(cfg.start_line, color="0.6", ls=":", lw=1)  # type: ignore[attr-defined]
    ax.set_xlim(-5, W + 5)  # type: ignore[attr-defined]
    ax.set_ylim(-5, D + 5)  # type: ignore[attr-defined]
    ax.set_aspect("equal")  # type: ignore[attr-defined]
    ax.set_xticks([])  # type: ignore[attr-defined]
    ax.set_yticks([])  # type: ignore[attr-defined]


def _robot(ax: object, cfg: DoorConfig, trial: Trials, pose: np.ndarray, *, beams: bool) -> None:
    from matplotlib.patches import Circle

    x, y, h = pose
    ax.add_patch(Circle((x, y), cfg.robot_radius, fc="tab:blue", ec="black", alpha=0.8, zorder=3))  # type: ignore[attr-defined]
    hr = np.deg2rad(h)
    ax.plot([x, x - 1.4 * cfg.robot_radius * np.sin(hr)], [y, y + 1.4 * cfg.robot_radius * np.cos(hr)],  # type: ignore[attr-defined]
            color="black", lw=1.5, zorder=4)
    if not beams:
        return
    world = DoorWorld(cfg, Trials(np.array([x]), np.array([h]), trial.opening))
    world.y[:] = y
    reading = world.sonars(np.array([0]))[0]
    for name, angle, r in zip(SONARS, SONAR_ANGLES, reading):
        a = hr + np.deg2rad(angle)
        failed = name in cfg.failed
        d = cfg.robot_radius * (2.5 if failed else 1.0) + r  # a failed sonar reads 0: a red stub shows it
        ax.plot([x, x - d * np.sin(a)], [y, y + d * np.cos(a)], color="tab:red" if failed else "tab:orange",  # type: ignore[attr-defined]
                lw=2.5 if failed else 1, alpha=0.9, zorder=2)


def path_figure(path: Path, rules: RuleSet, cfg: DoorConfig, *, seed: int, title: str, candidates: int = 20,
                prefer_success: bool = True) -> int:
    """Draw a trial of ``rules`` into ``path`` (PNG); returns the trial's outcome."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trial, poses, outcome = trial_path(rules, cfg, seed=seed, candidates=candidates, prefer_success=prefer_success)
    mid = len(poses) // 2
    fig, axes = plt.subplots(1, 2, figsize=(9, 5))
    for ax, upto, label in ((axes[0], mid, "a) during the run"), (axes[1], len(poses) - 1, f"b) {_OUTCOME[outcome]}")):
        _room(ax, cfg, float(trial.opening[0]))
        ax.plot(poses[: upto + 1, 0], poses[: upto + 1, 1], color="tab:blue", lw=1.2)
        _robot(ax, cfg, trial, poses[upto], beams=upto == mid)
        ax.set_title(label, fontsize=10)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return outcome


# ------------------------------------------------------------------ coevo show
_ENDING = {GOAL: "reached goal", COLLISION: "collided", TIMEOUT: "ran out of time"}
#: A trial's path and wall: none orange (a working sonar), red (a failed one, a collision) or green (the goal)
TRIAL_COLOURS = ("tab:blue", "tab:purple", "tab:brown", "tab:cyan", "tab:pink", "tab:olive", "tab:gray", "navy")
WALL_FILL = 0.25  # a trial's wall: its colour this opaque, so the walls of all trials read through one another


@dataclass(frozen=True)
class DoorRobot:
    """Door rules to show, in the world (sonars failed or not) they play in."""

    name: str
    world: DoorConfig
    rules: RuleSet


@dataclass(frozen=True)
class DoorPlay:
    """``episodes`` recorded trials: per trial its poses at every substep ``(k, 3)`` and the rules it fired
    per decision (0-based, in order)."""

    robot: DoorRobot
    seed: int
    trials: Trials
    poses: tuple[np.ndarray, ...]
    fired: tuple[np.ndarray, ...]
    outcome: np.ndarray
    time: np.ndarray

    @property
    def episodes(self) -> int:
        return len(self.outcome)


def door_robot(name: str, world: DoorConfig, rules: Mapping[str, RuleSet]) -> DoorRobot:
    if set(rules) != {DOOR}:
        raise ConfigError(f"{name}: the door task shows one {DOOR} rule set, got {', '.join(sorted(rules)) or 'none'}")
    return DoorRobot(name, world, rules[DOOR])


def play_trials(robot: DoorRobot, *, seed: int, trials: int) -> DoorPlay:
    """Play ``trials`` fresh trials drawn from ``seed``, recording every substep's pose."""
    cfg = robot.world
    rng = np.random.default_rng(seed)
    drawn = draw_trials(cfg, trials, rng)
    out = play(cfg, CompiledPolicies([robot.rules]), np.zeros(trials, dtype=np.int64), drawn, rng, record=True)
    path = np.stack(out.world.path)  # type: ignore[arg-type]  # (substeps + 1, trials, 3)
    poses, fired = [], []
    for i in range(trials):
        steps = int(round(out.time[i] / cfg.decision_seconds * cfg.substeps))
        poses.append(path[: steps + 1, i].copy())
        fired.append(out.rule[out.lane == i])
    return DoorPlay(robot, seed, drawn, tuple(poses), tuple(fired), out.outcome.copy(), out.time.copy())


def _box(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def _beams(cfg: DoorConfig, trials: Trials, k: int) -> list[Shape]:
    """The sonars of trial ``k``'s start: working ones to their echo, failed ones as red stubs (they read 0)."""
    x, h = float(trials.x[k]), float(trials.heading[k])
    world = DoorWorld(cfg, Trials(np.array([x]), np.array([h]), trials.opening[k:k + 1]), rng=np.random.default_rng(0))
    reading = world.sonars(np.array([0]))[0]
    y = cfg.start_line
    out = []
    for name, angle, r in zip(SONARS, SONAR_ANGLES, reading, strict=True):
        a = np.deg2rad(h + angle)
        failed = name in cfg.failed
        d = cfg.robot_radius * (2.5 if failed else 1.0) + float(r)
        out.append(Shape("polyline", np.array([[x, y], [x - d * np.sin(a), y + d * np.cos(a)]]),
                         "failed beam" if failed else "beam", name))
    return out


def scene_of(played: DoorPlay, *, title: str | None = None) -> Scene:
    """The trials of a recorded play, one after the other on the frame axis."""
    cfg, K = played.robot.world, played.episodes
    W, D = cfg.room_width, cfg.room_depth
    statics = [Shape("polygon", _box(0, W, 0, D), "wall")]
    post = max(3 * cfg.wall_thickness, 0.04 * D)  # how far a door post stands out of the wall, each side
    for k in range(K):  # each trial's wall faint and its opening's posts solid, in its path's colour
        a = float(played.trials.opening[k])
        for x0, x1 in ((0.0, a), (a + cfg.opening, W)):
            if x1 > x0:
                statics.append(Shape("polygon", _box(x0, x1, cfg.wall_near, cfg.wall_far), "wall piece",
                                     alpha=WALL_FILL, category=k))
        for x in (a, a + cfg.opening):
            statics.append(Shape("polyline", np.array([[x, cfg.wall_near - post], [x, cfg.wall_far + post]]),
                                 "door post", category=k))
    statics.append(Shape("polyline", np.array([[0, cfg.goal_line], [W, cfg.goal_line]], float), "goal"))
    statics.append(Shape("polyline", np.array([[0, cfg.start_line], [W, cfg.start_line]], float), "mark"))
    if K:
        statics += _beams(cfg, played.trials, K - 1)
    xy, heading, rule, captions, spans, events = [], [], [], [], [], []
    first = 0
    for k, (poses, fired) in enumerate(zip(played.poses, played.fired, strict=True)):
        n = len(poses)
        last = first + n - 1
        xy.append(poses[:, :2])
        heading.append(np.deg2rad(poses[:, 2]) + np.pi / 2)  # the renderer's angle is from +x; the door's from +y
        decision = np.minimum(np.arange(n) // cfg.substeps, max(len(fired) - 1, 0))
        r = np.where(np.arange(n) < n - 1, fired[decision] + 1 if len(fired) else 0, 0)
        rule.append(r)
        ending = _ENDING[int(played.outcome[k])]
        t = float(played.time[k])
        spans.append(Span(first, last, k, f"{k + 1:>2}. {ending}: {t:.0f} s, {len(fired)} decisions"))
        events.append(Event(first, float(poses[0, 0]), float(poses[0, 1]), "start", str(k + 1)))
        events.append(Event(last, float(poses[-1, 0]), float(poses[-1, 1]), ending, str(k + 1)))
        captions += [f"trial {k + 1} at {j * cfg.decision_seconds / cfg.substeps:.1f} s"
                     + (f" rule R{r[j]}" if r[j] else "") for j in range(n)]
        first = last + 1
    won = int((played.outcome == GOAL).sum())
    return Scene(
        title=title or (f"{played.robot.name}: {K} door trial{'s' if K != 1 else ''}, seed {played.seed}, "
                        f"{capability_label(cfg)}; {won} reached the goal"),
        extent=(0.0, W, 0.0, D),
        statics=tuple(statics),
        categories=tuple(f"trial {k + 1}" for k in range(K)),
        tracks=(Track("robot", np.concatenate(xy) if xy else np.zeros((0, 2)),
                      np.concatenate(heading) if heading else np.zeros(0),
                      np.repeat(np.arange(K), [len(p) for p in played.poses]).astype(np.int64), cfg.robot_radius),),
        rings=(), events=tuple(events), spans=tuple(spans), captions=tuple(captions),
        rule=np.concatenate(rule).astype(np.int64) if rule else None, rule_label="rule fired (R: door)",
        colours=TRIAL_COLOURS,
    )


def rule_tables(played: DoorPlay) -> list[RuleTable]:
    rs = played.robot.rules
    counts = np.bincount(np.concatenate(played.fired).astype(np.int64), minlength=len(rs))[: len(rs)] \
        if played.fired else np.zeros(len(rs), np.int64)
    title = f"{DOOR}: {len(rs)} rules by strength; fired = decisions it made in {played.episodes} trials"
    return [RuleTable(title, "R", tuple(rule_rows(rs, counts)))]


def trace_lines(played: DoorPlay) -> list[str]:
    return [f"trial {k + 1}: {run_lengths(f, 'R')} -> {_ENDING[int(o)]}"
            for k, (f, o) in enumerate(zip(played.fired, played.outcome, strict=True))]


#: Trials ``coevo show`` plays unless told: one, like the report's figures (each trial has its own opening).
SHOW_TRIALS = 1


class DoorDisplay(TaskDisplay[DoorConfig]):
    """The door task's pictures: ``DoorTask.display()``."""

    def picture(self, path: Path, behaviour: str, best: RuleSet, *, world: DoorConfig, partners: Partners, seed: int,
                name: str) -> None:
        """best.png: a trial of the best rules, during the run and at its end (the report's Figures 4-5)."""
        path_figure(path, best, world, seed=seed,
                    title=f"{name}: the best door rules ({capability_label(world)}), seed {seed}")

    def show_robot(self, name: str, world: DoorConfig, rules: Mapping[str, RuleSet]) -> DoorRobot:
        return door_robot(name, world, rules)

    def show_episodes(self, robot: DoorRobot) -> int | None:
        return SHOW_TRIALS

    def show_play(self, robot: DoorRobot, *, seed: int, episodes: int | None) -> DoorPlay:
        """``episodes`` trials (None, one epoch: :data:`SHOW_TRIALS`; the door task has no epochs)."""
        return play_trials(robot, seed=seed, trials=episodes or SHOW_TRIALS)

    def show_scene(self, played: DoorPlay, *, title: str | None = None) -> Scene:
        return scene_of(played, title=title)

    def show_rules(self, played: DoorPlay) -> list[RuleTable]:
        return rule_tables(played)

    def show_trace(self, played: DoorPlay) -> list[str]:
        return trace_lines(played)
