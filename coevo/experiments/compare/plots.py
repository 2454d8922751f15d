"""Learning-curve plots of a comparison (the report's Figures 5 and 6), as PNG files.

A regime's own figure draws each curve as the mean over its runs with the band between the lowest and highest
run, and the individual runs thin, so starved and successful runs remain visible instead of being averaged into one
another.  ``regimes.png`` draws each regime's mean with the band of its 95 % interval (the dashboard's bands and the
report's Executive-curve table: :func:`~coevo.experiments.compare.stats.mean_intervals`); each legend says which.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from coevo.experiments.common import plural
from coevo.experiments.compare.reading import Panel
from coevo.experiments.compare.stats import MIN_RUNS, clip, clip_words, mean_intervals

__all__ = ["figure_for_regime", "figure_regimes", "figure_rates", "REGIME_COLOURS", "REGIME_HATCHES"]

#: A comparison's groups: Okabe and Ito's colour-blind-safe colours (vermillion, blue, bluish green, orange, reddish
#: purple, sky blue), none two of which a colour-blind reader confuses or whose overlap reads as a third; the
#: dashboard's comparison page draws its regimes in them too.
REGIME_COLOURS = ("#D55E00", "#0072B2", "#009E73", "#E69F00", "#CC79A7", "#56B4E9")
#: Each group's band hatching, in the same order: overlapping bands cross-hatch.
REGIME_HATCHES = ("/", "\\", "|", "-", "x", ".")

Curves = Mapping[str, Mapping[str, Mapping[str, Sequence[float]]]]  # run -> behaviour -> column -> per generation


def _matrix(curves: Curves, behaviour: str, column: str) -> np.ndarray:
    """Runs × generations, padded with NaN where a run has fewer generations."""
    rows = [list(c[behaviour][column]) for c in curves.values() if behaviour in c and column in c[behaviour]]
    if not rows:
        return np.zeros((0, 0))
    n = max(len(r) for r in rows)
    m = np.full((len(rows), n), np.nan)
    for i, r in enumerate(rows):
        m[i, : len(r)] = r
    return m


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")  # files only, no display needed
    import matplotlib.pyplot as plt

    return plt


def _axis(ax, title: str, ylabel: str, top: float | None, *, xlabel: str = "generation") -> None:
    from matplotlib.ticker import MaxNLocator

    ax.set_title(title)
    ax.set_xlabel(xlabel)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # generations are whole: no 1.5 on a 3-generation run
    ax.set_ylabel(ylabel)
    if top is not None:
        ax.set_ylim(0, top)
    ax.grid(alpha=0.3)


def _grid(plt, panels: Sequence[Panel]):
    """A figure with a subplot per panel, three to a row, and its axes in the panels' order (spare ones hidden)."""
    cols = min(3, len(panels))
    rows = -(-len(panels) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(14 * cols / 3, 3.5 * rows), constrained_layout=True, squeeze=False)
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    return fig, list(axes.flat)[: len(panels)]


def figure_for_regime(curves: Curves, regime: str, path: Path, panels: Sequence[Panel]) -> None:
    """One regime's panels (the fuel task's: the report's four, its Figure 5 for Mutual, 6 for Independent, then
    Docking's own measure and how often the Executive picked Docking)."""
    plt = _pyplot()
    fig, axes = _grid(plt, panels)
    for ax, (title, beh, col, ylabel, top) in zip(axes, panels, strict=True):
        m = _matrix(curves, beh, col)
        if m.size and not np.isnan(m).all():
            g = np.arange(1, m.shape[1] + 1)
            for row in m:
                ax.plot(g, row, color="0.75", linewidth=0.7)
            ax.fill_between(g, np.nanmin(m, axis=0), np.nanmax(m, axis=0), color="tab:blue", alpha=0.12)
            ax.plot(g, np.nanmean(m, axis=0), color="tab:blue", linewidth=2,
                    label=f"mean of {plural(m.shape[0], 'run')} (band: lowest to highest run)")
            ax.legend(loc="upper left", fontsize=8)
        _axis(ax, title, ylabel, top)
    fig.suptitle(f"{regime.capitalize()} regime: learning and performance")
    fig.savefig(path, dpi=90)
    plt.close(fig)


def figure_regimes(by_regime: Mapping[str, Curves], path: Path, panels: Sequence[Panel]) -> None:
    """The regimes' mean curves side by side on the same panels."""
    plt = _pyplot()
    fig, axes = _grid(plt, panels)
    for ax, panel in zip(axes, panels, strict=True):
        title, beh, col, ylabel, top = panel
        for i, (regime, curves) in enumerate(by_regime.items()):
            colour, hatch = (x[i % len(x)] for x in (REGIME_COLOURS, REGIME_HATCHES))
            m = _matrix(curves, beh, col)
            if not m.size or np.isnan(m).all():
                continue
            g = np.arange(1, m.shape[1] + 1)
            mean, low, high = mean_intervals(m)
            low, high, cut = clip(low, high, panel.bounds)
            # hatched and edged, as on the dashboard: two overlapping bands stay two, not one blended colour
            ax.fill_between(g, low, high, facecolor=colour, alpha=0.15, edgecolor="none")
            ax.fill_between(g, low, high, facecolor="none", edgecolor=colour, hatch=hatch * 2, linewidth=0.8,
                            alpha=0.5)
            band = ("band: 95 % interval of the mean" + (f", {clip_words(cut)}" if cut else "")
                    if m.shape[0] >= MIN_RUNS else f"no band: an interval needs {MIN_RUNS} runs")
            ax.plot(g, mean, color=colour, linewidth=2, label=f"{regime}: mean of {plural(m.shape[0], 'run')} ({band})")
        _axis(ax, title, ylabel, top)
        ax.legend(loc="upper left", fontsize=8)
    fig.suptitle("Regimes compared")
    fig.savefig(path, dpi=90)
    plt.close(fig)


def figure_rates(by_group: Mapping[str, Curves], path: Path) -> None:
    """The Executive's mean learning curve per group: live regimes and every rate of asynchrony, overlaid."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    cmap = plt.get_cmap("viridis")
    offline = [g for g in by_group if g not in ("mutual", "independent")]
    styles = {"mutual": ("tab:red", "--"), "independent": ("black", "--")}
    styles |= {g: (cmap(i / max(1, len(offline) - 1)), "-") for i, g in enumerate(offline)}
    panels = (("Executive learning curve", "best_fitness", "generation's best fitness", 1.0),
              ("Docking picked (Executive's generation's best)", "dock_choice", "% of episodes", 100.0))
    for ax, (title, col, ylabel, top) in zip(axes, panels, strict=True):
        for g, curves in by_group.items():
            m = _matrix(curves, "executive", col)
            if not m.size or np.isnan(m).all():
                continue
            colour, line = styles[g]
            ax.plot(np.arange(1, m.shape[1] + 1), np.nanmean(m, axis=0), color=colour, linestyle=line, linewidth=2,
                    label=f"{g} ({plural(m.shape[0], 'run')})")
        _axis(ax, title, ylabel, top, xlabel="Executive generation")
        ax.legend(loc="upper right", fontsize=7)
    fig.suptitle("The Executive learning on recorded Tracking/Docking histories, by rate of asynchrony (means)")
    fig.savefig(path, dpi=90)
    plt.close(fig)
