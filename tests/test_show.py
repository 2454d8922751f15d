"""``coevo show`` and the runner's recorder: recorded states are the world's, recording changes nothing,
the command draws what it is given and refuses bad input in one line with status 2, writing nothing."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from coevo.cli import main
from coevo.policy.matcher import CompiledPolicies
from coevo.policy.text import format_ruleset, parse_ruleset
from coevo.tasks.fuel.pictures import episode_endings, play, robot_from_rules, scene_for
from coevo.tasks.fuel.pictures.rules_view import fire_counts, rule_rows, trace_lines
from coevo.tasks.fuel import default_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.recorder import Recorder
from coevo.tasks.fuel.runner import Rules, run_lanes
from coevo.tasks.fuel.settings import WorldConfig
from coevo.tasks.fuel.world import BatchWorld

EXEC_RULES = "# behaviour: executive\nIF fuel = [0, 20] THEN SET task = dock (strength 0.9)\nIF ANY THEN SET task = track (strength 0.5)\n"
PNG = b"\x89PNG\r\n\x1a\n"


def coevo(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "coevo", *args], capture_output=True, text=True, timeout=120, cwd=cwd)


# ----------------------------------------------------------------- the recorder
class LoggingWorld(BatchWorld):
    """A world that keeps its state before and after every step, to check the recorder against."""

    def __init__(self, *a: object, **k: object) -> None:
        super().__init__(*a, **k)  # type: ignore[arg-type]
        self.log: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def _state(self) -> np.ndarray:
        return np.stack([self.rx, self.ry, self.rh, self.tx, self.ty, self.fuel]).copy()

    def step(self, active, turn, speed, target_noise):  # type: ignore[no-untyped-def]
        before = self._state()
        ev = super().step(active, turn, speed, target_noise)
        self.log.append((active.copy(), before, self._state()))
        return ev


def _combined(lanes: int) -> dict[str, object]:
    ex = parse_ruleset(EXEC_RULES)
    rules = {b: Rules.single(CompiledPolicies([rs]), lanes) for b, rs in
             (("executive", ex), ("tracking", default_ruleset("tracking")), ("docking", default_ruleset("docking")))}
    return dict(lane_episodes=6, restart_epochs=True, **rules)


def test_recorded_states_are_what_the_world_did() -> None:
    lanes = 5
    w = LoggingWorld(WorldConfig(), lanes)
    rec = Recorder()
    out = run_lanes(w, rng=np.random.default_rng(3), record=rec, **_combined(lanes))  # type: ignore[arg-type]
    recorded = lambda k, t: np.stack([rec.rx[k, t], rec.ry[k, t], rec.rh[k, t], rec.tx[k, t], rec.ty[k, t], rec.fuel[k, t]])  # noqa: E731
    i = 0
    for k in range(6):
        for t in range(int(out.steps[:, k].max())):
            active, before, after = w.log[i]
            i += 1
            assert np.array_equal(recorded(k, t)[:, active], before[:, active])
            assert np.array_equal(recorded(k, t + 1)[:, active], after[:, active])
            assert (rec.rule[k, t, active] >= 0).all() and (rec.rule[k, t, ~active] == -1).all()
    assert i == len(w.log)
    # One recorded position per step plus the start; NaN past an episode's end.
    for k in range(6):
        for lane in range(lanes):
            s = int(out.steps[lane, k])
            assert np.isfinite(rec.rx[k, : s + 1, lane]).all() and np.isnan(rec.rx[k, s + 1:, lane]).all()
    assert np.array_equal(rec.task, out.task.T)
    assert (rec.executive_rule[out.played.T] >= 0).all()


def test_recording_does_not_change_the_outcome() -> None:
    lanes = 6
    kw = _combined(lanes)
    kw["learner"] = "tracking"
    plain = run_lanes(BatchWorld(WorldConfig(), lanes), rng=np.random.default_rng(11), scenarios=3, **kw)  # type: ignore[arg-type]
    recorded = run_lanes(BatchWorld(WorldConfig(), lanes), rng=np.random.default_rng(11), scenarios=3,
                         record=Recorder(), **kw)  # type: ignore[arg-type]
    for f in dataclasses.fields(plain):
        if f.name == "trace":
            for g in ("bins", "rule", "full"):
                assert np.array_equal(getattr(plain.trace, g), getattr(recorded.trace, g)), g
        else:
            assert np.array_equal(getattr(plain, f.name), getattr(recorded, f.name)), f.name


# ----------------------------------------------------------------- scene and rules
def test_scene_and_rule_counts_agree_with_the_outcome() -> None:
    robot = robot_from_rules("r", WorldConfig(), {Behaviour.EXECUTIVE: parse_ruleset(EXEC_RULES),
                                                  Behaviour.TRACKING: default_ruleset("tracking"),
                                                  Behaviour.DOCKING: default_ruleset("docking")})
    p = play(robot, seed=3)
    out = p.outcome
    scene = scene_for(p)
    assert scene.frames == int(out.steps[0].sum()) + p.episodes
    endings = episode_endings(p)
    assert [e.kind for e in scene.events if e.kind != "start"] == endings
    assert sum(e == "collided" for e in endings) == int(out.collided[0].sum())
    steps = {b: int(out.steps[0][out.task[0] == t].sum()) for b, t in ((Behaviour.TRACKING, 0), (Behaviour.DOCKING, 1))}
    for b, rs in robot.rulesets().items():
        counts = fire_counts(p, b, len(rs))
        assert counts.sum() == (p.episodes if b == Behaviour.EXECUTIVE else steps[b])
        rows = rule_rows(rs, counts)
        assert [r.strength for r in rows] == sorted((r.strength for r in rows), reverse=True)
    assert len(trace_lines(p)) == p.episodes
    # Same seed, same pictures' data.
    assert np.array_equal(scene_for(play(robot, seed=3)).tracks[0].xy, scene.tracks[0].xy, equal_nan=True)


# ----------------------------------------------------------------- the command
def _run_dir(root: Path, *, complete: bool = True) -> Path:
    d = root / "run1"
    d.mkdir()
    (d / "run.json").write_text(json.dumps({"run": "run1", "world": WorldConfig().model_dump()}))
    for b, text in (("executive", EXEC_RULES), ("tracking", format_ruleset(default_ruleset("tracking"))),
                    ("docking", format_ruleset(default_ruleset("docking")))):
        if b == "docking" and not complete:
            continue
        (d / "workers" / b).mkdir(parents=True)
        (d / "workers" / b / "best.rules").write_text(text)
    return d


def test_show_draws_a_run_directory_and_prints_rules(tmp_path: Path) -> None:
    d = _run_dir(tmp_path)
    r = coevo("show", str(d), "--trace", "--rules", "--out", str(tmp_path / "epoch.png"))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "epoch.png").read_bytes().startswith(PNG)
    lines = r.stdout.splitlines()
    assert lines[0].startswith("drawing seed ") and "the median of 9 epochs" in lines[0]  # which epoch, and why
    assert lines[1].startswith("executive: 2 rules by strength")
    assert any(line.startswith("episode 1 (") for line in lines)  # --trace with --rules
    assert "│" not in r.stdout and "┃" not in r.stdout  # plain text when not on a terminal


def test_show_default_and_animation(tmp_path: Path) -> None:
    r = coevo("show", "--default", "tracking", "--episodes", "1", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "default-tracking-episodes1-seed0.png").read_bytes().startswith(PNG)
    assert main(["show", "--default", "docking", "--episodes", "2", "--world", "episode_steps=8", "--animate",
                 "--out", str(tmp_path / "d.gif")]) == 0  # short episodes: a GIF costs ~50 ms a frame
    assert (tmp_path / "d.gif").read_bytes()[:6] == b"GIF89a"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.gif", "default-tracking-episodes1-seed0.png"]


def test_show_learn_directories(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = tmp_path / "learn-docking"
    d.mkdir()
    (d / "config.json").write_text(json.dumps({"behaviour": "docking", "world": WorldConfig().model_dump()}))
    (d / "best.rules").write_text(format_ruleset(default_ruleset("docking")))
    assert main(["show", str(d), "--episodes", "2"]) == 0
    assert (d / "show-episodes2-seed0.png").exists()
    e = tmp_path / "learn-executive"
    e.mkdir()
    (e / "best.rules").write_text(EXEC_RULES)
    assert main(["show", str(e)]) == 2
    err = capsys.readouterr().err
    assert "RunDirError" in err and "tracking.rules" in err and "--tracking FILE" in err
    (e / "tracking.rules").write_text(format_ruleset(default_ruleset("tracking")))
    (e / "docking.rules").write_text(format_ruleset(default_ruleset("docking")))
    assert main(["show", str(e), "--out", str(tmp_path / "e.png")]) == 0


def _bad_cases(tmp: Path) -> list[tuple[list[str], str]]:
    (tmp / "notes.txt").write_text("hello\n")
    (tmp / "empty").mkdir()
    d = _run_dir(tmp, complete=False)
    t = str(tmp / "notes.txt")
    good = ["--default", "tracking"]
    return [
        ([str(tmp / "missing.rules")], "no such file"),
        ([t], "not a coevo rule file"),
        ([str(tmp / "empty")], "holds no policies"),
        ([str(d)], "docking/best.rules"),
        ([*good, "--task", "maze"], "'maze'"),
        ([*good, "--episodes", "0"], "--episodes: invalid number 0: give a whole number from 1 to 1000"),
        ([*good, "--episodes=-3"], "invalid number -3"),
        ([*good, "--out", str(tmp / "nowhere" / "x.png")], "does not exist"),
        ([*good, "--out", str(tmp / "x.txt")], ".png"),
        ([*good, "--seed", "-1"], "invalid seed -1"),
        ([*good, "--fps", "0", "--animate"], "--fps: invalid number 0: give a whole number from 1 to 60"),
        ([*good, "--world", "arena=-1"], "arena=-1"),
        (["--default", "executive"], "'executive'"),
        ([], "nothing to show"),
        (["--default", "tracking", "--out", ""], "--out '' is empty"),
        (["/bin/sh"], "not UTF-8 text"),
    ]


def test_bad_input_fails_in_one_line_and_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for args, needle in _bad_cases(tmp_path):
        before = sorted(p.name for p in tmp_path.rglob("*"))
        try:
            code = main(["show", *args])
        except SystemExit as exc:  # refused by the parser (a flag's bound, an empty value)
            code = exc.code
        assert code == 2, args
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and needle in err and err.split(":")[0].endswith("Error"), (args, err)
        assert sorted(p.name for p in tmp_path.rglob("*")) == before, args


def _writable(d: Path) -> bool:
    try:
        with tempfile.TemporaryFile(dir=d):
            return True
    except OSError:
        return False


def test_bad_input_as_a_real_process(tmp_path: Path) -> None:
    r = coevo("show", str(tmp_path / "missing.rules"))
    assert r.returncode == 2 and r.stderr.strip() == f"ConfigError: no such file or directory: '{tmp_path / 'missing.rules'}'"
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o500)
    try:
        if _writable(out):  # root writes anywhere: use a directory the kernel refuses instead
            out = Path("/sys")
            if _writable(out):
                pytest.skip("no read-only directory to try")
        r = coevo("show", "--default", "tracking", "--out", str(out / "x.png"))
        assert r.returncode == 2 and "not writable" in r.stderr and "Traceback" not in r.stderr
        assert not (out / "x.png").exists()
    finally:
        (tmp_path / "ro").chmod(0o700)


@pytest.mark.skipif(shutil.which("ffmpeg") is not None, reason="ffmpeg is installed")
def test_mp4_without_ffmpeg_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["show", "--default", "tracking", "--episodes", "1", "--out", str(tmp_path / "a.mp4")]) == 2
    assert "ffmpeg" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------- other tasks: each task draws its own robots
def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data.startswith(PNG) and data[12:16] == b"IHDR", path
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def _learn(tmp: Path, behaviour: str, *extra: str) -> Path:
    d = tmp / f"learn-{behaviour}"
    assert main(["learn", "--behaviour", behaviour, "--generations", "1", "--population", "4", "--episodes", "2",
                 "--measure-epochs", "2", "--out", str(d), "--quiet", *extra]) == 0
    return d


def test_show_draws_a_door_learn_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _learn(tmp_path, "door", "--fail", "front")
    capsys.readouterr()
    assert main(["show", str(d), "--episodes", "2", "--rules", "--trace", "--out", str(tmp_path / "door.png")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("door: ") and "rules by strength" in lines[0]
    assert sum(line.startswith("trial ") for line in lines) == 2 and lines[-1].startswith("wrote ")
    w, h = _png_size(tmp_path / "door.png")
    assert 400 <= w <= 2000 and 300 <= h <= 2000
    assert main(["show", str(d)]) == 0  # the default: one trial, inside the run directory
    assert _png_size(d / "show-episodes1-seed0.png")[0] >= 400


def test_door_scene_shows_the_room_and_the_failed_sonar() -> None:
    from coevo.tasks import get_task
    from coevo.tasks.door import DoorConfig, default_ruleset

    door = get_task("door").display()
    robot = door.show_robot("r", DoorConfig(failed=("front",)), {"door": default_ruleset()})
    played = door.show_play(robot, seed=1, episodes=3)
    scene = door.show_scene(played)
    roles = [s.role for s in scene.statics]
    assert roles.count("goal") == 1 and roles.count("failed beam") == 1 and roles.count("beam") == 6
    assert [e.kind for e in scene.events if e.kind != "start"] == [
        {1: "reached goal", 2: "collided", 3: "ran out of time"}[int(o)] for o in played.outcome]
    assert scene.frames == len(scene.tracks[0].xy) == sum(len(p) for p in played.poses)
    assert np.isfinite(scene.tracks[0].xy).all()


def test_each_door_trial_crosses_its_own_wall_drawn_in_its_own_colour() -> None:
    """Every trial has a wall of its own (its opening somewhere else): each trial's wall and its opening's posts
    belong to that trial's category, the colour of its path, and a path that reaches the goal crosses the wall
    between its own trial's posts."""
    from coevo.tasks import get_task
    from coevo.tasks.door import DoorConfig, default_ruleset
    from coevo.tasks.door.world import GOAL

    door = get_task("door").display()
    cfg = DoorConfig()
    played = door.show_play(door.show_robot("r", cfg, {"door": default_ruleset()}), seed=0, episodes=6)
    scene = door.show_scene(played)
    assert scene.categories == tuple(f"trial {k + 1}" for k in range(6)) and len(set(scene.colours[:6])) == 6
    robot = scene.tracks[0]
    assert [sp.category for sp in scene.spans] == list(range(6))
    assert all((robot.category[sp.first: sp.last + 1] == k).all() for k, sp in enumerate(scene.spans))
    assert sum(played.outcome == GOAL) >= 1
    for k, sp in enumerate(scene.spans):
        posts = sorted(s.points[0, 0] for s in scene.statics if s.role == "door post" and s.category == k)
        walls = [s for s in scene.statics if s.role == "wall piece" and s.category == k]
        assert posts == pytest.approx([played.trials.opening[k], played.trials.opening[k] + cfg.opening])
        assert 1 <= len(walls) <= 2 and all(s.alpha < 0.5 for s in walls)  # faint: the others' show through
        if played.outcome[k] == GOAL:
            xy = robot.xy[sp.first: sp.last + 1]
            j = int(np.argmax(xy[:, 1] >= cfg.wall_centre))  # where its path crosses the wall
            assert posts[0] < xy[j, 0] < posts[1], (k, xy[j], posts)


