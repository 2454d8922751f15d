"""Where replicates run: this machine (``--jobs``) or a Dask cluster (``--cluster``).

Both take a :class:`~coevo.replicates.replicate.Replicate` and give back a handle with ``done()``;
:meth:`Backend.outcome` turns a finished handle into an :class:`Outcome` with the replicate's output
already in the experiment's folder.

``--cluster`` is ``local`` or ``local:N`` (a :class:`distributed.LocalCluster` of N worker processes of
one thread each, default one per two cores), ``slurm[:N]`` or ``pbs[:N]`` (N batch jobs through
dask-jobqueue, configured by ``--cluster-config FILE``, see deploy/slurm/), or the address of a running
scheduler (``tcp://host:8786``).  Dask is imported only here, and only when a cluster is asked for.
"""

from __future__ import annotations

import concurrent.futures
import logging
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

from coevo.errors import ConfigError, ServiceError
from coevo.replicates.replicate import Outcome, Replicate, execute, pack, running, unpack

if TYPE_CHECKING:  # Dask is imported only when a cluster is asked for
    from distributed import Client, Future
    from dask_jobqueue.core import JobQueueCluster
    from distributed.deploy.cluster import Cluster

__all__ = ["Handle", "Backend", "LocalBackend", "DaskBackend", "ClusterLost", "DEFAULT_CONNECT_TIMEOUT", "open_backend", "parse_cluster"]

log = logging.getLogger(__name__)


class ClusterLost(ServiceError):
    """The Dask scheduler is gone: the experiment stops; its finished replicates are kept for ``--resume``."""


class Handle(Protocol):
    """A replicate running on a backend (a future of its outcome): :func:`~coevo.replicates.runner.run_replicates`
    asks it whether it is done, and hands it back to its backend's :meth:`Backend.outcome`."""

    def done(self) -> bool: ...


H = TypeVar("H", bound=Handle)


class Backend(Generic[H]):
    """Runs replicates; ``room`` says whether one more fits now.  ``H``: its handle on a running replicate."""

    description = ""

    def room(self, busy_weight: int, rep: Replicate) -> bool:
        return True

    def submit(self, rep: Replicate, out: Path) -> H:
        raise NotImplementedError

    def outcome(self, handle: H, rep: Replicate, out: Path) -> Outcome:
        raise NotImplementedError

    def check(self) -> None:
        """Raise :class:`ClusterLost` if the backend can no longer run anything."""

    def stop(self, handles: list[H]) -> None:
        """Stop what still runs (the experiment was interrupted or failed)."""

    def close(self) -> None:
        pass


class LocalBackend(Backend["concurrent.futures.Future[Outcome]"]):
    """``jobs`` half-slot pairs on this machine: a live run takes two half-slots, an offline learner one (as
    ``coevo compare`` always did).  Commands run from threads; functions in the thread when ``jobs`` is 1
    (as the experiment always ran them), else in a pool of processes."""

    def __init__(self, jobs: int) -> None:
        if jobs < 1:
            raise ConfigError(f"--jobs must be at least 1, got {jobs}")
        self.jobs = jobs
        self.description = f"{jobs} at a time"
        self._threads = concurrent.futures.ThreadPoolExecutor(max_workers=2 * jobs)
        self._procs: concurrent.futures.ProcessPoolExecutor | None = None

    def room(self, busy_weight: int, rep: Replicate) -> bool:
        return busy_weight == 0 or busy_weight + rep.weight <= 2 * self.jobs

    def submit(self, rep: Replicate, out: Path) -> concurrent.futures.Future[Outcome]:
        if rep.function is not None and self.jobs > 1:
            if self._procs is None:
                import multiprocessing

                self._procs = concurrent.futures.ProcessPoolExecutor(self.jobs, mp_context=multiprocessing.get_context("spawn"))
            return self._procs.submit(execute, rep, str(out))
        return self._threads.submit(execute, rep, str(out))

    def outcome(self, handle: concurrent.futures.Future[Outcome], rep: Replicate, out: Path) -> Outcome:
        try:
            return handle.result()
        except Exception as exc:  # the process pool lost a process, or execute itself failed
            return Outcome(rep.name, False, f"{type(exc).__name__}: {exc}")

    def stop(self, handles: list[concurrent.futures.Future[Outcome]]) -> None:
        for p in list(running):
            if p.poll() is None:
                p.terminate()  # coevo run turns SIGTERM into a clean stop of its broker and workers
        deadline = time.monotonic() + 30
        for p in list(running):
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except Exception:
                p.kill()
        if self._procs is not None:
            for pid, proc in list(getattr(self._procs, "_processes", {}).items()):
                proc.terminate()

    def close(self) -> None:
        self._threads.shutdown(wait=True, cancel_futures=True)
        if self._procs is not None:
            self._procs.shutdown(wait=True, cancel_futures=True)


def parse_cluster(text: str) -> tuple[str, int | None]:
    """``local[:N]`` / ``slurm[:N]`` / ``pbs[:N]`` -> (kind, N); anything else is a scheduler address."""
    kind, _, n = text.partition(":")
    if kind in ("local", "slurm", "pbs"):
        if not n:
            return kind, None
        if not n.isdigit() or int(n) < 1:
            raise ConfigError(f"--cluster {text}: after {kind}: give a number of workers >= 1")
        return kind, int(n)
    import re

    if not re.fullmatch(r"((tcp|tls|inproc|ucx)://)?[A-Za-z0-9_.\-\[\]:]+:[0-9]{1,5}", text):
        raise ConfigError(f"--cluster {text!r}: give local[:N], slurm[:N], pbs[:N] or a scheduler address "
                          "(tcp://HOST:PORT)")
    return "address", None


