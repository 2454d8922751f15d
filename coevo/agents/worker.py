"""``coevo worker``: one behaviour's GA as its own process on the bus.

Each generation the worker (1) adopts the newest partner policies that arrived
while it was busy (they wait in rings of the newest few inside Zenoh, so no Python
runs per arriving message and a flood cannot slow the GA; decoding and validation
happen here, between evaluations), (2) runs one GA generation against its partner
models, heartbeating between episode rounds, (3) writes a checkpoint, then
publishes its best so far if it improved, its current best and a heartbeat.

What a worker writes in its directory (``runs/RUN/workers/BEHAVIOUR/``):

* ``worker.json``: its settings (a ``--resume`` with other settings is refused);
* ``curve.jsonl``: one line per generation (the learning curve);
* ``adoptions.jsonl``: after how many of its own generations it took which version
  of which partner, with the rules (what ``coevo replay`` needs);
* ``published.jsonl``: every version it published, in full: its outbox, from which
  it republishes whatever the broker's store turns out not to hold;
* ``checkpoint.msgpack``: see :mod:`coevo.agents.checkpoint`;
* ``best.rules`` and, at the end, ``done.json``.

Delivery to the store: a put nobody hears is lost silently (a broker that is down
or restarting).  The worker follows the broker's liveliness token and, while the
broker is up, asks its store which versions it holds; what is missing it publishes
again from its outbox.  So a broker killed and restarted, or messages dropped on
the way, leave the store's history complete once the broker is back.
"""

from __future__ import annotations

import json
import logging
import math
import os
import threading
import time
from functools import partial
from pathlib import Path
from typing import Any

import msgpack
from pydantic import BaseModel

from coevo import __version__
from coevo.agents.checkpoint import (
    CHECKPOINT,
    load_checkpoint,
    save_checkpoint,
    truncate_log,
)
from coevo.agents.models import PartnerModels
from coevo.agents.pacing import DEFAULT_MAX_LEAD, Pacer
from coevo.bus import keys
from coevo.bus.messages import Control, PolicyUpdate, Status, decode, encode
from coevo.bus.rejections import Rejections
from coevo.bus.session import drain, drain_messages, is_put, open_session, ring_subscriber
from coevo.config import GAConfig
from coevo.errors import ConfigError, MessageError, RunDirError
from coevo.ga import GA, GenerationReport
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.runs.layout import read_jsonl, write_json, write_text
from coevo.tasks import Task

__all__ = ["Worker", "INBOX", "FAULT_HANG_ENV"]

log = logging.getLogger(__name__)

INBOX = 32  # newest partner messages kept per key between two generations
LOGS = ("curve.jsonl", "adoptions.jsonl", "published.jsonl")
#: Fault injection for tests and ``coevo chaos``: after this many generations the
#: worker's main thread hangs (its Zenoh threads, and so its liveliness token, live on).
FAULT_HANG_ENV = "COEVO_FAULT_HANG_AFTER"


