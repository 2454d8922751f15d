"""The one job loop: run an experiment's replicates on a backend, with progress, resume and failures.

Finished replicates (``Replicate.finished`` under the experiment's folder) are skipped, which is what
``--resume`` means for every experiment; a replicate waits for those it comes ``after``, and is skipped,
with the reason, when one of them failed.  A failed replicate is reported with why (the last line of its
log, or that its Dask worker kept dying), never retried here: ``--resume`` runs it again.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from coevo.replicates.backends import Backend, H
from coevo.replicates.replicate import Outcome, Replicate
from coevo.rundir.layout import sigterm_stops

__all__ = ["Progress", "run_replicates"]

log = logging.getLogger(__name__)


@dataclass
class Progress:
    """What a display needs: units done of the total, replicates done, failures with their reasons."""

    total: int
    done: int = 0
    runs_total: int = 0
    runs_done: int = 0
    failed: dict[str, str] = field(default_factory=dict)  # name -> why
    outcomes: list[Outcome] = field(default_factory=list)  # this session's, in the order they ended

    @property
    def info(self) -> str:
        return f"runs {self.runs_done}/{self.runs_total}" + (f", {len(self.failed)} failed" if self.failed else "")


def run_replicates(
    reps: Sequence[Replicate],
    out: Path,
    backend: Backend[H],
    *,
    on_progress: Callable[[Progress], None] | None = None,
    poll: float = 1.0,
) -> Progress:
    """Run the unfinished ones of ``reps``; returns the final :class:`Progress` (``failed`` says which and why).
    Raises :class:`~coevo.replicates.backends.ClusterLost` when the cluster goes; interruptions stop what runs."""
    out = Path(out)
    names = [r.name for r in reps]
    if len(set(names)) != len(names):
        raise ValueError("replicate names repeat")
    unknown = {d for r in reps for d in r.after} - set(names)
    if unknown:
        raise ValueError(f"replicates wait for ones that are not in the list: {sorted(unknown)}")
    finished = {r.name for r in reps if r.finished(out)}
    prog = Progress(total=sum(r.cost for r in reps), runs_total=len(reps), runs_done=len(finished))
    base = sum(r.cost for r in reps if r.name in finished)
    pending = [r for r in reps if r.name not in finished]
    active: dict[str, tuple[Replicate, H]] = {}
    started: dict[str, float] = {}
    (out / "logs").mkdir(parents=True, exist_ok=True)
    with sigterm_stops():  # a SIGTERM (to the experiment or its process group) stops what runs in order, as Ctrl-C
        try:
            while pending or active:
                for rep in list(pending):
                    lost = [d for d in rep.after if d in prog.failed]
                    if lost:
                        pending.remove(rep)
                        prog.failed[rep.name] = f"skipped: {lost[0]}, which it needs, failed"
                        log.error("run %s skipped: the run it needs, %s, failed", rep.name, lost[0])
                        continue
                    if any(d not in finished for d in rep.after):
                        continue
                    if not backend.room(sum(r.weight for r, _ in active.values()), rep):
                        continue
                    pending.remove(rep)
                    started[rep.name] = time.perf_counter()
                    active[rep.name] = (rep, backend.submit(rep, out))
                time.sleep(poll)
                backend.check()
                for name, (rep, handle) in list(active.items()):
                    if not handle.done():
                        continue
                    del active[name]
                    res = backend.outcome(handle, rep, out)
                    res.wall = time.perf_counter() - started[name]
                    prog.outcomes.append(res)
                    if res.ok:
                        finished.add(name)
                        prog.runs_done += 1
                        base += rep.cost
                    else:
                        prog.failed[name] = res.reason
                        log.error("run %s failed: %s; see %s", name, res.reason, out / "logs" / f"{name}.log")
                prog.done = base + sum(min(r.cost, r.progress(out)) for r, _ in active.values() if r.progress is not None)
                if on_progress:
                    on_progress(prog)
        finally:
            if active:
                backend.stop([h for _, h in active.values()])
            backend.close()
    return prog