class DaskBackend(Backend["Future"]):
    """Replicates as Dask tasks (one thread each).  A replicate whose worker dies is run again by the scheduler
    (up to ``distributed.scheduler.allowed-failures`` times, 3 by default); one that fails for its own reasons
    comes back as a failed :class:`Outcome` and is not retried.  Without ``shared_dir`` each replicate's inputs
    travel with it and its output comes back as a tar; with it, the workers read and write the experiment's
    folder there."""

    def __init__(self, client: Client, cluster: Cluster | None = None, *, shared_dir: Path | None = None,
                 label: str = "") -> None:
        self.client, self.cluster, self.shared_dir = client, cluster, shared_dir
        self.description = f"on the Dask cluster {label}"
        self._token = os.urandom(3).hex()

    def submit(self, rep: Replicate, out: Path) -> Future:
        key = f"coevo-{rep.name}-{self._token}"
        if self.shared_dir is not None:
            return self.client.submit(execute, rep, str(self.shared_dir), key=key, pure=False, retries=0)
        # its inputs, and a half-done copy of its own output (it continues from its checkpoints)
        payload = pack(out, *rep.inputs, rep.output)
        return self.client.submit(execute, rep, None, payload, key=key, pure=False, retries=0)

    def check(self) -> None:
        if self.client.status not in ("running", "newly-created"):
            raise ClusterLost(f"lost the Dask scheduler at {self.client.scheduler.address} (client {self.client.status})")

    def outcome(self, handle: Future, rep: Replicate, out: Path) -> Outcome:
        from distributed import KilledWorker

        if handle.status == "cancelled":
            raise ClusterLost(f"lost the Dask scheduler at {self.client.scheduler.address}")
        try:
            res: Outcome = handle.result()
        except KilledWorker as exc:
            return Outcome(rep.name, False, f"its Dask worker died every time it ran ({exc})")
        except Exception as exc:
            if self.client.status != "running":
                raise ClusterLost(f"lost the Dask scheduler at {self.client.scheduler.address}") from exc
            return Outcome(rep.name, False, f"{type(exc).__name__}: {exc}")
        if res.payload is not None:
            unpack(res.payload, out, replace=rep.output)
        if res.log is not None:
            (out / "logs").mkdir(exist_ok=True)
            (out / "logs" / f"{rep.name}.log").write_bytes(res.log)
        res.payload = res.log = None
        return res

    def stop(self, handles: list[Future]) -> None:
        try:
            self.client.cancel(handles)
        except Exception:
            pass

    def close(self) -> None:
        for thing in (self.client, self.cluster):
            if thing is not None:
                try:
                    thing.close()
                except Exception:
                    pass


def _jobqueue(kind: str, config: Path | None) -> JobQueueCluster:
    """A SLURMCluster or PBSCluster (no job submitted yet) from the dask-jobqueue YAML ``config``."""
    import dask.config
    import yaml

    if config is not None:
        try:
            values = yaml.safe_load(config.read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f"--cluster-config {config}: {exc}") from exc
        dask.config.update(dask.config.config, values or {}, priority="new")
    from dask_jobqueue import PBSCluster, SLURMCluster

    return (SLURMCluster if kind == "slurm" else PBSCluster)()


#: Seconds a scheduler's address is tried before ``--cluster ADDRESS`` gives up (``--cluster-timeout``).
DEFAULT_CONNECT_TIMEOUT = 30.0


def open_backend(*, jobs: int, cluster: str | None = None, cluster_config: Path | None = None,
                 shared_dir: Path | None = None, connect_timeout: float = DEFAULT_CONNECT_TIMEOUT) -> Backend[Any]:
    """The backend the flags ask for (no ``cluster``: this machine, ``jobs`` at a time); ``connect_timeout``: the
    seconds to reach a cluster's scheduler."""
    if cluster is None:
        if shared_dir is not None or cluster_config is not None:
            raise ConfigError("--shared-dir and --cluster-config go with --cluster")
        return LocalBackend(jobs)
    kind, n = parse_cluster(cluster)
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - a dependency
        raise ConfigError(f"--cluster needs Dask (pip install distributed): {exc}") from exc
    logging.getLogger("distributed").setLevel(logging.ERROR)
    made: Cluster | None = None
    address: Cluster | str
    try:
        if kind == "local":
            n = n or max(1, (os.cpu_count() or 1) // 2)
            # No dashboard; the scheduler's HTTP server (health routes) on a free loopback port, not on 8787 of
            # every interface, where a second cluster or another program finds it taken.
            made = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"}, silence_logs=logging.ERROR)
            address, label = made, f"local:{n}"
        elif kind in ("slurm", "pbs"):
            queue = made = _jobqueue(kind, cluster_config)
            queue.scale(jobs=n or 1)  # submits the batch jobs; workers join as the jobs start
            address, label = made, f"{kind} ({n or 1} jobs)"
        else:
            address, label = cluster, cluster
        client = Client(address, timeout=f"{connect_timeout}s")
    except ValueError as exc:  # an address Dask cannot parse
        if made is not None:
            made.close()
        raise ConfigError(f"--cluster {cluster!r}: {exc}") from exc
    except (OSError, TimeoutError) as exc:
        if made is not None:
            made.close()
        raise ClusterLost(f"cannot reach the Dask scheduler {cluster} within {connect_timeout:g} s: {exc}") from exc
    return DaskBackend(client, made, shared_dir=shared_dir, label=label)
