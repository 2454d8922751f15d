"""Render a :class:`~coevo.scene.scene.Scene`: a PNG of the whole run, or an animation (GIF, MP4).

The picture: the static geometry, the protagonist's path coloured by category (older
spans paler), the other tracks thin and dashed, rings as shaded annuli, a marker per
event, the spans' summaries beside the arena and, with ``trace``, a strip below
showing which rule fired at each frame.  Animations show the bodies moving with their
path so far and the frame's caption, at most ``max_frames`` frames (evenly
thinned), written with matplotlib's PillowWriter (GIF) or FFMpegWriter (MP4, only
when ffmpeg is installed).  Files are written to a temporary sibling and renamed,
so a failure leaves nothing half-written.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from coevo.errors import ConfigError
from coevo.scene.scene import Scene

__all__ = ["draw_png", "animate", "check_out_path", "FORMATS", "ANIMATION_FORMATS", "SMALLEST_TEXT"]

FORMATS = (".png",)
ANIMATION_FORMATS = (".gif", ".mp4")
CATEGORY_COLOURS = ("tab:blue", "tab:orange", "tab:purple", "tab:cyan")
#: Points of a picture's smallest text (legend, episode summaries, a block's label, the trace's ticks): a page that
#: shows a picture at its own size chooses its dpi from this (coevo.dashboard.robot: 12 px at least)
SMALLEST_TEXT = 7.5
# kind -> (marker, colour, size, legend label)
EVENT_STYLE = {
    "start": ("o", "black", 40, "episode start (* new epoch)"),
    "tracking": ("^", "tab:green", 70, "time up, tracking"),
    "docked": ("*", "gold", 140, "docked"),
    "collided": ("X", "tab:red", 80, "collided"),
    "ran dry": ("s", "saddlebrown", 60, "ran dry"),
    "time up": ("D", "0.45", 45, "time up, out of range"),
    "reached goal": ("*", "tab:green", 140, "reached the goal"),
    "ran out of time": ("D", "0.45", 45, "ran out of time"),
}
# role -> line style of open or thin static shapes (SHAPE_ROLES); other roles are filled blocks
LINE_STYLE = {
    "goal": dict(color="tab:green", linestyle="--", linewidth=1.2),
    "mark": dict(color="0.6", linestyle=":", linewidth=1.0),
    "beam": dict(color="tab:orange", linestyle="-", linewidth=1.0),
    "failed beam": dict(color="tab:red", linestyle="-", linewidth=2.5),
}


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")  # files only, no display needed
    import matplotlib.pyplot as plt

    return plt


def check_out_path(path: Path, formats: tuple[str, ...]) -> None:
    """Refuse, before any work, an output file of the wrong type or in a missing or read-only directory."""
    path = Path(path)
    if path.suffix.lower() not in formats:
        raise ConfigError(f"--out {str(path)!r}: expected a {' or '.join(formats)} file")
    parent = path.parent
    if not parent.is_dir():
        raise ConfigError(f"--out {str(path)!r}: directory {str(parent)!r} does not exist")
    if path.is_dir():
        raise ConfigError(f"--out {str(path)!r} is a directory")
    try:  # the only sure test (root passes os.access everywhere, a read-only mount fails it late)
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError as exc:
        raise ConfigError(f"--out {str(path)!r}: directory {str(parent)!r} is not writable ({exc.strerror})") from None


def _atomic(path: Path, write: Callable[[str], None]) -> None:
    """Run ``write(tmp)`` on a temporary sibling of ``path``, then rename it into place."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    except OSError as exc:
        raise ConfigError(f"cannot write {str(path)!r}: {exc.strerror}") from None
    os.close(fd)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes it 0600; the picture is an ordinary file
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        raise ConfigError(f"cannot write {str(path)!r}: {exc.strerror or exc}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _title(fig: Any, title: str, fontsize: float, *, below: float = 0.0) -> float:
    """``title`` across the top of ``fig``, wrapped to its width (a long one was cut at both edges); returns the
    figure fraction left under it, and under ``below`` points more (an axes' own title), for the panels."""
    import textwrap

    width_pt = fig.get_figwidth() * 72
    chars = max(20, int(width_pt / (0.58 * fontsize)))  # DejaVu Sans: ~0.55 em a character on average
    lines = textwrap.wrap(title, chars) or [""]
    fig.suptitle("\n".join(lines), fontsize=fontsize, y=1 - 4 / (fig.get_figheight() * 72), va="top")
    used = 4 + len(lines) * fontsize * 1.25 + below
    return 1 - used / (fig.get_figheight() * 72)


def _colour(cat: int, scene: Scene) -> str:
    colours = scene.colours or CATEGORY_COLOURS
    return colours[cat % len(colours)]


def _arena(ax: Any, scene: Scene) -> list[tuple[int, Any]]:
    """The statics; returns the artists of those that belong to a category, with it (an animation brings the
    current one forward)."""
    from matplotlib.colors import to_rgba
    from matplotlib.patches import Polygon

    owned: list[tuple[int, Any]] = []
    x0, x1, y0, y1 = scene.extent
    for s in scene.statics:
        if s.role == "wall":
            ax.add_patch(Polygon(s.points, closed=s.kind == "polygon", fill=False, edgecolor="black", linewidth=2,
                                 alpha=None if s.alpha == 1 else s.alpha))
        elif s.role in LINE_STYLE:
            ax.plot(s.points[:, 0], s.points[:, 1], alpha=s.alpha, zorder=2, **LINE_STYLE[s.role])
        elif s.category is not None and s.kind == "polyline":  # a category's mark (e.g. one trial's door posts)
            (line,) = ax.plot(s.points[:, 0], s.points[:, 1], color=_colour(s.category, scene), linewidth=2.2,
                              alpha=s.alpha, zorder=3, solid_capstyle="butt")
            owned.append((s.category, line))
        elif s.category is not None:  # a category's block (e.g. one trial's wall): a faint fill in its colour
            owned.append((s.category, ax.add_patch(Polygon(
                s.points, closed=True, facecolor=to_rgba(_colour(s.category, scene), s.alpha), edgecolor="none",
                zorder=1.5))))
        else:
            ax.add_patch(Polygon(s.points, closed=s.kind == "polygon", facecolor="0.55", edgecolor="black",
                                 alpha=None if s.alpha == 1 else s.alpha))
            if s.label:
                cx, cy = s.points.mean(axis=0)
                ax.annotate(s.label, (cx, cy), ha="center", va="center", fontsize=SMALLEST_TEXT, color="white")
    pad = 0.03 * (x1 - x0)
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    return owned


def _segments(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The protagonist's path as (segments (n, 2, 2), category per segment, span index per segment)."""
    robot = scene.tracks[0]
    segs, cats, spans = [], [], []
    for i, sp in enumerate(scene.spans):
        xy = robot.xy[sp.first: sp.last + 1]
        if len(xy) < 2:
            continue
        segs.append(np.stack([xy[:-1], xy[1:]], axis=1))
        cats.append(np.full(len(xy) - 1, sp.category))
        spans.append(np.full(len(xy) - 1, i))
    if not segs:
        return np.zeros((0, 2, 2)), np.zeros(0, int), np.zeros(0, int)
    return np.concatenate(segs), np.concatenate(cats), np.concatenate(spans)


def _ring(ax: Any, r: Any, scene: Scene, alpha: float = 0.12) -> Any:
    from matplotlib.patches import Rectangle, Wedge

    w = Wedge((r.x, r.y), r.outer, 0, 360, width=r.outer - r.inner, facecolor="tab:green", alpha=alpha,
              edgecolor="tab:green", linewidth=0.6)
    ax.add_patch(w)
    x0, x1, y0, y1 = scene.extent
    w.set_clip_path(Rectangle((x0, y0), x1 - x0, y1 - y0, transform=ax.transData))  # not beyond the walls
    return w


def _legend(ax: Any, scene: Scene) -> None:
    from matplotlib.lines import Line2D

    used = {sp.category for sp in scene.spans}
    handles = [Line2D([], [], color=_colour(i, scene), linewidth=2.5, label=f"{scene.tracks[0].name}: {c}")
               for i, c in enumerate(scene.categories) if i in used]
    handles += [Line2D([], [], color="0.4", linestyle="--", linewidth=1, label=t.name) for t in scene.tracks[1:]]
    if scene.rings:
        handles.append(Line2D([], [], color="tab:green", alpha=0.4, linewidth=6, label="tracking range"))
    kinds = {e.kind for e in scene.events}
    for kind, (marker, colour, size, label) in EVENT_STYLE.items():
        if kind in kinds:
            handles.append(Line2D([], [], marker=marker, color=colour, linestyle="", markersize=np.sqrt(size), label=label))
    ax.legend(handles=handles, loc="upper left", fontsize=SMALLEST_TEXT, frameon=False)


def draw_png(scene: Scene, path: Path, *, trace: bool = False, dpi: int = 80) -> None:
    """The whole scene in one picture, written atomically to ``path``."""
    plt = _pyplot()
    from matplotlib.collections import LineCollection
    from matplotlib.colors import to_rgba

    fig = plt.figure(figsize=(10.5, 8.0 if trace else 6.4))
    top = _title(fig, scene.title, 11, below=6)
    grid = fig.add_gridspec(2 if trace else 1, 2, width_ratios=(1.0, 0.72), height_ratios=(1.0, 0.3) if trace else None,
                            left=0.02, right=0.99, top=top, bottom=0.07 if trace else 0.02, wspace=0.03, hspace=0.15)
    ax = fig.add_subplot(grid[0, 0])
    side = fig.add_subplot(grid[0, 1])
    _arena(ax, scene)
    for r in scene.rings:
        _ring(ax, r, scene)
    for t in scene.tracks[1:]:
        for sp in scene.spans:  # per span: a body may jump between them (a new epoch)
            ax.plot(t.xy[sp.first: sp.last + 1, 0], t.xy[sp.first: sp.last + 1, 1], color="0.4", linestyle="--",
                    linewidth=0.9)
    segs, cats, spans = _segments(scene)
    if len(segs):
        n = max(1, len(scene.spans) - 1)
        alpha = 0.35 + 0.65 * spans / n if len(scene.spans) > 1 else np.ones(len(spans))
        colours = [to_rgba(_colour(c, scene), a) for c, a in zip(cats, alpha, strict=True)]
        ax.add_collection(LineCollection(list(segs), colors=colours, linewidths=2.0))
    for e in scene.events:
        marker, colour, size, _ = EVENT_STYLE.get(e.kind, ("o", "black", 30, e.kind))
        face = "none" if e.kind == "start" else colour
        ax.scatter([e.x], [e.y], marker=marker, s=size, facecolors=face, edgecolors=colour, zorder=5, linewidths=1.2)
        if e.kind == "start":
            ax.annotate(e.label, (e.x, e.y), xytext=(4, 4), textcoords="offset points", fontsize=8, zorder=6)
    side.axis("off")
    _legend(side, scene)
    lines = [s.summary for s in scene.spans]
    side.text(0.0, 0.52, "\n".join(lines[:24] + ([f"... {len(lines) - 24} more"] if len(lines) > 24 else [])),
              va="top", ha="left", fontsize=SMALLEST_TEXT, family="monospace", transform=side.transAxes)
    if trace and scene.rule is not None:
        _trace_panel(fig.add_subplot(grid[1, :]), scene)
    try:
        _atomic(Path(path), lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"))
    finally:
        plt.close(fig)


def _trace_panel(ax: Any, scene: Scene) -> None:
    """Rule fired per frame, coloured by category, with span boundaries."""
    if scene.rule is None:
        return
    frames = np.arange(scene.frames)
    cat = scene.tracks[0].category if scene.tracks[0].category is not None else np.zeros(scene.frames, int)
    fired = scene.rule > 0
    for c in np.unique(cat[fired]):
        sel = fired & (cat == c)
        ax.scatter(frames[sel], scene.rule[sel], s=6, color=_colour(int(c), scene), marker="s", linewidths=0)
    for sp in scene.spans[1:]:
        ax.axvline(sp.first - 0.5, color="0.8", linewidth=0.8)
    ax.set_xlim(-0.5, scene.frames - 0.5)
    top = int(scene.rule.max()) if fired.any() else 1
    ax.set_ylim(0.3, top + 0.7)
    ax.set_ylabel("rule #", fontsize=8)
    ax.set_xlabel(f"step (all episodes in a row); {scene.rule_label}", fontsize=8)
    ax.tick_params(labelsize=SMALLEST_TEXT)
    if top <= 16:
        ax.set_yticks(range(1, top + 1))
    ax.grid(axis="y", alpha=0.25)


def animate(scene: Scene, path: Path, *, fps: int = 12, max_frames: int = 150, dpi: int = 70) -> int:
    """The scene as an animation (GIF, or MP4 with ffmpeg), written atomically; returns the frames drawn."""
    plt = _pyplot()
    from matplotlib import animation
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Circle

    path = Path(path)
    if path.suffix.lower() == ".mp4":
        if not animation.FFMpegWriter.isAvailable():
            raise ConfigError(f"--out {str(path)!r}: MP4 needs ffmpeg, which is not installed; use a .gif")
        writer: Any = animation.FFMpegWriter(fps=fps)
    else:
        writer = animation.PillowWriter(fps=fps)
    stride = max(1, int(np.ceil(scene.frames / max_frames)))
    shown = list(range(0, scene.frames, stride))
    if shown[-1] != scene.frames - 1:
        shown.append(scene.frames - 1)

    fig, ax = plt.subplots(figsize=(6.0, 6.4))
    fig.subplots_adjust(left=0.02, right=0.98, top=_title(fig, scene.title, 10, below=9 * 1.25 + 8), bottom=0.02)
    owned = _arena(ax, scene)
    alphas = [a.get_alpha() if a.get_alpha() is not None else a.get_facecolor()[3] for _, a in owned]
    segs, cats, _ = _segments(scene)
    seg_frame = np.concatenate([np.arange(sp.first + 1, sp.last + 1) for sp in scene.spans if sp.last > sp.first]) \
        if len(segs) else np.zeros(0, int)
    path_lines = LineCollection([], linewidths=1.8)
    ax.add_collection(path_lines)
    robot, others = scene.tracks[0], scene.tracks[1:]
    body = Circle((0, 0), robot.radius, facecolor="white", edgecolor="black", zorder=6)
    ax.add_patch(body)
    (nose,) = ax.plot([], [], color="black", linewidth=1.5, zorder=7)
    other_bodies = [ax.add_patch(Circle((0, 0), t.radius, facecolor="0.6", edgecolor="0.2", zorder=5)) for t in others]
    names = [t.name for t in scene.tracks]
    halo = next((r for r in scene.rings if r.around in names), None)
    ring = _ring(ax, halo, scene, alpha=0.15) if halo is not None else None
    ring_track = scene.tracks[names.index(halo.around)] if halo is not None else None
    caption = ax.set_title("", fontsize=9)
    colours = np.array([_colour(int(c), scene) for c in cats]) if len(cats) else np.array([])

    def frame(i: int) -> None:
        upto = seg_frame <= i
        path_lines.set_segments(list(segs[upto]))
        path_lines.set_color(list(colours[upto]))
        x, y = robot.xy[i]
        body.set_center((x, y))
        h = robot.heading[i] if robot.heading is not None else 0.0
        nose.set_data([x, x + 1.6 * robot.radius * np.cos(h)], [y, y + 1.6 * robot.radius * np.sin(h)])
        for b, t in zip(other_bodies, others, strict=True):
            b.set_center(tuple(t.xy[i]))
        if ring is not None and ring_track is not None:
            ring.set_center(tuple(ring_track.xy[i]))
        caption.set_text(scene.captions[i])
        now = robot.category[i] if robot.category is not None else -1
        for (cat, artist), alpha in zip(owned, alphas, strict=True):  # the current episode's own statics forward
            artist.set_alpha(min(1.0, alpha * 2.5) if cat == now else alpha * 0.5)

    anim = animation.FuncAnimation(fig, frame, frames=shown, interval=1000 / fps, blit=False)
    try:
        _atomic(path, lambda tmp: anim.save(tmp, writer=writer, dpi=dpi))
    finally:
        plt.close(fig)
    return len(shown)
