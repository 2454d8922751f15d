"""``coevo worker``: one behaviour's GA as its own process on the bus.

Each generation the worker (1) adopts the newest partner policies that arrived
while it was busy (the subscriber callbacks only queue raw bytes; decoding and
validation happen here, between evaluations, so the GA never waits on the
network), (2) runs one GA generation against its partner models, (3) publishes
its best so far if it improved and a status heartbeat.  Every adoption is logged
(``adoptions.jsonl``: after how many of its own generations it took which
version of which partner), which is what ``coevo replay`` needs to re-run it.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections import Counter
from functools import partial
from pathlib import Path
from typing import Any

from coevo import __version__, keys
from coevo.agents.models import PartnerModels
from coevo.agents.pacing import DEFAULT_MAX_LEAD, Pacer
from coevo.behaviours import Behaviour
from coevo.bus import open_session
from coevo.config import GAConfig, WorldConfig
from coevo.errors import MessageError, RuleSetError
from coevo.ga import GA, GenerationReport
from coevo.messages import Control, PolicyUpdate, Status, decode, encode
from coevo.policy.rules import RuleSet
from coevo.policy.text import format_ruleset
from coevo.rundir import write_json, write_text

__all__ = ["Worker"]

log = logging.getLogger(__name__)


class Worker:
    def __init__(
        self,
        *,
        behaviour: Behaviour | str,
        regime: str,
        run: str,
        worker_id: str,
        seed: int,
        world: WorldConfig,
        ga: GAConfig,
        out_dir: Path,
        conf: Any,
        model: str = "best",
        store_timeout: float = 2.0,
        broker_wait: float = 30.0,
        max_lead: int | None = DEFAULT_MAX_LEAD,
    ) -> None:
        self.behaviour = Behaviour(behaviour)
        self.regime = regime
        self.run_id = keys.check_id("run id", run)
        self.worker_id = keys.check_id("worker id", worker_id)
        self.seed = seed
        self.world = world
        self.ga_cfg = ga
        self.out = Path(out_dir)
        self.conf = conf
        self.models = PartnerModels(self.behaviour, regime, seed, kind=model, initial_rules=ga.initial_rules)
        self.store_timeout = store_timeout
        self.broker_wait = broker_wait
        self.max_lead = max_lead
        self._inbox: list[tuple[str, bytes]] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.rejected: Counter[str] = Counter()
        self.net_seconds = 0.0

    # ------------------------------------------------------------ callbacks: queue and return
    def _on_policy(self, sample: Any) -> None:
        with self._lock:
            self._inbox.append((str(sample.key_expr), bytes(sample.payload.to_bytes())))

    def _on_control(self, sample: Any) -> None:
        try:
            msg = decode(bytes(sample.payload.to_bytes()), key=str(sample.key_expr))
        except MessageError as err:
            self._reject(err, str(sample.key_expr))
            return
        if isinstance(msg, Control) and msg.command == "stop":
            self._stop.set()

    def stop(self) -> None:
        self._stop.set()

    def _reject(self, err: MessageError, key: str) -> None:
        self.rejected[err.reason] += 1
        log.warning("%s rejected a message on %s: %s", self.worker_id, key, err)

    # ------------------------------------------------------------ adoption
    def _adopt(self, generation: int, log_file: Any) -> None:
        with self._lock:
            items, self._inbox = self._inbox, []
        newest: dict[Behaviour, tuple[PolicyUpdate, RuleSet]] = {}
        for key, payload in items:
            try:
                msg = decode(payload, key=key)
                if not isinstance(msg, PolicyUpdate):
                    raise MessageError("wrong_key", f"{msg.kind} on {key!r}")
                rules = msg.ruleset()
            except (MessageError, RuleSetError) as err:
                self._reject(err if isinstance(err, MessageError) else MessageError("invalid", str(err)), key)
                continue
            cur = newest.get(msg.behaviour)
            if cur is None or msg.version > cur[0].version:
                newest[msg.behaviour] = (msg, rules)
        for beh, (msg, rules) in newest.items():
            if self.models.adopt(beh, msg.version, rules):
                entry = {
                    "generation": generation, "partner": beh.value, "version": msg.version,
                    "from_worker": msg.worker, "fitness": msg.fitness, "received_at": time.time(),
                    "rules": msg.rules,  # so a replay needs nothing but this log
                }
                log_file.write(json.dumps(entry) + "\n")
                log_file.flush()

    # ------------------------------------------------------------ main loop
    def run(self) -> list[GenerationReport]:
        self.out.mkdir(parents=True, exist_ok=True)
        write_json(self.out / "worker.json", {
            "coevo": __version__, "behaviour": self.behaviour.value, "regime": self.regime, "run": self.run_id,
            "worker": self.worker_id, "seed": self.seed, "model": self.models.kind, "max_lead": self.max_lead,
            "world": self.world.model_dump(), "ga": self.ga_cfg.model_dump(),
        })
        ga = GA(self.behaviour, world=self.world, ga=self.ga_cfg, seed=self.seed)
        curve: list[GenerationReport] = []
        version = 0
        with open_session(self.conf, what=f"{self.behaviour} worker session") as s, \
                open(self.out / "adoptions.jsonl", "a", encoding="utf-8") as adopt_log, \
                open(self.out / "curve.jsonl", "a", encoding="utf-8") as curve_log:
            partner_key = keys.current if self.models.kind == "current" else keys.policy
            decls = [s.declare_subscriber(partner_key(self.run_id, b), self._on_policy) for b in self.models.needed]
            decls.append(s.declare_subscriber(keys.control(self.run_id), self._on_control))
            token = s.liveliness().declare_token(keys.alive(self.run_id, self.behaviour, self.worker_id))
            pub = s.declare_publisher(keys.policy(self.run_id, self.behaviour))
            current_pub = s.declare_publisher(keys.current(self.run_id, self.behaviour))
            status_pub = s.declare_publisher(keys.status(self.run_id, self.behaviour, self.worker_id))
            pacer = Pacer(s, self.run_id, self.models.needed, max_lead=self.max_lead)
            last_policy: bytes | None = None
            try:
                self._wait_for_broker(s)
                self._fetch_from_store(s)
                for g in range(self.ga_cfg.generations):
                    if self._stop.is_set():
                        log.info("%s stopping at generation %d", self.worker_id, g)
                        break
                    pacer.wait(g, self._stop, tick=partial(self._heartbeat, g, ga, adopt_log, status_pub))
                    t_net = time.perf_counter()
                    self._adopt(g, adopt_log)
                    self.net_seconds += time.perf_counter() - t_net
                    rep = ga.generation(self.models.partners())
                    curve.append(rep)
                    curve_log.write(json.dumps(rep.as_dict()) + "\n")
                    curve_log.flush()
                    t0 = time.perf_counter()
                    if rep.improved and ga.best is not None:
                        version += 1
                        last_policy = encode(PolicyUpdate(
                            run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, version=version,
                            generation=rep.generation, fitness=rep.best_so_far, episodes=self.ga_cfg.best_episodes,
                            rules=ga.best.to_dict(), sent_at=time.time(),
                        ))
                        write_text(self.out / "best.rules", format_ruleset(ga.best))
                    if ga.current is not None:
                        current_pub.put(encode(PolicyUpdate(
                            run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, version=rep.generation,
                            generation=rep.generation, fitness=ga.current_fitness, episodes=self.ga_cfg.episodes,
                            rules=ga.current.to_dict(), sent_at=time.time(),
                        )))
                    if last_policy is not None:
                        # Every generation, not only on improvement: a put nobody received is lost
                        # silently, and the store and partners drop versions they already have.
                        pub.put(last_policy)
                    status_pub.put(encode(self._status(rep.generation, rep.best_so_far, done=False)))
                    self.net_seconds += time.perf_counter() - t0
                status_pub.put(encode(self._status(len(curve), float(ga.best_fitness) if curve else 0.0, done=True)))
            finally:
                pacer.close()
                token.undeclare()
                for d in decls:
                    d.undeclare()
        write_json(self.out / "done.json", {
            "generations": len(curve), "versions_published": version, "rejected": dict(self.rejected),
            "net_seconds": self.net_seconds, "gen_seconds": sum(r.seconds for r in curve),
            "pace_seconds": pacer.waited,
        })
        return curve

    def _heartbeat(self, completed: int, ga: GA, adopt_log: Any, status_pub: Any) -> None:
        """While paced: take in what arrived (so rejections are counted) and tell status we are alive."""
        self._adopt(completed, adopt_log)
        best = float(ga.best_fitness) if completed else 0.0
        status_pub.put(encode(self._status(completed, best, done=False)))

    def _status(self, generation: int, best: float, *, done: bool) -> Status:
        return Status(
            run=self.run_id, behaviour=self.behaviour, worker=self.worker_id, regime=self.regime,
            generation=generation, generations=self.ga_cfg.generations, best_fitness=best if best > -1e300 else 0.0,
            partner_versions={b.value: v for b, v in self.models.versions.items()},
            rejected=dict(self.rejected), done=done, sent_at=time.time(),
        )

    def _wait_for_broker(self, session: Any) -> None:
        """Wait (up to ``broker_wait`` s) for a broker whose store is up, so nothing is published into the void."""
        end = time.monotonic() + self.broker_wait
        while time.monotonic() < end and not self._stop.is_set():
            if any(r.ok is not None for r in session.liveliness().get(keys.BROKER, timeout=1.0)):
                return
            time.sleep(0.2)
        log.warning("%s: no coevo broker seen after %.0f s; going on without a store", self.worker_id, self.broker_wait)

    def _fetch_from_store(self, session: Any) -> None:
        """A late or restarted worker gets the partners' current best at once."""
        if self.models.kind == "current":
            return  # current policies are not stored; the next generation's arrives within a generation
        for b in self.models.needed:
            try:
                for reply in session.get(keys.store_latest(self.run_id, b), timeout=self.store_timeout):
                    if reply.ok is not None:
                        with self._lock:
                            self._inbox.append((keys.policy(self.run_id, b), bytes(reply.ok.payload.to_bytes())))
            except Exception as exc:  # no broker store yet: the subscription will catch up
                log.info("store query for %s failed: %s", b, exc)
