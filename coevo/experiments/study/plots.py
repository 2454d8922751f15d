"""A study's figures (PNG, matplotlib as the comparison's): one effect plot per factor, and every cell's shares (a
study of learning runs: every cell's runs on its behaviour's first measure).

An effect plot shows, per level of the factor, each measure's mean over the runs at that level with its 95 %
interval (Student t for means, none below three runs; Wilson for shares), one line per stratum (regime or rate
group), pooled over the other factors' levels: the main effect, as the report's tests take it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["effect_figure", "cells_figure", "learn_cells_figure"]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")  # files only, no display needed
    import matplotlib.pyplot as plt

    return plt


def _errorbars(ax: Any, xs: Sequence[float], rows: Sequence[Mapping[str, Any]], *, label: str, colour: Any) -> None:
    mean = np.array([r["mean"] for r in rows], dtype=float)
    low = np.array([r["low"] for r in rows], dtype=float)
    high = np.array([r["high"] for r in rows], dtype=float)
    err = np.vstack([np.nan_to_num(mean - low), np.nan_to_num(high - mean)])
    ax.errorbar(xs, mean, yerr=err, marker="o", capsize=4, color=colour, label=label)


def effect_figure(factor: str, levels: Sequence[str], panels: Mapping[str, Mapping[str, Sequence[Mapping[str, Any]]]],
                  titles: Mapping[str, str], path: Path) -> None:
    """``panels``: measure -> stratum -> one row per level (``mean``, ``low``, ``high``)."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.8), constrained_layout=True, squeeze=False)
    colours = plt.get_cmap("tab10")
    for ax, (measure, strata) in zip(axes.flat, panels.items(), strict=True):
        for k, (stratum, rows) in enumerate(strata.items()):
            offset = (k - (len(strata) - 1) / 2) * 0.06  # strata side by side, their bars apart
            _errorbars(ax, [i + offset for i in range(len(levels))], rows, label=stratum, colour=colours(k % 10))
        ax.set_xticks(range(len(levels)), levels)
        ax.set_xlabel(factor)
        ax.set_title(titles[measure], fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"Effect of {factor} (mean and 95 % interval per level; a mean of fewer than 3 runs has no bar)")
    fig.savefig(path, dpi=90)
    plt.close(fig)


def cells_figure(rows: Sequence[Mapping[str, Any]], path: Path) -> None:
    """One bar per cell and group: its No Docking and Good Docking shares with their Wilson intervals."""
    plt = _pyplot()
    labels = [f"{r['cell']} · {r['group']}" for r in rows]
    fig, ax = plt.subplots(figsize=(9, 1.2 + 0.32 * len(rows)), constrained_layout=True)
    y = np.arange(len(rows))
    for off, key, colour in ((-0.17, "no_docking", "tab:red"), (0.17, "good_docking", "tab:green")):
        p = np.array([r[key]["p"] for r in rows], dtype=float)
        err = np.vstack([p - np.array([r[key]["low"] for r in rows]), np.array([r[key]["high"] for r in rows]) - p])
        ax.barh(y + off, p, height=0.32, color=colour, alpha=0.6, xerr=np.nan_to_num(err), capsize=2,
                label=key.replace("_", " ").capitalize())
    ax.set_yticks(y, labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel("share of the cell's runs (95 % Wilson interval)")
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=8, loc="lower right")
    fig.savefig(path, dpi=90)
    plt.close(fig)


def learn_cells_figure(cells: Sequence[str], values: Mapping[str, Sequence[float]],
                       summaries: Sequence[Mapping[str, Any]], title: str, path: Path) -> None:
    """One row per cell of a study of learning runs: each run's value of one measure (a dot), the mean with its 95 %
    t interval, and the median (a bar)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(9, 1.2 + 0.4 * len(cells)), constrained_layout=True)
    y = np.arange(len(cells))
    for i, c in enumerate(cells):
        v = np.array([x for x in values[c] if not np.isnan(x)], dtype=float)
        ax.scatter(v, np.full(v.size, i + 0.15), s=14, color="tab:gray", alpha=0.7, label="a run" if i == 0 else None)
    mean = np.array([r["mean"] for r in summaries], dtype=float)
    err = np.vstack([np.nan_to_num(mean - np.array([r["low"] for r in summaries], dtype=float)),
                     np.nan_to_num(np.array([r["high"] for r in summaries], dtype=float) - mean)])
    ax.errorbar(mean, y, xerr=err, fmt="o", capsize=4, color="tab:blue", label="mean, 95 % interval")
    ax.scatter([r["median"] for r in summaries], y, marker="|", s=200, color="tab:red", label="median")
    ax.set_yticks(y, list(cells), fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel(title)
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=8, loc="best")
    fig.savefig(path, dpi=90)
    plt.close(fig)