class Worker:
    def __init__(
        self,
        *,
        task: Task,
        behaviour: str,
        regime: str,
        run: str,
        worker_id: str,
        seed: int,
        world: BaseModel,
        ga: GAConfig,
        out_dir: Path,
        conf: Any,
        model: str = "best",
        store_timeout: float = 2.0,
        broker_wait: float = 30.0,
        final_sync: float = 30.0,
        confirm_every: float = 2.0,
        heartbeat_every: float = 1.0,
        max_lead: int | None = DEFAULT_MAX_LEAD,
        resume: bool = False,
    ) -> None:
        self.task = task
        self.behaviour = task.check_behaviour(behaviour)
        self.regime = regime
        self.run_id = keys.check_id("run id", run)
        self.worker_id = keys.check_id("worker id", worker_id)
        self.seed = seed
        self.world = world
        self.ga_cfg = ga
        self.out = Path(out_dir)
        self.conf = conf
        self.models = PartnerModels(task, self.behaviour, task.check_regime(regime), seed, kind=model, ga=ga)
        self.store_timeout = store_timeout
        self.broker_wait = broker_wait
        self.final_sync = final_sync
        self.confirm_every = confirm_every
        self.heartbeat_every = heartbeat_every
        self.max_lead = max_lead
        self.resume = resume
        self.rejected = Rejections(self.worker_id, log)
        self.net_seconds = 0.0
        self.checkpoint_seconds = 0.0
        self.republished = 0
        self._stop = threading.Event()
        self._broker_up = threading.Event()
        self._broker_back = threading.Event()  # the broker (re)appeared: ask its store what it holds
        self._fetched: list[tuple[str, bytes]] = []  # partner policies fetched from the store
        self._published: dict[int, bytes] = {}  # version -> encoded PolicyUpdate: the outbox
        self._stored: set[int] = set()  # versions the store confirmed holding
        self._last_query = -math.inf  # monotonic time the store was last asked what it holds
        self._accepted: dict[str, bytes] = {}  # key -> last partner payload accepted (repeats skip decoding)
        self._refetch = True  # ask the store for the partners' latest before the next generation
        self._completed = 0
        self._best = 0.0
        self._measures: dict[str, float] = {}  # the task's status_measures of the latest generation, for the heartbeat
        self._last_beat = 0.0
        self._io: dict[str, Any] = {}  # session objects while running

    def _reject(self, err: MessageError, key: str) -> None:
        self.rejected.note(err, key)

    # ------------------------------------------------------------ the worker directory
    def _meta(self) -> dict[str, Any]:
        return {
            "coevo": __version__, "task": self.task.name, "behaviour": self.behaviour, "regime": self.regime, "run": self.run_id,
            "worker": self.worker_id, "seed": self.seed, "model": self.models.kind, "max_lead": self.max_lead,
            "world": self.world.model_dump(mode="json"), "ga": self.ga_cfg.model_dump(mode="json"),
        }

    def _ident(self) -> dict[str, Any]:
        return {"run": self.run_id, "behaviour": self.behaviour, "worker": self.worker_id, "seed": self.seed}

    def _prepare(self) -> dict[str, Any] | None:
        """Create the directory, or check it and cut its logs back to the checkpoint (``resume``)."""
        self.out.mkdir(parents=True, exist_ok=True)
        meta, wj = self._meta(), self.out / "worker.json"
        if not self.resume:
            used = [n for n in ("worker.json", CHECKPOINT, *LOGS) if (self.out / n).exists()]
            if used:
                raise RunDirError(f"worker directory {str(self.out)!r} already holds a worker's run ({used[0]}); "
                                  "add --resume to continue it, or choose another --out")
            write_json(wj, meta)
            for n in LOGS:
                (self.out / n).touch()
            return None
        if wj.exists():
            saved = json.loads(wj.read_text(encoding="utf-8"))
            diff = [f"{k} was {saved.get(k)!r}, now {meta[k]!r}" for k in meta if k != "coevo" and saved.get(k) != meta[k]]
            if diff:
                raise ConfigError(f"--resume of {str(self.out)!r} with other settings: {'; '.join(diff)}")
        else:
            write_json(wj, meta)
        state = load_checkpoint(self.out / CHECKPOINT, self._ident())
        sizes = state["worker"]["log_sizes"] if state else {n: 0 for n in LOGS}
        for n in LOGS:
            truncate_log(self.out / n, int(sizes[n]))
        return state

    def _restore(self, ga: GA, state: dict[str, Any] | None) -> None:
        for line in (self.out / "published.jsonl").read_text(encoding="utf-8").splitlines():
            msg = PolicyUpdate.model_validate(json.loads(line))
            self._published[msg.version] = encode(msg)
        if state is None:
            if self.resume:
                log.info("%s: no checkpoint in %s; starting afresh", self.worker_id, self.out)
            return
        ga.load_state(state["ga"])
        self.models.load_state(state["models"])
        w = state["worker"]
        self.rejected.load(w["rejected"])
        self.net_seconds = float(w["net_seconds"])
        self.checkpoint_seconds = float(w["checkpoint_seconds"])
        self._completed = ga.generation_no
        self._best = float(ga.best_fitness) if ga.generation_no else 0.0
        if ga.best is not None:
            write_text(self.out / "best.rules", format_ruleset(ga.best))
        log.info("%s resumed after generation %d with %d published versions", self.worker_id, ga.generation_no,
                 len(self._published))

    def _checkpoint(self, ga: GA, pace_seconds: float) -> None:
        t0 = time.perf_counter()
        state = {
            "ga": ga.state_dict(),
            "models": self.models.state_dict(),
            "worker": {
                "log_sizes": {n: (self.out / n).stat().st_size for n in LOGS},
                "rejected": self.rejected.as_dict(), "net_seconds": self.net_seconds,
                "checkpoint_seconds": self.checkpoint_seconds, "pace_seconds": pace_seconds,
            },
        }
        save_checkpoint(self.out / CHECKPOINT, self._ident(), state)
        self.checkpoint_seconds += time.perf_counter() - t0

    # ------------------------------------------------------------ adoption
    def _adopt(self, generation: int, log_file: Any) -> None:
        items, self._fetched = self._fetched, []
        for sub in self._io.get("partner_subs", ()):
            got = drain(sub, INBOX)
            if len(got) == INBOX:  # the ring was full: older messages were dropped unread
                self._reject(MessageError("flood", f"over {INBOX} messages on {got[0][0]!r} within one generation"), got[0][0])
                self._refetch = True
            items += got
        newest: dict[str, tuple[PolicyUpdate, RuleSet]] = {}
        for key, payload in items:
            if self._accepted.get(key) == payload:
                continue  # the partner's every-generation repeat of what this worker already checked and holds
            try:
                msg = decode(payload, key=key)
                if not isinstance(msg, PolicyUpdate):
                    raise MessageError("wrong_key", f"{msg.kind} on {key!r}")
                rules = msg.ruleset()
            except MessageError as err:
                self._reject(err, key)
                continue
            self._accepted[key] = payload
            cur = newest.get(msg.behaviour)
            if cur is None or msg.version > cur[0].version:
                newest[msg.behaviour] = (msg, rules)
        for beh, (msg, rules) in newest.items():
            if self.models.adopt(beh, msg.version, rules):
                entry = {
                    "generation": generation, "partner": beh, "version": msg.version,
                    "from_worker": msg.worker, "fitness": msg.fitness, "received_at": time.time(),
                    "rules": msg.rules,  # so a replay needs nothing but this log
                }
                log_file.write(json.dumps(entry) + "\n")
                log_file.flush()

    # ------------------------------------------------------------ liveliness of the broker, control
    def _on_broker(self, sample: Any) -> None:
        if is_put(sample):
            self._broker_up.set()
            self._broker_back.set()
        else:
            self._broker_up.clear()

    def _stop_requested(self) -> bool:
        sub = self._io.get("control_sub")
        for _, msg in drain_messages(sub, 64, self._reject) if sub is not None else ():
            if isinstance(msg, Control) and msg.command == "stop":
                self._stop.set()
        return self._stop.is_set()

    # ------------------------------------------------------------ main loop
    def run(self) -> list[GenerationReport]:
        state = self._prepare()
        ga = GA(self.task, self.behaviour, world=self.world, ga=self.ga_cfg, seed=self.seed)
        self._restore(ga, state)
        curve: list[GenerationReport] = []
        with open_session(self.conf, what=f"{self.behaviour} worker session") as s, \
                open(self.out / "adoptions.jsonl", "a", encoding="utf-8") as adopt_log, \
                open(self.out / "curve.jsonl", "a", encoding="utf-8") as curve_log, \
                open(self.out / "published.jsonl", "a", encoding="utf-8") as outbox:
            partner_key = keys.current if self.models.kind == "current" else keys.policy
            io = self._io
            io["partner_subs"] = [ring_subscriber(s, partner_key(self.run_id, b), INBOX) for b in self.models.needed]
            io["control_sub"] = ring_subscriber(s, keys.control(self.run_id), 64)
            broker_watch = s.liveliness().declare_subscriber(keys.BROKER, self._on_broker, history=True)
            token = s.liveliness().declare_token(keys.alive(self.run_id, self.behaviour, self.worker_id))
            io["pub"] = s.declare_publisher(keys.policy(self.run_id, self.behaviour))
            current_pub = s.declare_publisher(keys.current(self.run_id, self.behaviour))
            io["status_pub"] = s.declare_publisher(keys.status(self.run_id, self.behaviour, self.worker_id))
            pacer = Pacer(s, self.run_id, self.models.needed, max_lead=self.max_lead)
            if state is not None:
                pacer.waited = float(state["worker"]["pace_seconds"])
            hang_after = _fault_hang_after()
            try:
                self._wait_for_broker()
                self._refetch = True
                for g in range(ga.generation_no, self.ga_cfg.generations):
                    if self._stop_requested():
                        log.info("%s stopping at generation %d", self.worker_id, g)
                        break
                    pacer.wait(g, self._stop, tick=partial(self._paced_tick, g, adopt_log))
                    t_net = time.perf_counter()
                    if self._refetch:
                        self._fetch_from_store(s)
                    self._adopt(g, adopt_log)
                    self.net_seconds += time.perf_counter() - t_net
                    rep = ga.generation(self.models.partners(), tick=self._tick)
                    curve.append(rep)
                    curve_log.write(json.dumps(rep.as_dict()) + "\n")
                    curve_log.flush()
                    if rep.improved and ga.best is not None:
                        msg = PolicyUpdate(
                            run=self.run_id, behaviour=self.behaviour, worker=self.worker_id,
                            version=len(self._published) + 1, generation=rep.generation, fitness=rep.best_so_far,
                            episodes=self.ga_cfg.best_episodes, rules=ga.best.to_dict(), sent_at=time.time(),
                        )
                        outbox.write(json.dumps(msg.model_dump(mode="json")) + "\n")
                        outbox.flush()
                        os.fsync(outbox.fileno())
                        self._published[msg.version] = encode(msg)
                        write_text(self.out / "best.rules", format_ruleset(ga.best))
                    self._completed, self._best = rep.generation, rep.best_so_far
                    self._measures = self.task.status_measures(self.behaviour, rep.measures)
                    # Checkpoint before anything leaves: what was published is always in a checkpoint,
                    # so a resumed worker never publishes a different policy under a version number.
                    self._checkpoint(ga, pacer.waited)
                    t0 = time.perf_counter()
                    if ga.current is not None:
                        current_pub.put(encode(PolicyUpdate(
                            run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, version=rep.generation,
                            generation=rep.generation, fitness=ga.current_fitness, episodes=self.ga_cfg.episodes,
                            rules=ga.current.to_dict(), sent_at=time.time(),
                        )))
                    if self._published:
                        # Every generation, not only on improvement: partners that missed a put catch up.
                        io["pub"].put(self._published[max(self._published)])
                    self._heartbeat(done=False)
                    self._sync(s, upto=max(self._published, default=0) - (1 if rep.improved else 0))
                    self.net_seconds += time.perf_counter() - t0
                    if hang_after is not None and rep.generation >= hang_after:
                        _hang(self.worker_id, rep.generation)
                finished = self._completed >= self.ga_cfg.generations
                if finished:
                    self._final_sync(s)
                self._heartbeat(done=finished)
            finally:
                pacer.close()
                token.undeclare()
                broker_watch.undeclare()
                for sub in (*io.pop("partner_subs", ()), io.pop("control_sub")):
                    sub.undeclare()
                self._io = {}
                self.rejected.flush()
        rows = read_jsonl(self.out / "curve.jsonl")
        write_json(self.out / "done.json", {
            "generations": len(rows), "finished": len(rows) >= self.ga_cfg.generations,
            "versions_published": len(self._published), "unconfirmed": sorted(set(self._published) - self._stored),
            "republished": self.republished, "rejected": self.rejected.as_dict(),
            "net_seconds": self.net_seconds, "gen_seconds": sum(r["seconds"] for r in rows),
            "checkpoint_seconds": self.checkpoint_seconds, "pace_seconds": pacer.waited,
        })
        return curve

    # ------------------------------------------------------------ heartbeats
    def _status(self, *, done: bool) -> Status:
        return Status(
            run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, regime=self.regime,
            generation=self._completed, generations=self.ga_cfg.generations,
            best_fitness=self._best if self._best > -1e300 else 0.0,
            partner_versions=dict(self.models.versions),
            rejected=self.rejected.as_dict(), buffered=len(set(self._published) - self._stored), done=done,
            measures=self._measures, sent_at=time.time(),
        )

    def _heartbeat(self, *, done: bool) -> None:
        self._io["status_pub"].put(encode(self._status(done=done)))
        self._last_beat = time.monotonic()

    def _tick(self) -> None:
        """Between episode rounds of an evaluation: a heartbeat every ``heartbeat_every`` s."""
        if time.monotonic() - self._last_beat >= self.heartbeat_every:
            self._stop_requested()
            self._heartbeat(done=False)

    def _paced_tick(self, completed: int, adopt_log: Any) -> None:
        """While paced: take in what arrived (so rejections are counted) and tell status we are alive."""
        self._adopt(completed, adopt_log)
        self._stop_requested()
        self._heartbeat(done=False)

    # ------------------------------------------------------------ the broker's store
    def _wait_for_broker(self) -> None:
        """Wait (up to ``broker_wait`` s) for a broker whose store is up, so nothing is published into the void."""
        end = time.monotonic() + self.broker_wait
        while time.monotonic() < end and not self._stop.is_set():
            if self._broker_up.wait(0.2):  # the broker watch (history=True) reports a token already there
                return
        log.warning("%s: no coevo broker seen after %.0f s; going on without a store (publications are kept "
                    "and delivered when one appears)", self.worker_id, self.broker_wait)

    def _fetch_from_store(self, session: Any) -> None:
        """A late, restarted or flooded worker gets the partners' current best from the store."""
        self._refetch = False
        if self.models.kind == "current" or not self.models.needed or not self._broker_up.is_set():
            return  # current policies are not stored; the next generation's arrives within a generation
        for b in self.models.needed:
            try:
                for reply in session.get(keys.store_latest(self.run_id, b), timeout=self.store_timeout):
                    if reply.ok is not None:
                        self._fetched.append((keys.policy(self.run_id, b), bytes(reply.ok.payload.to_bytes())))
            except Exception as exc:  # the broker went away meanwhile: the subscription will catch up
                log.info("store query for %s failed: %s", b, exc)

    def _store_versions(self, session: Any) -> set[int] | None:
        """The versions of this worker's policies the store holds; None if it did not answer."""
        try:
            for reply in session.get(keys.store_versions(self.run_id, self.behaviour), timeout=self.store_timeout):
                if reply.ok is None:
                    continue
                data = msgpack.unpackb(bytes(reply.ok.payload.to_bytes()), raw=False)
                return {int(v) for v in data.get("workers", {}).get(self.worker_id, [])}
        except Exception as exc:
            log.info("%s: store versions query failed: %s", self.worker_id, exc)
        return None

    def _sync(self, session: Any, *, upto: int, now: bool = False) -> bool:
        """Make sure the store holds every version up to ``upto``; republish what it lacks.  True if it does.

        Asks the store only when there is something unconfirmed or the broker has
        just (re)appeared, at most once per ``confirm_every`` seconds unless ``now``
        or the broker is back, and never while the broker is down (a query would
        wait for its timeout).  The newest version is confirmed a generation later,
        so the check never races the put that carries it.
        """
        if not self._broker_up.is_set():
            return False
        back = self._broker_back.is_set()
        if not back and all(v in self._stored for v in self._published if v <= upto):
            return True
        if not (back or now) and time.monotonic() - self._last_query < self.confirm_every:
            return False
        self._broker_back.clear()
        self._last_query = time.monotonic()
        have = self._store_versions(session)
        if have is None:
            return False
        if back:
            self._refetch = True  # a restarted broker may hold partner versions this worker missed
        self._stored = have & set(self._published)
        missing = sorted(v for v in self._published if v <= upto and v not in have)
        for v in missing:
            self._io["pub"].put(self._published[v])
        if missing:
            self.republished += len(missing)
            log.info("%s republished versions %s the store lacked", self.worker_id, missing)
        return not missing

    def _final_sync(self, session: Any) -> None:
        """Before saying done: wait (up to ``final_sync`` s) until the store holds every version."""
        end = time.monotonic() + self.final_sync
        top = max(self._published, default=0)
        while time.monotonic() < end and not self._stop.is_set():
            if self._sync(session, upto=top, now=True):
                return
            self._heartbeat(done=False)
            time.sleep(0.2)
        lacking = sorted(set(self._published) - self._stored)
        if lacking:
            log.warning("%s: the broker's store has not confirmed versions %s after %.0f s; they stay in %s",
                        self.worker_id, lacking, self.final_sync, self.out / "published.jsonl")


def _fault_hang_after() -> int | None:
    value = os.environ.get(FAULT_HANG_ENV)
    if not value:
        return None
    try:
        return int(value)
    except ValueError:
        raise ConfigError(f"${FAULT_HANG_ENV} must be a generation number, got {value!r}") from None


def _hang(worker_id: str, generation: int) -> None:
    log.warning("%s: hanging after generation %d (fault injection, $%s)", worker_id, generation, FAULT_HANG_ENV)
    while True:
        time.sleep(1.0)
