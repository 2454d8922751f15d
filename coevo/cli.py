"""The ``coevo`` command line.

Every sub-command catches :class:`~coevo.errors.CoevoError`, prints
``ErrorType: message`` to stderr and exits with status 2; a bug still shows its
traceback.  Logging handlers are configured here and nowhere else.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any

from coevo.config import GAConfig, build
from coevo.errors import CoevoError, ConfigError
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["main"]

EXIT_ERROR = 2


def _read_rules(path: str | None, behaviour: Behaviour) -> Any:
    if path is None:
        return None
    from coevo.policy.text import read_rule_file

    return read_rule_file(Path(path), behaviour)


def seed_arg(text: str) -> int:
    """A seed: a whole number from 0 to 2**63 - 1 (numpy's generators refuse negative seeds)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid seed {text!r}: give a whole number >= 0") from None
    if not 0 <= v < 2**63:
        raise argparse.ArgumentTypeError(f"invalid seed {v}: give a whole number from 0 to 2**63 - 1")
    return v


def _settings(values: list[str] | None, model: type) -> dict[str, Any]:
    """``--set name=value`` pairs for a settings model (values parsed as JSON when they can be)."""
    out: dict[str, Any] = {}
    for item in values or []:
        if "=" not in item:
            raise ConfigError(f"--{'world' if model is WorldConfig else 'ga'} {item!r}: expected name=value")
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out


def _configs(args: argparse.Namespace) -> tuple[WorldConfig, GAConfig]:
    world = build(WorldConfig, _settings(args.world, WorldConfig))
    ga_over = _settings(args.ga, GAConfig)
    for name in ("generations", "population", "episodes"):
        if getattr(args, name, None) is not None:
            ga_over[name] = getattr(args, name)
    return world, build(GAConfig, ga_over)


def _add_settings(p: argparse.ArgumentParser) -> None:
    p.add_argument("--generations", type=int, help="generations (default 50)")
    p.add_argument("--population", type=int, help="population size (default 50)")
    p.add_argument("--episodes", type=int, help="evaluation episodes per individual (default 90)")
    p.add_argument("--world", action="append", metavar="NAME=VALUE", help="world setting, e.g. target_speed=3 (repeatable)")
    p.add_argument("--ga", action="append", metavar="NAME=VALUE", help="GA setting, e.g. mutation_rate=0.05 (repeatable)")
    p.add_argument("--initial", dest="ga", action="append", type=lambda v: f"initial={v}", metavar="default|random",
                   help="how Tracking and Docking start: their shipped direction-only rule sets (default) or random "
                        "rule sets; the Executive always starts random (the same as --ga initial=...)")
    p.add_argument("--mutation-model", dest="ga", action="append", type=lambda v: f"mutation_model={v}", metavar="fm|gm|fh|gh",
                   help="mutation model (default fm; the same as --ga mutation_model=...; parameters: see README)")


def _add_max_lead(p: argparse.ArgumentParser) -> None:
    p.add_argument("--max-lead", default="1", metavar="N|off",
                   help="pacing: start a generation only when every partner is at most N generations behind (default 1; off = unpaced)")


def cmd_learn(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from coevo.runs.learn import learn

    behaviour = Behaviour(args.behaviour)
    world, ga = _configs(args)
    partners = {b.value: _read_rules(f, b) for b, f in ((Behaviour.TRACKING, args.tracking), (Behaviour.DOCKING, args.docking)) if f}
    seed_policy = _read_rules(args.seed_policy, behaviour)
    if args.measure_epochs < 1:
        raise ConfigError(f"--measure-epochs must be at least 1, got {args.measure_epochs}")
    out = Path(args.out) if args.out else Path("runs") / f"learn-{behaviour.value}-seed{args.seed}-{time.strftime('%Y%m%d-%H%M%S')}"
    columns = (
        TextColumn(f"[bold]{behaviour.value}[/]"), BarColumn(), TextColumn("gen {task.completed}/{task.total}"),
        TextColumn("{task.fields[info]}"), TimeElapsedColumn(), TimeRemainingColumn(),
    )
    with Progress(*columns, disable=args.quiet, transient=False) as bar:
        task = bar.add_task("learn", total=ga.generations, info="")

        def show(rep: Any) -> None:
            info = f"best {rep.best_fitness:.3f} (so far {rep.best_so_far:.3f}) mean {rep.population_mean:.3f}"
            bar.update(task, advance=1, info=info)

        res = learn(
            behaviour, world=world, ga=ga, seed=args.seed, out_dir=out, partners=partners,
            seed_policy=seed_policy, measure_epochs=args.measure_epochs, on_generation=show,
            history=Path(args.history) if args.history else None, rate=args.rate,
        )
    m = res.measures
    print(f"run directory: {res.out_dir}")
    print(f"time: {res.seconds:.1f} s; best fitness {m['best_fitness']:.3f}")
    keys = ["quality_tracking", "successful_docking", "docking_success_rate", "average_epoch_length", "dock_choice"]
    if "docking_from_random_starts" in m:
        keys.append("docking_from_random_starts")
    print("measures: " + ", ".join(f"{k} {m[k]:.1f}" for k in keys))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from coevo.tasks.fuel.bench import bench

    world = build(WorldConfig, _settings(args.world, WorldConfig))
    if args.lanes < 1 or args.rules < 1 or args.rules > 64 or args.repeats < 1:
        raise ConfigError(f"need lanes >= 1, 1 <= rules <= 64, repeats >= 1; got lanes={args.lanes} rules={args.rules} repeats={args.repeats}")
    behaviour = Behaviour(args.behaviour)
    policy = _read_rules(args.policy, behaviour)
    res = bench(world=world, behaviour=behaviour, lanes=args.lanes, rules=args.rules, repeats=args.repeats,
                baseline_seconds=args.baseline_seconds, seed=args.seed, policy=policy)
    if args.json:
        print(json.dumps(res.as_dict(), indent=2))
    else:
        print(f"batched ({res.lanes} lanes, {res.rules_per_policy} rules): {res.batched_steps_per_s / 1e6:.3f} M robot-steps/s")
        print(f"plain one-episode loop:                {res.baseline_steps_per_s / 1e6:.3f} M robot-steps/s")
        print(f"ratio {res.ratio:.1f}x; batch peak {res.batch_peak_mb:.0f} MB (tracemalloc), process max RSS {res.max_rss_mb:.0f} MB")
    return 0


def _router_listen(args: argparse.Namespace) -> list[str]:
    """Where a router listens (default: loopback); a broker run as a client of another router only connects."""
    if args.mode != "router":
        return [f"(a {args.mode} of {', '.join(args.connect or [args.config or '?'])})"]
    if not args.listen and not args.config:
        args.listen = ["tls/127.0.0.1:7447" if args.tls_ca else "tcp/127.0.0.1:7447"]
    return args.listen or ["(from " + args.config + ")"]


def cmd_router(args: argparse.Namespace) -> int:
    """A plain Zenoh router (no store): a second site's meeting point, joined to the broker with --connect."""
    from coevo.bus.session import config_from_args, open_session, sigterm_as_exit

    listen = _router_listen(args)
    conf = config_from_args(args)
    sigterm_as_exit()
    try:  # SIGTERM at any moment, even while the session opens, is a clean stop
        with open_session(conf, what="router"):
            print(f"coevo router listening on {', '.join(listen)}; joined to {', '.join(args.connect or ['-'])}", flush=True)
            while True:
                time.sleep(3600)
    except KeyboardInterrupt:
        pass
    return 0


def cmd_broker(args: argparse.Namespace) -> int:
    from coevo.broker.server import Broker
    from coevo.bus.session import config_from_args, sigterm_as_exit

    listen = _router_listen(args)
    if args.inbox_mb <= 0:
        raise ConfigError(f"--inbox-mb must be positive, got {args.inbox_mb}")
    conf = config_from_args(args)
    sigterm_as_exit()
    try:  # SIGTERM at any moment, even while the store loads, is a clean stop
        with Broker(conf, Path(args.data_dir), inbox_bytes=int(args.inbox_mb * (1 << 20))) as broker:
            logging.getLogger("coevo.broker").info("broker listening on %s, store in %s", listen, args.data_dir)
            print(f"coevo broker listening on {', '.join(listen)}; store in {args.data_dir}", flush=True)
            broker.serve_forever()
    except KeyboardInterrupt:
        pass
    return 0


def cmd_worker(args: argparse.Namespace) -> int:
    from coevo.agents.pacing import parse_max_lead
    from coevo.agents.worker import Worker
    from coevo.bus import keys
    from coevo.bus.session import config_from_args, sigterm_as_exit
    from coevo.tasks import get_task

    world, ga = _configs(args)
    behaviour = Behaviour(args.behaviour)
    keys.check_id("run id", args.run)
    worker_id = args.worker_id or f"{behaviour.value}-{args.seed}"
    out = Path(args.out) if args.out else Path("runs") / args.run / "workers" / behaviour.value
    sigterm_as_exit()
    w = Worker(task=get_task("fuel"), behaviour=behaviour, regime=args.regime, run=args.run, worker_id=worker_id, seed=args.seed,
               world=world, ga=ga, out_dir=out, conf=config_from_args(args), model=args.model,
               max_lead=parse_max_lead(args.max_lead), resume=args.resume, final_sync=args.final_sync)
    try:
        curve = w.run()
    except KeyboardInterrupt:
        return 130
    print(f"{worker_id}: {len(curve)} generations, best so far {curve[-1].best_so_far if curve else float('nan'):.3f}")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from rich.live import Live

    from coevo.agents.pacing import parse_max_lead
    from coevo.bus.status import PlainStatus, status_table
    from coevo.runs.local import read_run_json, run_local

    if args.resume:
        given = [f"--{n}" for n in ("regime", "run", "generations", "population", "episodes", "world", "ga", "seed", "model")
                 if getattr(args, n, None) is not None]
        if given or args.max_lead is not None:
            raise ConfigError(f"--resume takes every setting from the run's run.json; drop {', '.join(given or ['--max-lead'])}")
        meta = read_run_json(Path(args.resume))
        run_id, root, regime = meta["run"], Path(args.resume).parent, meta["regime"]
        settings = dict(world=meta["world"], ga=meta["ga"], seed=meta["seed"], model=meta["model"], max_lead=meta["max_lead"])
    else:
        world, ga = _configs(args)
        regime = args.regime or "independent"
        run_id = args.run or f"{regime}-{time.strftime('%Y%m%d-%H%M%S')}"
        root = Path(args.root)
        settings = dict(world=world, ga=ga, seed=args.seed or 0, model=args.model or "best",
                        max_lead=parse_max_lead("1" if args.max_lead is None else args.max_lead))

    tty = sys.stdout.isatty()
    plain = PlainStatus()
    with Live(auto_refresh=False, transient=False) if tty else contextlib.nullcontext() as live:
        def show(board: Any) -> None:
            if args.quiet:
                return
            if tty:
                live.update(status_table(board, f"run {run_id} ({regime})"), refresh=True)
            else:  # a log or a pipe: plain lines, no box drawing, no redraws
                for line in plain.lines(board):
                    print(line, flush=True)

        summary = run_local(regime=regime, run=run_id, root=root, measure_epochs=args.measure_epochs, on_status=show,
                            log_level=args.log_level, resume=bool(args.resume), **settings)
    print(f"run directory: {root / run_id} ({summary['seconds']:.1f} s)")
    if "measures" in summary:
        m = summary["measures"]
        print("combined robot: " + ", ".join(f"{k} {m[k]:.1f}" for k in
              ("quality_tracking", "dock_choice", "docking_success_rate", "successful_docking", "average_epoch_length",
               "executive_payoff")))
    return 130 if summary["interrupted"] else 0


def cmd_compare(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from coevo.agents.pacing import parse_max_lead
    from coevo.experiments.compare import CompareSpec, prepare, run_all, write_report
    from coevo.experiments.compare.experiment import default_jobs, replicates

    world, ga = _configs(args)
    rates = {} if args.rates is None else {"rates": tuple(args.rates)}
    spec = CompareSpec.make(regimes=tuple(args.regimes), **rates, runs=args.runs, seed=args.seed, model=args.model,
                            max_lead=parse_max_lead(args.max_lead), measure_epochs=args.measure_epochs, world=world, ga=ga)
    jobs = default_jobs() if args.jobs is None else args.jobs
    if jobs < 1:
        raise ConfigError(f"--jobs must be at least 1, got {jobs}")
    out = Path(args.out) if args.out else Path("runs") / f"compare-{time.strftime('%Y%m%d-%H%M%S')}"
    t0 = time.time()
    if args.report_only:
        if not (out / "compare.json").exists():
            raise ConfigError(f"--report-only: {out} holds no comparison (no compare.json)")
        todo = prepare(out, spec, resume=True)
        print(f"{len(todo)} runs unfinished; reporting on the rest")
    else:
        todo = prepare(out, spec, resume=args.resume)
        total = len(replicates(spec))
        print(f"comparison in {out}: {total - len(todo)} of {total} runs already done, {len(todo)} to run, {jobs} at a time",
              flush=True)
        columns = (TextColumn("[bold]compare[/]"), BarColumn(), TextColumn("{task.fields[info]}"),
                   TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn())
        with Progress(*columns, disable=args.quiet) as bar:
            task = bar.add_task("compare", total=1, info="")

            def show(p: Any) -> None:
                bar.update(task, total=p.total_generations, completed=p.done_generations,
                           info=f"runs {p.runs_done}/{p.runs_total}" + (f", {len(p.failed)} failed" if p.failed else ""))

            try:
                failed = run_all(out, spec, todo, jobs=jobs, on_progress=show)
            except KeyboardInterrupt:
                print(f"interrupted; finished runs are kept: continue with the same command and --resume --out {out}",
                      file=sys.stderr)
                return 130
        if failed:
            print(f"{len(failed)} runs failed ({', '.join(failed)}); their logs are in {out / 'logs'}. "
                  f"Run again with --resume to retry them.", file=sys.stderr)
    results = write_report(out, spec, elapsed=None if args.report_only else time.time() - t0)
    print(f"report: {out / 'report.md'}")
    for r, counts in results["table1"].items():
        print(f"  {r}: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
    print(results["verdict"])
    return 1 if results["runs_finished"] < results["runs_expected"] and not args.report_only else 0


def cmd_status(args: argparse.Namespace) -> int:
    from coevo.bus import keys
    from coevo.bus.session import config_from_args, open_session, sigterm_as_exit
    from coevo.bus.status import PlainStatus, StatusBoard, status_table

    keys.check_id("run id", args.run)
    sigterm_as_exit()
    end = time.monotonic() + args.duration if args.duration else None
    with open_session(config_from_args(args), what="status session") as s:
        board = StatusBoard(s, args.run, stall=args.stall)
        try:
            if args.json:
                while end is None or time.monotonic() < end:
                    board.changed.wait(args.every)
                    board.changed.clear()
                    print(board.json_line(), flush=True)
            elif not sys.stdout.isatty():  # a log or a pipe: one plain line per worker when it changes
                plain = PlainStatus()
                while end is None or time.monotonic() < end:
                    board.changed.wait(args.every)
                    board.changed.clear()
                    for line in plain.lines(board):
                        print(line, flush=True)
            else:
                from rich.live import Live

                with Live(auto_refresh=False) as live:
                    while end is None or time.monotonic() < end:
                        board.changed.wait(args.every)
                        board.changed.clear()
                        live.update(status_table(board, f"run {args.run} at {time.strftime('%H:%M:%S')}"), refresh=True)
        except KeyboardInterrupt:
            pass
        finally:
            board.close()
    return 0


def cmd_chaos(args: argparse.Namespace) -> int:
    from coevo.runs.chaos import ChaosPlan, run_chaos, summary_lines

    world, ga = _configs(args)
    plan = ChaosPlan(faults=args.faults, kinds=tuple(args.kinds), gap=tuple(args.gap), down=tuple(args.down), seed=args.seed)
    run_id = args.run or f"chaos-{args.regime}-{time.strftime('%Y%m%d-%H%M%S')}"

    def say(text: str) -> None:
        if not args.quiet:
            print(f"{time.strftime('%H:%M:%S')} {text}", flush=True)

    report = run_chaos(regime=args.regime, run=run_id, root=Path(args.root), world=world, ga=ga, seed=args.seed,
                       plan=plan, model=args.model, measure_epochs=args.measure_epochs, on_event=say, log_level=args.log_level)
    for line in summary_lines(report):
        print(line)
    print(f"report: {Path(args.root) / run_id / 'chaos.json'}")
    return 0 if report["complete"] else 1


def cmd_check(args: argparse.Namespace) -> int:
    from coevo.runs.check import check_run

    res = check_run(Path(args.run_dir), replay=not args.no_replay)
    for beh, facts in sorted((k, v) for k, v in res.facts.items() if isinstance(v, dict)):
        print(f"{beh}: {facts['generations']} generations, {facts['published']} versions published, "
              f"{facts['adoptions']} adoptions")
    if res.ok:
        print("complete" + (" (replay exact)" if res.facts.get("replayed") else ""))
        return 0
    for p in res.problems:
        print(f"PROBLEM: {p}")
    return 1


def cmd_replay(args: argparse.Namespace) -> int:
    from coevo.runs.replay import replay

    results = replay(Path(args.run_dir))
    ok = True
    for r in results:
        ok &= r.reproduced
        verdict = "reproduced exactly" if r.reproduced else f"DIFFERS at generation {r.first_mismatch}: {r.detail}"
        print(f"{r.behaviour}: {r.generations} generations {verdict}")
    return 0 if ok else 1


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="coevo", description="Co-evolve robot behaviours with SAMUEL-style rule GAs.")
    parser.add_argument("--log-level", default="WARNING", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("learn", help="one behaviour learns offline (no network)")
    p.add_argument("--behaviour", required=True, choices=[b.value for b in Behaviour])
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--out", help="run directory to create (default runs/learn-BEHAVIOUR-seedN-TIME)")
    p.add_argument("--tracking", help="Tracking rule file (for --behaviour executive)")
    p.add_argument("--docking", help="Docking rule file (for --behaviour executive)")
    p.add_argument("--seed-policy", help="start the population from this rule file instead of the behaviour's default (or random) rules")
    p.add_argument("--history", metavar="RUN_DIR", help="executive: adopt the Tracking/Docking policies stored in a finished run, in step")
    p.add_argument("--rate", type=float, default=1.0, help="with --history: partner generations per executive generation (default 1)")
    p.add_argument("--measure-epochs", type=int, default=100, help="fresh epochs for the final measures")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    _add_settings(p)
    p.set_defaults(func=cmd_learn)

    p = sub.add_parser("bench", help="robot-steps/s of the batched world vs a plain one-episode pymunk loop")
    p.add_argument("--behaviour", default="tracking", choices=["tracking", "docking"])
    p.add_argument("--lanes", type=int, default=4500, help="episodes run at once (default 50 x 90)")
    p.add_argument("--rules", type=int, default=32, help="rules per policy (evolved size)")
    p.add_argument("--policy", help="a rule file to drive every lane instead of random rule sets")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--baseline-seconds", type=float, default=3.0)
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--world", action="append", metavar="NAME=VALUE")
    p.add_argument("--json", action="store_true", help="print both figures and their ratio as JSON")
    p.set_defaults(func=cmd_bench)

    from coevo.bus.session import add_connection_args

    p = sub.add_parser("broker", help="the Zenoh router workers meet at, plus the policy store")
    add_connection_args(p, default_mode="router")
    p.add_argument("--data-dir", default="runs", help="where the store keeps each run's policies (default runs/)")
    p.add_argument("--inbox-mb", type=float, default=64.0,
                   help="policy messages waiting to be stored at most (default 64 MB); a flood beyond is dropped and counted")
    p.set_defaults(func=cmd_broker)

    p = sub.add_parser("router", help="a plain Zenoh router, no store: another site's meeting point (--connect to the broker)")
    add_connection_args(p, default_mode="router")
    p.set_defaults(func=cmd_router)

    p = sub.add_parser("worker", help="one behaviour's GA as its own process on the bus")
    p.add_argument("--behaviour", required=True, choices=[b.value for b in Behaviour])
    p.add_argument("--regime", required=True, choices=["mutual", "independent"])
    p.add_argument("--run", required=True, help="run id (letters, digits, _ - .)")
    p.add_argument("--worker-id", help="default BEHAVIOUR-SEED")
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--model", default="best", choices=["best", "current", "recent"], help="how partners are modelled (default best so far)")
    p.add_argument("--out", help="worker directory (default runs/RUN/workers/BEHAVIOUR)")
    p.add_argument("--resume", action="store_true",
                   help="continue from the checkpoint in --out (or start afresh if there is none yet)")
    p.add_argument("--final-sync", type=float, default=30.0, metavar="SECONDS",
                   help="at the end, wait this long for the broker's store to hold every published version (default 30)")
    _add_max_lead(p)
    _add_settings(p)
    add_connection_args(p)
    p.set_defaults(func=cmd_worker)

    p = sub.add_parser("run", help="broker + three workers on this machine, with a live status")
    p.add_argument("--regime", choices=["mutual", "independent"], help="default independent")
    p.add_argument("--run", help="run id (default REGIME-TIME)")
    p.add_argument("--root", default="runs", help="parent of the run directory (default runs/)")
    p.add_argument("--resume", metavar="RUN_DIR", help="continue this run from its workers' checkpoints, with its settings")
    p.add_argument("--seed", type=seed_arg, help="default 0")
    p.add_argument("--model", choices=["best", "current", "recent"], help="default best")
    p.add_argument("--measure-epochs", type=int, default=100)
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--max-lead", metavar="N|off",
                   help="pacing: start a generation only when every partner is at most N generations behind (default 1; off = unpaced)")
    _add_settings(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("compare", help="many real runs per regime: Table 1, learning curves, rank tests, verdict")
    p.add_argument("--regimes", nargs="+", default=["mutual", "independent"], metavar="REGIME",
                   help="regimes to compare (default: mutual independent); independent-offline: the Executive "
                        "learns on the independent runs' recorded Tracking/Docking histories, at each --rates")
    p.add_argument("--rates", nargs="+", type=float, metavar="R",
                   help="independent-offline: rates of asynchrony, partner generations per Executive generation "
                        "(default 0.25 0.5 1 2 4)")
    p.add_argument("--runs", type=int, default=10, help="runs per regime (default 10, as in the report)")
    p.add_argument("--out", help="comparison directory (default runs/compare-TIME)")
    p.add_argument("--resume", action="store_true", help="continue the comparison in --out, keeping its finished runs")
    p.add_argument("--report-only", action="store_true", help="only (re)write the report from the finished runs in --out")
    p.add_argument("--jobs", type=int, help="runs at once (default: one per two cores; an offline Executive counts half)")
    p.add_argument("--seed", type=seed_arg, default=0, help="base seed; run i of every regime uses seed + 1000 i")
    p.add_argument("--model", default="best", choices=["best", "current", "recent"])
    p.add_argument("--measure-epochs", type=int, default=100, help="fresh epochs measuring each final robot")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    _add_max_lead(p)
    _add_settings(p)
    p.set_defaults(func=cmd_compare)

    from coevo.experiments.evolvability.command import add_parser as add_evolvability

    add_evolvability(sub)

    from coevo.show.command import add_parser as add_show

    add_show(sub)

    p = sub.add_parser("replay", help="re-run a finished run in one process from its adoption log")
    p.add_argument("run_dir")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("chaos", help="a whole run while random processes are killed and restarted; then check it")
    p.add_argument("--regime", default="mutual", choices=["mutual", "independent"])
    p.add_argument("--run", help="run id (default chaos-REGIME-TIME)")
    p.add_argument("--root", default="runs", help="parent of the run directory (default runs/)")
    p.add_argument("--seed", type=seed_arg, default=0, help="seeds the workers and the choice of faults")
    p.add_argument("--model", default="best", choices=["best", "current", "recent"])
    p.add_argument("--faults", type=int, default=8, help="faults to inject (default 8)")
    p.add_argument("--kinds", nargs="+", default=["kill-worker", "kill-broker", "pause-worker"], metavar="KIND",
                   help="kill-worker kill-broker pause-worker (default all three)")
    p.add_argument("--gap", type=float, nargs=2, default=[1.0, 4.0], metavar=("MIN", "MAX"),
                   help="seconds between faults (default 1 4)")
    p.add_argument("--down", type=float, nargs=2, default=[0.5, 3.0], metavar=("MIN", "MAX"),
                   help="seconds a killed process stays down or a paused one stopped (default 0.5 3)")
    p.add_argument("--measure-epochs", type=int, default=20)
    p.add_argument("--quiet", action="store_true")
    _add_settings(p)
    p.set_defaults(func=cmd_chaos)

    p = sub.add_parser("check", help="is a finished run directory complete? (every generation, every version stored, replay)")
    p.add_argument("run_dir")
    p.add_argument("--no-replay", action="store_true", help="skip re-running the GAs")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("status", help="follow a run's workers")
    p.add_argument("--run", required=True)
    p.add_argument("--json", action="store_true", help="one JSON object per update")
    p.add_argument("--stall", type=float, default=3.0,
                   help="seconds without a heartbeat before a live worker counts as stalled (default 3; workers beat every second)")
    p.add_argument("--every", type=float, default=0.5, help="refresh period in seconds (default 0.5; changes show at once)")
    p.add_argument("--duration", type=float, help="stop after this many seconds (default: until Ctrl-C)")
    add_connection_args(p)
    p.set_defaults(func=cmd_status)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    try:
        return int(args.func(args))
    except CoevoError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
