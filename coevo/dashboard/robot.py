"""The current best robot of one run, for the page: an episode from its latest policies, and their rules.

A run's workers append every policy they publish to ``workers/*/published.jsonl`` (fsynced before
it leaves).  :class:`RobotPanel` follows those logs; once every agent of the task has published,
it plays the robot their newest versions make, as ``coevo show RUN_DIR`` would (the task's own
``show_*`` hooks: one epoch of the fuel task, one trial of the door task, from seed 0), draws it
as a PNG and lists each rule set's rules by strength with how often each fired.  It redraws when
a newer version arrives, at most every :data:`EVERY` seconds, so a run publishing every
generation costs one drawing (0.1-0.7 s of CPU) per interval at most.
"""

from __future__ import annotations

import base64
import math
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from coevo.dashboard.files import Tail
from coevo.errors import CoevoError

__all__ = ["EVERY", "TEXT_PX", "DPI", "RobotPicture", "RobotPanel"]

EVERY = 10.0  # seconds between two drawings of the robot, at least (a drawing: 0.1-0.7 s of CPU)
TEXT_PX = 12  # the picture's smallest text, in pixels, shown at its own size (the page does not enlarge it)


def _dpi() -> int:
    from coevo.scene.draw import SMALLEST_TEXT

    return math.ceil(TEXT_PX * 72 / SMALLEST_TEXT)


DPI = _dpi()  # 116: a picture 1218 px wide, which a laptop's page shows at its size


@dataclass
class RobotPicture:
    """What the page shows of a robot: the versions drawn, the picture, the rule tables; or why there is none."""

    run: str
    versions: dict[str, int] = field(default_factory=dict)
    png: str = ""  # base64
    tables: list[Any] = field(default_factory=list)  # coevo.tasks.showing.RuleTable
    episodes: int = 0
    note: str = ""  # why there is no picture (yet)

    def key(self) -> str:
        """What changes the page: the versions drawn and the note."""
        return f"{self.run}:{sorted(self.versions.items())}:{self.note}:{len(self.png)}"


class RobotPanel:
    """One run directory's robot, redrawn as its agents publish."""

    def __init__(self, run_dir: Path, *, seed: int = 0, every: float = EVERY) -> None:
        from coevo.rundir.layout import RunPaths

        self.paths = RunPaths(Path(run_dir))
        self.seed, self.every = seed, every
        self._tails: dict[str, Tail] = {}
        self._latest: dict[str, dict[str, Any]] = {}  # behaviour -> its newest published row
        self._drawn_at = float("-inf")  # the first policies are drawn at once
        self.picture = RobotPicture(self.paths.name, note="waiting for the run's first policies")

    def _read(self) -> None:
        """The newest row of every worker's publication log (a run not started yet has none)."""
        workers = self.paths.workers_dir
        for d in sorted(workers.iterdir()) if workers.is_dir() else []:
            tail = self._tails.get(d.name)
            if tail is None:
                tail = self._tails[d.name] = Tail(self.paths.worker(d.name).published)
            for row in tail.read():
                if isinstance(row.get("rules"), dict) and isinstance(row.get("version"), int):
                    self._latest[d.name] = row

    def update(self, now: float | None = None) -> bool:
        """Read what was published since the last call; redraw if newer versions arrived and the last drawing is
        ``every`` seconds old.  True if the picture changed."""
        now = time.time() if now is None else now
        self._read()
        versions = {b: int(r["version"]) for b, r in sorted(self._latest.items())}
        if not versions or versions == self.picture.versions or now - self._drawn_at < self.every:
            return False
        self._drawn_at = now
        before = self.picture.key()
        self.picture = self._draw(versions)
        return self.picture.key() != before

    def _draw(self, versions: dict[str, int]) -> RobotPicture:
        from coevo.policy.rules import RuleSet
        from coevo.scene import draw_png
        from coevo.show.source import from_path

        run = self.paths.name
        try:
            rules = {b: RuleSet.from_dict(r["rules"]) for b, r in self._latest.items()}
            shown = from_path(self.paths.dir, world_over={}, partners=rules, wanted=None)
        except CoevoError as exc:  # e.g. an agent that has not published yet: said, drawn once it has
            return RobotPicture(run, versions, note=f"no robot yet: {exc}")
        display, robot = shown.display, shown.robot
        played = display.show_play(robot, seed=self.seed, episodes=display.show_episodes(robot))
        shown_versions = ", ".join(f"{b} v{v}" for b, v in versions.items())
        scene = display.show_scene(played, title=f"{run}: {shown_versions}, seed {self.seed}")
        with tempfile.TemporaryDirectory(prefix="coevo-dashboard-") as tmp:
            out = Path(tmp) / "robot.png"
            draw_png(scene, out, dpi=DPI)
            png = base64.b64encode(out.read_bytes()).decode("ascii")
        return RobotPicture(run, versions, png, list(display.show_rules(played)), int(played.episodes))
