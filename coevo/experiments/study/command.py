"""``coevo study``: factors × seeds, each cell a regime comparison (or, with ``--learn``, a set of learning runs), on
``--jobs`` or ``--cluster``, with one report.

Registered by :mod:`coevo.cli`; the declaration is :mod:`.declaration`, the folder and the runs :mod:`.experiment`,
the report :mod:`.report`.  See docs/studies.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from coevo.console import ProgressBar, add_max_lead, add_settings, count_arg, pairs, seed_arg
from coevo.config import MODELS
from coevo.errors import ConfigError, RunDirError
from coevo.replicates.flags import add_backend_flags, backend_of, check_backend_flags

if TYPE_CHECKING:
    from coevo.experiments.study.declaration import StudySpec
    from coevo.replicates.runner import Progress

__all__ = ["configure_study", "cmd_study"]


def _settings_given(args: argparse.Namespace) -> dict[str, Any]:
    """The settings flags given on the command line, by their study names (not given: left out)."""
    from coevo.tasks import DEFAULT_TASK, get_task, split_settings
    from coevo.experiments.study.declaration import task_learning

    given: dict[str, Any] = {}
    for flag, name in (("runs", "runs"), ("model", "model"), ("measure_epochs", "measure_epochs"), ("learn", "learn")):
        if getattr(args, flag) is not None:
            given[name] = getattr(args, flag)
    if args.max_lead is not None:
        given["max_lead"] = "off" if args.max_lead.value is None else args.max_lead.value
    for flag in ("generations", "population", "episodes"):
        if getattr(args, flag) is not None:
            given[f"ga.{flag}"] = getattr(args, flag)
    task = task_learning(args.learn) if args.learn is not None else get_task(DEFAULT_TASK)  # comparisons: fuel's
    world, ga = split_settings(task, pairs(args.world, "world"), pairs(args.ga, "ga"))
    given |= {f"ga.{k}": v for k, v in ga.items()}  # --ga docking_sensors=... is the world setting it is now
    given |= {f"world.{k}": v for k, v in world.items()}
    return given


def _declaration(args: argparse.Namespace, out: Path | None) -> StudySpec:
    """The study the command line declares; with --resume (or --report-only) and nothing declared, the one in --out."""
    from coevo.experiments.study.declaration import declare, read_toml
    from coevo.experiments.study.experiment import held_declaration

    settings = _settings_given(args)
    if args.declaration is None and not args.factor and not settings and args.seed is None:
        if out is not None and (args.resume or args.report_only):
            held = held_declaration(out)
            if held is None:
                raise RunDirError(f"--out {str(out)!r} holds no study (no study.json)")
            return held
    toml = read_toml(Path(args.declaration)) if args.declaration is not None else None
    return declare(toml=toml, source=f"study file {args.declaration!r}", factors=args.factor or [],
                   settings=settings, seed=args.seed)


def cmd_study(args: argparse.Namespace) -> int:
    from coevo.experiments.compare.experiment import default_jobs
    from coevo.experiments.study.declaration import study_cells
    from coevo.experiments.study.experiment import SEP, check_cells, held_declaration, mark_complete, prepare_study, run_study
    from coevo.replicates.backends import ClusterLost

    given_out = Path(args.out) if args.out else None
    if (args.resume or args.report_only) and given_out is None:
        raise ConfigError("--resume and --report-only need --out: the study's folder")
    if args.force and not args.resume:
        raise ConfigError("--force goes with --resume (continue a study that ran on other code)")
    spec = _declaration(args, given_out)  # every cell checked before anything is opened or written
    check_backend_flags(args)
    out = given_out or Path("runs") / f"study-{spec.name}-{time.strftime('%Y%m%d-%H%M%S')}"
    t0 = time.time()
    if args.report_only:
        held = held_declaration(out)
        if held is None:
            raise RunDirError(f"--report-only: {str(out)!r} holds no study (no study.json)")
        if held != spec:
            raise RunDirError(f"--report-only: {str(out)!r} holds a different study; give its declaration, or none")
        check_cells(out, study_cells(spec), report_only=True)  # before anything is changed
        (out / "complete.json").unlink(missing_ok=True)
    else:
        backend = backend_of(args, default_jobs=default_jobs())
        try:
            the_cells = prepare_study(out, spec, resume=args.resume, force=args.force)
        except BaseException:
            backend.close()
            raise
        from coevo.experiments.study.experiment import study_jobs

        jobs = study_jobs(out, the_cells)
        done = {j.name for j in jobs if j.finished(out)}
        print(f"study {spec.name} in {out}: {len(the_cells)} cells, {len(done)} of {len(jobs)} runs already done, "
              f"{len(jobs) - len(done)} to run, {backend.description}", flush=True)
        cell_of = {j.name: j.name.split(SEP, 1)[0] for j in jobs}
        per_cell: dict[str, int] = {}
        for name in cell_of:
            per_cell[cell_of[name]] = per_cell.get(cell_of[name], 0) + 1

        def info(ok: set[str]) -> str:
            cells_done = sum(1 for c, n in per_cell.items() if sum(1 for j in ok if cell_of[j] == c) == n)
            return f"cells {cells_done}/{len(per_cell)}"

        finished = set(done)
        unit = "runs" if spec.learn is not None else "worker generations"  # a learning run shows nothing until done
        with ProgressBar("study", total=1, unit=unit, quiet=args.quiet) as bar:
            def show(p: Progress) -> None:
                finished.update(o.name for o in p.outcomes if o.ok)
                bar.update(p.done, p.total, info=f"{info(finished)}, {p.info}")

            try:
                prog = run_study(out, the_cells, backend=backend, on_progress=show)
            except KeyboardInterrupt:
                print(f"interrupted; finished runs are kept: continue with --resume --out {out}", file=sys.stderr)
                return 130
            except ClusterLost as exc:
                print(f"{exc}; finished runs are kept: continue with --resume --out {out}", file=sys.stderr)
                return 3
        if prog.failed:
            print(f"{len(prog.failed)} runs failed; their logs are in {out / 'logs'}. Run again with --resume to "
                  "retry them.", file=sys.stderr)
            for name, why in prog.failed.items():
                print(f"  {name}: {why}", file=sys.stderr)
    from coevo.experiments.study.learn_report import write_learn_report  # scipy.stats: imported once it is needed,
    from coevo.experiments.study.report import write_report  # not before a bad flag is refused (1 CPU-s)

    report = write_report if spec.learn is None else write_learn_report  # a study of learning runs: its own report
    results = report(out, spec, elapsed=None if args.report_only else time.time() - t0)
    complete = results["runs_finished"] == results["runs_expected"]
    if complete:
        mark_complete(out, spec, runs=results["runs_expected"])
    print(f"report: {out / 'report.md'} ({results['runs_finished']} of {results['runs_expected']} runs"
          f"{'' if complete else '; the study is not complete: --resume runs the rest'})")
    _print_cells(results, learn=spec.learn is not None)
    if results.get("caveat"):  # the smoke-test warning with the verdict, as report.md and the dashboard show it
        print(results["caveat"])
    print(results["verdict"])
    return 0 if complete or args.report_only else 1


def _print_cells(results: dict[str, Any], *, learn: bool) -> None:
    """A line per cell (and group) with runs: its docking classes, or its behaviour's first measure."""
    for r in results["cell_rows"]:
        if r["n"] and learn:
            key = results["measures"][0]
            m = r["measures"][key]
            print(f"  {r['cell']}: {key} median {m['median']:.1f}, mean {m['mean']:.1f} over {r['n']} runs")
        elif r["n"]:
            nd, gd = r["no_docking"], r["good_docking"]
            print(f"  {r['cell']} · {r['group']}: No Docking {nd['k']}/{r['n']}, Good Docking {gd['k']}/{r['n']}")