def test_a_long_title_is_wrapped_inside_the_picture_not_cut() -> None:
    from coevo.scene.draw import _pyplot, _title

    plt = _pyplot()
    for size in ((6.0, 6.4), (10.5, 6.4)):  # the animation's figure, the picture's
        fig = plt.figure(figsize=size)
        title = "runs/learn-door-seed0-20261126-123456-a-long-name: 4 door trials, seed 0, failed: front, front_right, right; 2 reached the goal"
        top = _title(fig, title, 10)
        fig.canvas.draw()
        box = fig._suptitle.get_window_extent()
        width, height = fig.bbox.width, fig.bbox.height
        assert 0 <= box.x0 < box.x1 <= width and box.y0 >= top * height - 1 and box.y1 <= height, (size, box)
        assert fig._suptitle.get_text().replace("\n", " ") == title
        plt.close(fig)


def test_show_draws_a_corridor_learn_run(tmp_path: Path) -> None:
    d = _learn(tmp_path, "corridor")
    assert main(["show", str(d), "--out", str(tmp_path / "c.png"), "--rules"]) == 0
    w, h = _png_size(tmp_path / "c.png")
    assert 400 <= w <= 2000 and 300 <= h <= 2000
    assert main(["show", str(d / "best.rules"), "--episodes", "2", "--animate", "--out", str(tmp_path / "c.gif")]) == 0
    assert (tmp_path / "c.gif").read_bytes()[:6] == b"GIF89a"


