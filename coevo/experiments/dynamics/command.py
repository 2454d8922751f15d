"""``coevo dynamics RUN_DIR``: a finished run's CIAO matrices and master tournaments, as CSV and PNG in the run.

For every behaviour and every partner it learned against (:mod:`.matrix`), written to ``RUN/dynamics/``:

* ``ciao-LEARNER-PARTNER.csv`` and ``.png``: the learner's published versions (rows, by the generation each was
  published at) against the partner's (columns), each cell the learner's mean payoff on the same fresh episodes;
* ``master-LEARNER-PARTNER.csv`` and ``.png``: each learner version's mean over every partner version, with a 95 %
  t interval over the partner versions (none below three), and the mean over the partner versions published up
  to it (its ancestors, CIAO's lower triangle) beside the mean over all of them.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from coevo.console import ProgressBar, count_arg, seed_arg
from coevo.errors import ConfigError

__all__ = ["configure_dynamics"]


def configure_dynamics(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", metavar="RUN_DIR", help="a finished coevo run directory")
    p.add_argument("--episodes", type=count_arg(1, 100_000), default=60,
                   help="fresh episodes per cell, the same for every cell (default 60)")
    p.add_argument("--seed", type=seed_arg, default=1, help="the seed of those episodes (default 1)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.set_defaults(func=cmd_dynamics)


def cmd_dynamics(args: argparse.Namespace) -> int:
    from coevo.experiments.dynamics.matrix import pairs_of, play_matrix, read_run, versions_of
    from coevo.rundir.layout import ensure_dir

    settings, task, world, ga, paths = read_run(Path(args.run))
    pairs = pairs_of(task, settings.regime)
    if not pairs:
        raise ConfigError(f"{args.run}: in the {settings.regime} regime no behaviour of task {task.name!r} learns "
                          "against another's policies: there is no matrix to play")
    versions = {b: versions_of(paths, b) for b in {x for pair in pairs for x in pair}}
    final = {b: v.rules[-1] for b, v in versions.items()}
    out = ensure_dir(paths.dir / "dynamics", what="the dynamics' directory")
    with ProgressBar("dynamics", total=sum(len(versions[b].rules) for _, b in pairs), unit="columns",
                     quiet=args.quiet) as bar:
        done = 0
        for a, b in pairs:
            others = {k: final[k] for k in task.partners_needed(a, settings.regime) if k != b}

            def tick(j: int, n: int, first: int = done, what: str = f"{a} with {b}") -> None:
                bar.update(first + j, info=what)

            m = play_matrix(task, world, ga, versions[a], versions[b], others, episodes=args.episodes, seed=args.seed,
                            tick=tick)
            done += len(versions[b].rules)
            written = _write(out, m)
            print(f"{a} with {b}: {m.fitness.shape[0]} x {m.fitness.shape[1]} versions: {', '.join(written)}")
    return 0


def _write(out: Path, m: Any) -> list[str]:
    """The matrix and its master tournament, as CSV and PNG; the files' names."""
    import numpy as np

    from coevo.rundir.layout import write_csv

    a, b = m.learner.behaviour, m.partner.behaviour
    rows = [{"version": v, "generation": g, **{f"{b}@{gb}": round(float(x), 6) for gb, x in zip(m.partner.generation, row,
                                                                                            strict=True)}}
            for v, g, row in zip(m.learner.version, m.learner.generation, m.fitness, strict=True)]
    write_csv(out / f"ciao-{a}-{b}.csv", rows)
    master = []
    for i, (v, g) in enumerate(zip(m.learner.version, m.learner.generation, strict=True)):
        lo, hi = _interval(m.fitness[i])
        ancestors = [j for j, gb in enumerate(m.partner.generation) if gb <= g]
        master.append({"version": v, "generation": g, "mean": round(float(m.fitness[i].mean()), 6),
                       "low95": lo, "high95": hi, "partner_versions": len(m.fitness[i]),
                       "mean_over_ancestors": round(float(np.mean(m.fitness[i, ancestors])), 6) if ancestors else None})
    write_csv(out / f"master-{a}-{b}.csv", master)
    _draw(out, m, master)
    return [f"ciao-{a}-{b}.csv", f"ciao-{a}-{b}.png", f"master-{a}-{b}.csv", f"master-{a}-{b}.png"]


def _interval(x: Any) -> tuple[float | None, float | None]:
    """A 95 % t interval of the mean of ``x``; none below three values (too few for one to hold)."""
    import numpy as np
    from scipy import stats

    if len(x) < 3:
        return None, None
    half = float(stats.t.ppf(0.975, len(x) - 1) * np.std(x, ddof=1) / np.sqrt(len(x)))
    return round(float(np.mean(x)) - half, 6), round(float(np.mean(x)) + half, 6)


def _draw(out: Path, m: Any, master: list[dict[str, Any]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b = m.learner.behaviour, m.partner.behaviour
    fig, ax = plt.subplots(figsize=(6.4, 5.2), dpi=90)
    im = ax.imshow(m.fitness, origin="lower", cmap="viridis", aspect="auto")
    ax.set_xticks(range(len(m.partner.generation)), [str(g) for g in m.partner.generation], fontsize=7)
    ax.set_yticks(range(len(m.learner.generation)), [str(g) for g in m.learner.generation], fontsize=7)
    ax.set_xlabel(f"{b}: generation its version was published at")
    ax.set_ylabel(f"{a}: generation its version was published at")
    ax.set_title(f"CIAO: {a} (current) with {b} (ancestral), mean payoff on {m.episodes} episodes, seed {m.seed}",
                 fontsize=8)
    fig.colorbar(im, ax=ax, label=f"{a}'s mean payoff")
    fig.tight_layout()
    fig.savefig(out / f"ciao-{a}-{b}.png")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=90)
    g = [r["generation"] for r in master]
    ax.plot(g, [r["mean"] for r in master], "o-", label=f"mean over all {len(m.partner.rules)} {b} versions")
    bands = [(x, r["low95"], r["high95"]) for x, r in zip(g, master, strict=True) if r["low95"] is not None]
    if bands:
        ax.fill_between([x for x, _, _ in bands], [lo for _, lo, _ in bands], [hi for _, _, hi in bands], alpha=0.25,
                        label="95 % t interval over those versions")
    anc = [(x, r["mean_over_ancestors"]) for x, r in zip(g, master, strict=True) if r["mean_over_ancestors"] is not None]
    ax.plot([x for x, _ in anc], [y for _, y in anc], "s--", ms=3, label=f"mean over the {b} versions published by then")
    ax.set_xlabel(f"{a}: generation its version was published at")
    ax.set_ylabel(f"{a}'s mean payoff")
    ax.set_title(f"master tournament: each {a} version against every {b} version", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / f"master-{a}-{b}.png")
    plt.close(fig)
