"""``coevo dynamics RUN_DIR``: a finished run's CIAO matrices and master tournaments, as CSV and PNG in the run.

For every behaviour and every partner it learned against (:mod:`.matrix`), written to ``RUN/dynamics/``:

* ``ciao-LEARNER-PARTNER.csv`` and ``.png``: the learner's published versions (rows, by the generation each was
  published at) against the partner's (columns), each cell the learner's mean payoff on the same fresh episodes;
* ``master-LEARNER-PARTNER.csv`` and ``.png``: each learner version's mean over every partner version, with a 95 %
  t interval over the partner versions (none below three), and the mean over the partner versions published up
  to it (its ancestors, CIAO's lower triangle) beside the mean over all of them.

In a run whose partner model is each generation's best (``--model current`` or ``hall``) the versions played are
every generation's best the partners adopted (their adoption logs), not the bests so far the store holds: what
each side met.

``--generations A:B`` keeps the versions published at generations A to B and, for each behaviour, the one in play
at A (the last published by then).  Only a finished run is read (every worker's ``done.json`` says finished);
every matrix is played before anything is written, and ``RUN/dynamics/`` is replaced whole, so a refusal or a
stop leaves the run as it was.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from coevo.console import ProgressBar, count_arg, seed_arg
from coevo.errors import ConfigError, RunDirError
from coevo.replicates.flags import add_backend_flags, check_backend_flags

__all__ = ["configure_dynamics"]


def configure_dynamics(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", metavar="RUN_DIR", help="a finished coevo run directory, or a folder of them (a comparison, "
                   "a study): each run's dynamics and a summary across them in DIR/dynamics")
    p.add_argument("--episodes", type=count_arg(1, 100_000), default=60,
                   help="fresh episodes per cell, the same for every cell (default 60)")
    p.add_argument("--seed", type=seed_arg, default=1, help="the seed of those episodes (default 1)")
    p.add_argument("--generations", type=generation_range, metavar="A:B",
                   help="only the versions published at generations A to B (and each side's in play at A); "
                        "default the whole run")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_backend_flags(p, jobs_help="with a folder of runs: runs played at a time on this machine (default 2)")
    p.set_defaults(func=cmd_dynamics)


def generation_range(text: str) -> tuple[int, int]:
    """``A:B``, whole numbers with 0 <= A <= B (whether the run has them is checked against the run)."""
    shown = text if len(text) <= 40 else text[:40] + "..."
    parts = text.strip().split(":")
    if len(parts) != 2 or not all(x.strip().isdigit() for x in parts):
        raise argparse.ArgumentTypeError(f"invalid generation range {shown!r}: give A:B, whole numbers, e.g. 0:50")
    a, b = int(parts[0]), int(parts[1])
    if a > b:
        raise argparse.ArgumentTypeError(f"invalid generation range {shown!r}: A must not exceed B")
    return a, b


def _readable(run: Path, generations: tuple[int, int] | None) -> tuple[Any, Any, Any, Any, Any, list[tuple[str, str]],
                                                                      tuple[int, int]]:
    """A run dynamics can play: (settings, task, world, GA settings, paths, pairs, generation span); else the one-line
    refusal that names what is wrong."""
    from coevo.experiments.dynamics.matrix import check_finished, pairs_of, read_run

    settings, task, world, ga, paths = read_run(run)
    pairs = pairs_of(task, settings.regime)
    if not pairs:
        raise ConfigError(f"{run}: in the {settings.regime} regime no behaviour of task {task.name!r} learns "
                          f"against another's policies (behaviours: {', '.join(task.behaviours)}): there is no "
                          "matrix to play")
    check_finished(paths, task, settings.ga.generations)
    span = generations or (0, settings.ga.generations)
    if span[1] > settings.ga.generations:
        raise ConfigError(f"--generations {span[0]}:{span[1]}: run {settings.run} has generations 0 to "
                          f"{settings.ga.generations}")
    return settings, task, world, ga, paths, pairs, span


def cmd_dynamics(args: argparse.Namespace) -> int:
    check_backend_flags(args)
    if not (Path(args.run) / "run.json").exists() and Path(args.run).is_dir():
        return _many(args)
    if args.jobs is not None or args.cluster is not None:
        raise ConfigError(f"--jobs and --cluster are for a folder of runs; {args.run} is one run")
    return _one(args)


def _one(args: argparse.Namespace) -> int:
    from coevo.experiments.dynamics.matrix import DONE, adopted_versions, play_matrix, versions_of, within
    from coevo.rundir.layout import write_json

    settings, task, world, ga, paths, pairs, span = _readable(Path(args.run), args.generations)
    generational = settings.model in ("current", "hall")  # the partners met every generation's best: play those

    def played(b: str) -> Any:
        return adopted_versions(paths, b, task, settings.regime) if generational else versions_of(paths, b)

    versions = {b: within(played(b), *span) for b in {x for pair in pairs for x in pair}}
    final = {b: v.rules[-1] for b, v in versions.items()}
    matrices = []
    with ProgressBar("dynamics", total=sum(len(versions[b].rules) for _, b in pairs), unit="columns",
                     quiet=args.quiet) as bar:
        done = 0
        for a, b in pairs:
            others = {k: final[k] for k in task.partners_needed(a, settings.regime) if k != b}

            def tick(j: int, n: int, first: int = done, what: str = f"{a} with {b}") -> None:
                bar.update(first + j, info=what)

            matrices.append(play_matrix(task, world, ga, versions[a], versions[b], others, episodes=args.episodes,
                                        seed=args.seed, tick=tick))
            done += len(versions[b].rules)
    with replaced_dir(paths.dir / "dynamics") as out:
        for m in matrices:
            written = _write(out, m)
            print(f"{m.learner.behaviour} with {m.partner.behaviour}: {m.fitness.shape[0]} x {m.fitness.shape[1]} "
                  f"versions: {', '.join(written)}")
        write_json(out / DONE, {"episodes": args.episodes, "seed": args.seed, "generations": list(span),
                                "pairs": [list(p) for p in pairs]})
    return 0


def _many(args: argparse.Namespace) -> int:
    """Every run under the folder ``args.run``, each checked before any is played; then the summary."""
    from coevo.experiments.dynamics.across import find_runs, replicates, summarise
    from coevo.replicates.flags import backend_of
    from coevo.replicates.runner import run_replicates

    root = Path(args.run).resolve()
    runs = [r for r in find_runs(root) if r != root]
    read = {r: _readable(r, args.generations) for r in runs}
    spans = {r: read[r][6] for r in runs}
    groups = {r: f"{read[r][0].regime}, model {read[r][0].model}" for r in runs}
    reps = replicates(root, runs, lambda r: {"episodes": args.episodes, "seed": args.seed,
                                             "generations": list(spans[r])})
    with ProgressBar("dynamics", total=len(reps), unit="runs", quiet=args.quiet) as bar:
        prog = run_replicates(reps, root, backend_of(args, default_jobs=2),
                              on_progress=lambda p: bar.update(p.runs_done, info=f"{len(p.failed)} failed"))
    if prog.failed:
        name, why = next(iter(prog.failed.items()))
        raise RunDirError(f"{len(prog.failed)} of {len(reps)} runs' dynamics failed, {name} first: {why} (its log: "
                          f"{root / 'logs' / (name + '.log')}); nothing summarised")
    with replaced_dir(root / "dynamics") as out:
        written = summarise(root, runs, groups, spans, out)
    print(f"{len(runs)} runs ({', '.join(sorted(set(groups.values())))}): {', '.join(written)} in {root / 'dynamics'}")
    return 0


@contextmanager
def replaced_dir(final: Path) -> Iterator[Path]:
    """A staged directory that takes the place of ``final`` (and of whatever it held) only when the block succeeds."""
    import shutil

    from coevo.rundir.layout import staged_dir

    aside = final.with_name(f".{final.name}.old")
    shutil.rmtree(aside, ignore_errors=True)
    with staged_dir(aside) as tmp:
        yield tmp
    if final.exists():
        final.rename(final.with_name(f".{final.name}.older"))
    aside.rename(final)
    shutil.rmtree(final.with_name(f".{final.name}.older"), ignore_errors=True)


def _write(out: Path, m: Any) -> list[str]:
    """The matrix and its master tournament, as CSV and PNG; the files' names."""
    import numpy as np

    from coevo.experiments.dynamics.matrix import interval
    from coevo.rundir.layout import write_csv

    a, b = m.learner.behaviour, m.partner.behaviour
    rows = [{"version": v, "generation": g, **{f"{b}@{gb}": round(float(x), 6) for gb, x in zip(m.partner.generation, row,
                                                                                            strict=True)}}
            for v, g, row in zip(m.learner.version, m.learner.generation, m.fitness, strict=True)]
    write_csv(out / f"ciao-{a}-{b}.csv", rows)
    master = []
    for i, (v, g) in enumerate(zip(m.learner.version, m.learner.generation, strict=True)):
        lo, hi = interval(m.fitness[i])
        ancestors = [j for j, gb in enumerate(m.partner.generation) if gb <= g]
        master.append({"version": v, "generation": g, "mean": round(float(m.fitness[i].mean()), 6),
                       "low95": lo, "high95": hi, "partner_versions": len(m.fitness[i]),
                       "mean_over_ancestors": round(float(np.mean(m.fitness[i, ancestors])), 6) if ancestors else None})
    write_csv(out / f"master-{a}-{b}.csv", master)
    _draw(out, m, master)
    return [f"ciao-{a}-{b}.csv", f"ciao-{a}-{b}.png", f"master-{a}-{b}.csv", f"master-{a}-{b}.png"]


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
