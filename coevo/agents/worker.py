"""``coevo worker``: one behaviour's GA as its own process on the bus.

The worker is three parts, each a context-managed object on one Zenoh session:

* the :class:`~coevo.agents.inbox.Inbox` takes in partner policies and control
  messages, and adopts the newest partner versions between generations;
* the :class:`~coevo.agents.outbox.Outbox` logs and publishes this worker's
  versions and makes sure the broker's store holds every one;
* :class:`Worker` runs the generation loop: adopt, one GA generation against the
  partner models (heartbeating between episode rounds), checkpoint, then publish
  the best so far if it improved, the current best and a heartbeat.

What a worker writes in its directory (``runs/RUN/workers/BEHAVIOUR/``,
:class:`~coevo.rundir.layout.WorkerPaths`):

* ``worker.json``: its settings (a ``--resume`` with other settings is refused);
* ``curve.jsonl``: one line per generation (the learning curve);
* ``adoptions.jsonl``: after how many of its own generations it took which version
  of which partner, with the rules (what ``coevo replay`` needs);
* ``published.jsonl``: every version it published, in full: its outbox, from which
  it republishes whatever the broker's store turns out not to hold;
* ``checkpoint.msgpack``: see :mod:`coevo.agents.checkpoint`;
* ``machines.jsonl``: the machine it ran on, one line per start (:mod:`coevo.rundir.machine`);
* ``best.rules`` and, at the end, ``done.json``.
"""

from __future__ import annotations

import json
import logging
import time
from contextlib import AbstractContextManager
from functools import partial
from pathlib import Path
from typing import IO, Any

from coevo import __version__
from coevo.agents.checkpoint import cut_logs, prepare_dir, resume_problems, resume_state, save_checkpoint
from coevo.agents.inbox import INBOX, Inbox
from coevo.agents.models import PartnerModels, hall_settings
from coevo.agents.outbox import BrokerWatch, Outbox
from coevo.agents.pacing import Pacer
from coevo.bus import keys
from coevo.bus.auth import RunKey
from coevo.bus.messages import PolicyUpdate, Status
from coevo.bus.rejections import Rejections
from coevo.bus.lifecycle import SIGNALLED, Lifecycle, main_of
from coevo.bus.session import Config, Publisher, Session
from coevo.errors import ConfigError, MessageError, ServiceError
from coevo.ga import GA, GenerationReport
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.rundir.layout import WorkerPaths, append_durably, read_jsonl, write_json, write_text
from coevo.rundir.machine import machine
from coevo.rundir.settings import RunSettings
from coevo.tasks import DEFAULT_TASK, saved_settings
from coevo.tasks.base import check_behaviour

__all__ = ["Worker", "run_worker", "INBOX"]

log = logging.getLogger(__name__)

def _saved_meta(meta: dict[str, Any]) -> dict[str, Any]:
    """A worker.json as it is meant today: written before tasks were named (the default task's), or before some
    setting existed or where it is now (:func:`coevo.tasks.saved_settings`)."""
    return saved_settings({"task": DEFAULT_TASK, **meta})