def test_foreign_or_broken_directories_fail_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    door = _learn(tmp_path, "door")
    fuel_world = tmp_path / "door-with-a-fuel-world"
    shutil.copytree(door, fuel_world)
    meta = json.loads((fuel_world / "config.json").read_text())
    (fuel_world / "config.json").write_text(json.dumps({**meta, "world": WorldConfig().model_dump()}))
    runs = {}
    for name, text in (("newer", '{"settings_version": 9, "task": "door"}'), ("maze", '{"task": "maze"}'),
                       ("garbled", "{not json"), ("inf", '{"task": "door", "world": {"room_width": Infinity}}')):
        runs[name] = tmp_path / name
        runs[name].mkdir()
        (runs[name] / "run.json").write_text(text)
    capsys.readouterr()
    cases = [
        ([str(door), "--task", "fuel"], str(door)),
        ([str(fuel_world)], "does not hold 'door' world settings"),
        ([str(runs["newer"])], "settings version 9"),
        ([str(runs["maze"])], "'maze'"),
        ([str(runs["garbled"])], "cannot be read"),
        ([str(runs["inf"])], "finite"),
        ([str(tmp_path)], "holds no policies"),
    ]
    for args, needle in cases:
        before = sorted(p.name for p in tmp_path.rglob("*"))
        try:
            code = main(["show", *args])
        except SystemExit as exc:  # refused by the parser (a flag's bound, an empty value)
            code = exc.code
        assert code == 2, args
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("RunDirError: ") and needle in err, (args, err)
        assert sorted(p.name for p in tmp_path.rglob("*")) == before, args
    for value in ("NaN", "Infinity", "-Infinity"):
        assert main(["show", str(door), "--world", f"room_width={value}"]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("ConfigError: ") and "finite" in err, err


def test_show_names_no_task() -> None:
    src = Path(__file__).resolve().parents[1] / "coevo" / "show"
    for f in src.glob("*.py"):
        text = f.read_text()
        assert "tasks.fuel" not in text and "tasks.door" not in text and "tasks.corridor" not in text, f.name
