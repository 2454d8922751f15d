"""``coevo cel-experiment``: Appendix B's Figure 3 over live ``coevo cel`` runs (registered by :mod:`coevo.cli`;
the runs are :mod:`.experiment`, the report :mod:`.report`)."""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

from coevo.console import add_settings, count_arg, seed_arg
from coevo.errors import ConfigError
from coevo.replicates.flags import add_backend_flags, check_backend_flags

if TYPE_CHECKING:
    from coevo.rundir.settings import RunSettings

__all__ = ["configure_cel_experiment", "cmd_cel_experiment"]


def _base_settings(args: argparse.Namespace) -> RunSettings:
    """The runs' settings but the seed (a CEL run's RunSettings), checked before anything runs: the flags of
    ``coevo cel`` with its defaults (100 generations, Figure 3's failure at 50, lockstep)."""
    from coevo.cel.settings import CelSettings
    from coevo.config import build
    from coevo.console import given_settings
    from coevo.rundir.settings import RunSettings
    from coevo.cel_service.command import CEL_GENERATIONS, CEL_MAX_LEAD, SCHEDULES

    if args.fail and args.schedule:
        raise ConfigError("give --schedule or --fail events, not both")
    schedule = tuple(args.fail) if args.fail else SCHEDULES[args.schedule or "figure3"]
    k = args.trials_per_generation or CelSettings().trials_per_generation
    cel = build(CelSettings, {"schedule": schedule, "case_base": args.case_base, "trials_per_generation": k, "chunk": k})
    world, ga = given_settings(args, "door")
    ga.setdefault("generations", CEL_GENERATIONS)  # checked once, with the rest, by RunSettings
    return RunSettings.make(run="live", task="door", regime="independent", seed=0, max_lead=CEL_MAX_LEAD,
                            world=world, ga=ga, cel=cel)


def cmd_cel_experiment(args: argparse.Namespace) -> int:
    """Run the live runs that are not finished in ``--out``, then write the report and print its table."""
    from coevo.experiments.cel.experiment import lockstep_equal, read_lockstep, replicates, write_settings, collect
    from coevo.experiments.cel.report import write_report
    from coevo.experiments.common import open_out, run_with_progress

    base = _base_settings(args)
    check_backend_flags(args)
    lockstep = read_lockstep(Path(args.lockstep), bool(args.case_base)) if args.lockstep else None
    out = Path(args.out) if args.out else Path("runs") / f"cel-experiment-{time.strftime('%Y%m%d-%H%M%S')}"
    seeds = list(range(args.first_seed, args.first_seed + args.runs))
    cel = base.block("cel")
    assert cel is not None  # _base_settings gives a CEL run's settings, with its cel block
    spec = {"runs": args.runs, "first_seed": args.first_seed, "generations": base.ga.generations,
            "trials_per_generation": cel.trials_per_generation, "case_base": cel.case_base,
            "schedule": [[g, list(f)] for g, f in cel.schedule],
            "settings": {k: v for k, v in base.model_dump(mode="json").items() if k not in ("run", "seed")}}
    backend = open_out(args, out, "cel-experiment.json", spec, default_jobs=os.cpu_count() or 1)
    write_settings(out, base, seeds)
    reps = replicates(seeds, base.ga.generations)
    print(f"Figure 3, live: {len(reps)} coevo cel runs in {out}, {backend.description}", flush=True)
    t0 = time.time()
    prog = run_with_progress(reps, out, backend, label="cel-experiment", quiet=args.quiet)
    if prog is None:
        return 3
    runs = collect(out, seeds)
    data = write_report(out, runs, spec, wall=time.time() - t0,
                        lockstep=None if lockstep is None else lockstep_equal(runs, lockstep))
    for r in data["table"]:
        rep = "" if r["report"] is None else f"   (report {'over ' if r['key'] == 'end' else ''}{r['report']:.0f} %)"
        print(f"  {r['label']:45s} {r['mean']:5.1f} ± {r['sd']:4.1f} %{rep}")
    print(f"report: {out / 'report.md'}")
    return 1 if prog.failed else 0


def configure_cel_experiment(p: argparse.ArgumentParser) -> None:
    """``coevo cel-experiment``'s arguments (the command line gathers it: :mod:`coevo.cli`)."""
    from coevo.cel_service.command import SCHEDULES, add_cel_flags

    p.add_argument("--runs", type=count_arg(1, 10_000), default=10, help="live runs, one per seed (default 10)")
    p.add_argument("--first-seed", type=seed_arg, default=0, help="seeds first-seed .. first-seed + runs - 1")
    add_cel_flags(p, schedules=[s for s in SCHEDULES if s != "none"])
    p.add_argument("--lockstep", metavar="FILE",
                   help="per-seed curves of the in-process lockstep runs (benchmarks/cel.py's JSON, e.g. "
                        "docs/cel/figure3.json): count the live runs equal to them")
    p.add_argument("--out", help="output directory (default runs/cel-experiment-TIME)")
    p.add_argument("--resume", action="store_true", help="keep the finished runs in --out and run the rest")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_settings(p, generations=100, initial="how the learner starts: the door task's direction-only rule set "
                                               "(default) or random rule sets")
    add_backend_flags(p, jobs_help="runs at once on this machine (default: one per core; a run in lockstep keeps "
                                   "about one core busy)")
    p.set_defaults(func=cmd_cel_experiment)