def configure_study(p: argparse.ArgumentParser) -> None:
    """``coevo study``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    p.add_argument("declaration", nargs="?", metavar="STUDY_FILE",
                   help="the study's declaration, a TOML file (docs/studies.md); --factor and the settings flags add to it")
    p.add_argument("--factor", action="append", metavar="NAME=V1,V2,...",
                   help="a factor and its levels (repeatable): regime, rate, max_lead, model, runs, measure_epochs, "
                        "ga.NAME, world.NAME; replaces the file's factor or setting of that name")
    p.add_argument("--learn", metavar="BEHAVIOUR",
                   help="every cell a set of 'coevo learn --behaviour BEHAVIOUR' runs (the fuel task's docking or "
                        "tracking, or a behaviour of another installed task that learns with no partner given, e.g. "
                        "pursuer), one per seed, instead of a regime comparison (the file's learn = ...); --world "
                        "names are then its task's; regime, rate, max_lead and model are refused")
    p.add_argument("--runs", type=count_arg(1, 1000), help="runs per regime in every cell (default 10; with --learn: "
                   "seeds per cell)")
    p.add_argument("--model", choices=MODELS, help="partner model of every cell (default best)")
    p.add_argument("--measure-epochs", type=count_arg(1, 100_000), help="fresh epochs measuring each final robot "
                   "(default 100)")
    p.add_argument("--seed", type=seed_arg, help="base seed: each cell's seeds derive from it and the cell "
                   "(default: the file's, else 0)")
    p.add_argument("--out", help="study directory (default runs/study-NAME-TIME)")
    p.add_argument("--resume", action="store_true", help="continue the study in --out (its finished runs kept); "
                   "without a declaration, the one stored there")
    p.add_argument("--report-only", action="store_true", help="only (re)write the report from the finished runs in --out")
    p.add_argument("--force", action="store_true",
                   help="with --resume: continue a study whose cells ran on other code (their code.json) all the same")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_backend_flags(p, jobs_help="runs at once on this machine (default: one per two cores; an offline Executive "
                                   "counts half)")
    add_max_lead(p)
    add_settings(p)
    p.set_defaults(func=cmd_study)
