"""Pictures of door trials: the counterparts of the report's Figures 4 and 5 (Appendix B §8.2).

A figure has two panels, like the report's: (a) the robot during the run, with its
path so far and its seven sonar beams (a failed sonar drawn red at its reading of 0),
and (b) the robot at the end of the trial with its whole path.  The trial shown is
the first of ``candidates`` fresh trials that reached the goal *(ours)*, so the
picture shows how the rules succeed; if none did, or with ``prefer_success=False``
(how rules fail, e.g. right after a sonar failure), the first trial.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from coevo.policy.matcher import CompiledPolicies
from coevo.policy.rules import RuleSet
from coevo.tasks.door.evaluate import play
from coevo.tasks.door.settings import SONAR_ANGLES, SONARS, DoorConfig
from coevo.tasks.door.world import GOAL, DoorWorld, Trials, draw_trials

__all__ = ["trial_path", "path_figure"]

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