class Worker:
    def __init__(
        self,
        settings: RunSettings,
        *,
        behaviour: str,
        worker_id: str | None = None,
        seed: int | None = None,
        out_dir: Path,
        conf: Config,
        store_timeout: float = 2.0,
        broker_wait: float = 30.0,
        final_sync: float = 30.0,
        confirm_every: float = 2.0,
        heartbeat_every: float = 1.0,
        resume: bool = False,
        run_key: RunKey | None = None,
    ) -> None:
        """One behaviour's worker of the run ``settings`` describe; ``seed`` defaults to the
        behaviour's seed in the run, ``worker_id`` to BEHAVIOUR-SEED.  With ``run_key`` it seals
        everything it sends and accepts only what carries the run's authenticator; without, the
        worker is open (and says so in its log and heartbeats)."""
        self.settings = settings
        self.task = settings.the_task
        self.behaviour = check_behaviour(self.task, behaviour)
        self.regime = settings.regime
        self.run_id = settings.run
        self.seed = settings.worker_seed(self.behaviour) if seed is None else seed
        self.worker_id = keys.check_id("worker id", worker_id or f"{self.behaviour}-{self.seed}")
        self.world = settings.world_config()
        self.ga_cfg = settings.ga
        self.paths = WorkerPaths(Path(out_dir))
        self.conf = conf
        self.models = PartnerModels(self.task, self.behaviour, self.regime, self.seed, kind=settings.model, ga=settings.ga,
                                    world=self.world, **hall_settings(settings.model, settings.hall_sample,
                                                                      settings.hall_share))
        self.store_timeout = store_timeout
        self.broker_wait = broker_wait
        self.final_sync = final_sync
        self.confirm_every = confirm_every
        self.heartbeat_every = heartbeat_every
        self.max_lead = settings.max_lead
        self.resume = resume
        self.rejected = Rejections(self.worker_id, log)
        if settings.roster is not None and settings.roster.get(self.behaviour) != self.worker_id:
            raise ConfigError(f"the run's roster names {settings.roster.get(self.behaviour)!r} as the {self.behaviour} "
                              f"worker, not {self.worker_id!r}: drop --seed/--worker-id or fix the roster in run.json")
        if run_key is not None and run_key.run != self.run_id:
            raise ConfigError(f"the key is run {run_key.run!r}'s, not run {self.run_id!r}'s")
        self.gate = settings.gate(run_key, reject=self._reject)
        self.net_seconds = 0.0
        self.checkpoint_seconds = 0.0
        self._completed = 0
        self._best = 0.0
        self._measures: dict[str, float] = {}  # the task's status_measures of the latest generation, for the heartbeat
        self._last_beat = 0.0
        self._said_stopped = False  # its last heartbeat said it stops in order (Status.stopped)
        self._status_pub: Publisher | None = None
        self._inbox: Inbox | None = None
        self._outbox: Outbox | None = None
        self.logs: tuple[str, ...] = WorkerPaths.LOGS  # the append-only logs its checkpoint keeps in step

    @property
    def out(self) -> Path:
        return self.paths.dir

    def _reject(self, err: MessageError, key: str) -> None:
        self.rejected.note(err, key)

    # ------------------------------------------------------------ the worker directory
    def meta(self) -> dict[str, Any]:
        return {
            "coevo": __version__, "task": self.task.name, "behaviour": self.behaviour, "regime": self.regime,
            "run": self.run_id, "worker": self.worker_id, "seed": self.seed, "model": self.models.kind,
            "max_lead": self.max_lead, "world": self.world.model_dump(mode="json"), "ga": self.ga_cfg.model_dump(mode="json"),
            **hall_settings(self.models.kind, self.models.hall_sample, self.models.hall_share),
        }

    def _ident(self) -> dict[str, Any]:
        return {"run": self.run_id, "behaviour": self.behaviour, "worker": self.worker_id, "seed": self.seed}

    def _prepare(self) -> dict[str, Any] | None:
        """Create the directory, or check it and cut its logs back to the checkpoint (``resume``)."""
        p = self.paths
        logs = [p.dir / n for n in self.logs]
        prepare_dir(p.dir, what="worker", meta_file=p.worker_json, meta=self.meta(), logs=logs, checkpoint=p.checkpoint,
                    resume=self.resume, saved=_saved_meta, hint=", or choose another --out")
        with open(p.machines, "a", encoding="utf-8") as f:  # what decides the last bits here (coevo.rundir.machine)
            append_durably(f, {"started": time.time(), **machine()})
        if not self.resume:
            return None
        state = resume_state(p, self._ident())
        cut_logs(logs, state["worker"]["log_sizes"] if state else {})
        return state

    def resume_problems(self) -> list[str]:
        """What would stop this worker's ``--resume`` (:meth:`_prepare`), found by reading every file of its directory
        that it reads, changing nothing: one line a problem (:func:`~coevo.agents.checkpoint.resume_problems`)."""
        p = self.paths
        return resume_problems(p.dir, what="worker", meta_file=p.worker_json, meta=self.meta(),
                               logs=[p.dir / n for n in self.logs], checkpoint=p.checkpoint,
                               load=lambda: resume_state(p, self._ident()), sizes=lambda s: s["worker"]["log_sizes"],
                               writes=[p.machines, p.done, p.best_rules], saved=_saved_meta)

    def restore(self, ga: GA, state: dict[str, Any] | None) -> float:
        """Continue from the checkpoint ``state``; the seconds it had spent pacing."""
        if state is None:
            if self.resume:
                log.info("%s: no checkpoint in %s; starting afresh", self.worker_id, self.out)
            return 0.0
        self.load_learner(ga, state["ga"])
        self.models.load_state(state["models"])
        w = state["worker"]
        self.rejected.load(w["rejected"])
        self.net_seconds = float(w["net_seconds"])
        self.checkpoint_seconds = float(w["checkpoint_seconds"])
        self._completed = ga.generation_no
        self._best = float(ga.best_fitness) if ga.generation_no else 0.0
        if ga.best is not None:
            write_text(self.paths.best_rules, format_ruleset(ga.played(ga.best)))
        log.info("%s resumed after generation %d", self.worker_id, ga.generation_no)
        return float(w["pace_seconds"])

    def _checkpoint(self, ga: GA, pace_seconds: float) -> None:
        t0 = time.perf_counter()
        state = {
            "ga": self.learner_state(ga),
            "models": self.models.state_dict(),
            "worker": {
                "log_sizes": {n: (self.out / n).stat().st_size for n in self.logs},
                "rejected": self.rejected.as_dict(), "net_seconds": self.net_seconds,
                "checkpoint_seconds": self.checkpoint_seconds, "pace_seconds": pace_seconds,
            },
        }
        save_checkpoint(self.paths.checkpoint, self._ident(), state)
        self.checkpoint_seconds += time.perf_counter() - t0

    # ------------------------------------------------------------ the seam: what another kind of learner changes
    # A learner of another kind (the CEL learning module is one) subclasses Worker and overrides only these public
    # methods: how its GA is made and checkpointed (make_ga, learner_state, load_learner; restore and meta for what
    # more it keeps), how one generation is made and what of it is published (generation), what it takes in between
    # generations (take_in), how it is paced (pacer), and the extra context managers it runs inside (services).
    # one_generation is the step around generation (the curve, publication, checkpoint, heartbeat), for a subclass
    # or a test to wrap.  The loop, the directory, the publication log, the store sync and the heartbeats stay
    # here (on a coevo.bus.lifecycle.Lifecycle), and this module names no kind but its own.
    def make_ga(self) -> GA:
        return GA(self.task, self.behaviour, world=self.world, ga=self.ga_cfg, seed=self.seed)

    def learner_state(self, ga: GA) -> dict[str, Any]:
        return ga.state_dict()

    def load_learner(self, ga: GA, state: dict[str, Any]) -> None:
        ga.load_state(state)

    def generation(self, ga: GA) -> tuple[GenerationReport, RuleSet | None, float]:
        """One generation: its report, the new best so far to publish (None: no improvement), the best so far's
        fitness."""
        rep = ga.generation(self.models.partners(), tick=self._tick, mixture=self.models.mixture(ga.cfg.episodes))
        return rep, (ga.played(ga.best) if rep.improved and ga.best is not None else None), rep.best_so_far

    def take_in(self, inbox: Inbox, completed: int) -> None:
        """Between generations: what arrived for the learner (partner policies)."""
        inbox.fetch()
        inbox.adopt(completed)

    def pacer(self, session: Session) -> Pacer:
        return Pacer(session, self.run_id, self.models.needed, max_lead=self.max_lead)

    def services(self, session: Session, broker: BrokerWatch) -> list[AbstractContextManager[object]]:
        """More context managers the generation loop runs inside (a subclass's subscriptions)."""
        return []

    # ------------------------------------------------------------ the generation loop
    def run(self) -> list[GenerationReport]:
        state = self._prepare()
        self.paths.done.unlink(missing_ok=True)  # written at the end of this start; a predecessor's tells of its own
        ga = self.make_ga()
        paced = self.restore(ga, state)
        if state is None:  # generation 0: from now on, logs without a checkpoint mean it was removed
            self._checkpoint(ga, paced)
        curve: list[GenerationReport] = []
        p = self.paths
        if self.gate.open:
            log.warning("%s: run %s is OPEN: no key, so its messages are not authenticated and anyone who reaches the "
                        "bus can steer it (give --key-file, or let coevo run make the run)", self.worker_id, self.run_id)
        with Lifecycle(self.conf, what=f"{self.behaviour} worker session", gate=self.gate) as life:
            s = life.session
            adopt_log = life.enter(open(p.adoptions, "a", encoding="utf-8"))
            curve_log = life.enter(open(p.curve, "a", encoding="utf-8"))
            broker = life.enter(BrokerWatch(s, self.run_id, self.gate))
            inbox = self._inbox = life.enter(Inbox(
                s, broker, run=self.run_id, models=self.models, adoptions=adopt_log, reject=self._reject,
                store_timeout=self.store_timeout, gate=self.gate))
            outbox = self._outbox = life.enter(Outbox(
                s, broker, run=self.run_id, behaviour=self.behaviour, worker_id=self.worker_id, log_path=p.published,
                store_timeout=self.store_timeout, confirm_every=self.confirm_every, gate=self.gate))
            pacer = life.enter(self.pacer(s))
            for service in self.services(s, broker):
                life.enter(service)
            life.declare(s.liveliness().declare_token(keys.alive(self.run_id, self.behaviour, self.worker_id)))
            self._status_pub = life.declare(s.declare_publisher(keys.status(self.run_id, self.behaviour,
                                                                            self.worker_id)))
            life.at_end(self._closing)
            pacer.waited = paced
            if not broker.wait(self.broker_wait, inbox.stop):
                log.warning("%s: no coevo broker seen after %.0f s; going on without a store (publications are kept and "
                            "delivered when one appears)", self.worker_id, self.broker_wait)
            inbox.refetch = True
            for g in range(ga.generation_no, self.ga_cfg.generations):
                if inbox.stop_requested() or life.stop.is_set():
                    log.info("%s stopping at generation %d", self.worker_id, g)
                    break
                pacer.wait(g, inbox.stop, tick=partial(self._paced_tick, g))
                t_net = time.perf_counter()
                self.take_in(inbox, g)
                self.net_seconds += time.perf_counter() - t_net
                curve.append(self.one_generation(ga, inbox, outbox, pacer, curve_log))
            finished = self._completed >= self.ga_cfg.generations
            if finished:
                outbox.final_sync(self.final_sync, inbox.stop, partial(self._heartbeat, done=False))
            self._heartbeat(done=finished, stopped=not finished and self._asked_to_stop())
            life.linger()
        rows = read_jsonl(p.curve)
        write_json(p.done, {
            "generations": len(rows), "finished": len(rows) >= self.ga_cfg.generations,
            "versions_published": len(outbox.published), "unconfirmed": outbox.unconfirmed,
            "republished": outbox.republished, "rejected": self.rejected.as_dict(),
            "net_seconds": self.net_seconds, "gen_seconds": sum(r["seconds"] for r in rows),
            "checkpoint_seconds": self.checkpoint_seconds, "pace_seconds": pacer.waited, "open": self.gate.open,
            "refused": broker.refused.is_set(),
        })
        if broker.refused.is_set() and outbox.unconfirmed:
            raise ServiceError(f"the broker refused to store run {self.run_id} (it holds no key for it): versions "
                               f"{outbox.unconfirmed} are only in {p.published}; start the broker with --open, or "
                               "give the broker and every worker the run's key (coevo keygen, --key-file)")
        return curve

    def _closing(self) -> None:
        """As the worker's life ends (before its token and heartbeats' publisher go): a worker asked to stop (a
        signal, or the run's stop) short of its last generation says so in a last heartbeat, so that every board
        reads its token's going as a stop, not a death; then nothing more is sent."""
        if not self._said_stopped and self._asked_to_stop() and self._completed < self.ga_cfg.generations:
            self._heartbeat(done=False, stopped=True)  # a signal cut its generation short: no last heartbeat yet
        self._status_pub = None
        self._inbox = None
        self.rejected.flush()

    def one_generation(self, ga: GA, inbox: Inbox, outbox: Outbox, pacer: Pacer, curve_log: IO[str]) -> GenerationReport:
        """One generation and what follows it: the curve's line, the new best published (after the checkpoint),
        the current best, a heartbeat and the store sync."""
        p = self.paths
        rep, new_best, best_so_far = self.generation(ga)
        curve_log.write(json.dumps(rep.as_dict()) + "\n")
        curve_log.flush()
        if new_best is not None:
            outbox.record(self._policy(outbox.next_version, rep, new_best.to_dict(), best_so_far,
                                       self.ga_cfg.best_episodes))
            write_text(p.best_rules, format_ruleset(new_best))
        self._completed, self._best = rep.generation, best_so_far
        self._measures = self.task.status_measures(self.behaviour, rep.measures)
        # Checkpoint before anything leaves: what was published is always in a checkpoint,
        # so a resumed worker never publishes a different policy under a version number.
        self._checkpoint(ga, pacer.waited)
        t0 = time.perf_counter()
        if ga.current is not None:
            outbox.put_current(self._policy(rep.generation, rep, ga.played(ga.current).to_dict(), ga.current_fitness,
                                            self.ga_cfg.episodes))
        outbox.put_latest()
        self._heartbeat(done=False)
        if outbox.broker.back.is_set():
            inbox.refetch = True  # a restarted broker may hold partner versions this worker missed
        outbox.sync(upto=outbox.top - (1 if new_best is not None else 0))
        self.net_seconds += time.perf_counter() - t0
        return rep

    def _policy(self, version: int, rep: GenerationReport, rules: dict[str, Any], fitness: float,
                episodes: int) -> PolicyUpdate:
        return PolicyUpdate(run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, version=version,
                            generation=rep.generation, fitness=fitness, episodes=episodes, rules=rules, sent_at=time.time())

    # ------------------------------------------------------------ heartbeats
    def _asked_to_stop(self) -> bool:
        """A signal (Ctrl-C, SIGTERM) or the run's stop, not a failure of its own."""
        return SIGNALLED.is_set() or (self._inbox is not None and self._inbox.stop.is_set())

    def _status(self, *, done: bool, stopped: bool = False) -> Status:
        outbox = self._outbox
        return Status(
            run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, regime=self.regime,
            generation=self._completed, generations=self.ga_cfg.generations,
            best_fitness=self._best if self._best > -1e300 else 0.0,
            partner_versions=dict(self.models.versions),
            rejected=self.rejected.as_dict(), buffered=len(outbox.unconfirmed) if outbox else 0, done=done, stopped=stopped,
            open=self.gate.open, measures=self._measures, sent_at=time.time(),
        )

    def _heartbeat(self, *, done: bool, stopped: bool = False) -> None:
        self._said_stopped = self._said_stopped or stopped
        if self._status_pub is not None:
            self._status_pub.put(self.gate.seal(self._status(done=done, stopped=stopped),
                                                keys.status(self.run_id, self.behaviour, self.worker_id)))
        self._last_beat = time.monotonic()

    def _tick(self) -> None:
        """Between episode rounds of an evaluation: a heartbeat every ``heartbeat_every`` s."""
        if time.monotonic() - self._last_beat >= self.heartbeat_every:
            if self._inbox is not None:
                self._inbox.stop_requested()
            self._heartbeat(done=False)

    def _paced_tick(self, completed: int) -> None:
        """While paced: take in what arrived (so rejections are counted) and tell status we are alive."""
        if self._inbox is not None:
            self._inbox.adopt(completed)
            self._inbox.stop_requested()
        self._heartbeat(done=False)


def run_worker(settings: RunSettings, *, behaviour: str, seed: int | None, worker_id: str | None, out: Path | None,
               conf: Config, resume: bool, final_sync: float, run_key: RunKey | None = None,
               kind: type[Worker] = Worker) -> int:
    """``coevo worker``: run one worker of ``kind`` (this class, or a learner plugged into its seam, e.g. the CEL
    learner) to its end (exit status 0), or until SIGINT/SIGTERM (130)."""
    out = out if out is not None else settings.paths(Path("runs")).worker(behaviour).dir
    w = kind(settings, behaviour=behaviour, seed=seed, worker_id=worker_id, out_dir=out, conf=conf, resume=resume,
             final_sync=final_sync, run_key=run_key)
    curve = main_of(w.run)
    if curve is None:
        return 130
    print(f"{w.worker_id}: {len(curve)} generations, best so far {curve[-1].best_so_far if curve else float('nan'):.3f}")
    return 0

