"""The flags every many-run command shares: ``--jobs``, ``--cluster``, ``--cluster-config``, ``--shared-dir``.

Light on purpose (argparse only): commands declare these at ``coevo --help`` time.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from coevo.config import Bounded

__all__ = ["add_backend_flags", "check_backend_flags", "backend_of"]


def add_backend_flags(p: argparse.ArgumentParser, *, jobs_help: str) -> None:
    g = p.add_argument_group("where the runs go (docs/cluster.md)")
    g.add_argument("--jobs", type=Bounded(1, 1024), help=jobs_help)
    g.add_argument("--cluster", metavar="WHERE",
                   help="run the replicates on Dask: local[:N] (N worker processes here, 1 thread each), "
                        "slurm[:N] or pbs[:N] (N batch jobs, see --cluster-config), or a scheduler's address "
                        "(tcp://host:8786); default: this machine, --jobs at a time")
    g.add_argument("--cluster-timeout", type=Bounded(0, 3600, whole=False, above=True), metavar="SECONDS",
                   help="with --cluster ADDRESS: how long to try to reach the scheduler before giving up (default 30)")
    g.add_argument("--cluster-config", type=Path, metavar="FILE",
                   help="with --cluster slurm/pbs: a dask-jobqueue YAML (deploy/slurm/jobqueue.yaml)")
    g.add_argument("--shared-dir", type=Path, metavar="DIR",
                   help="with --cluster: the workers see --out at DIR (a shared filesystem); runs are written "
                        "there in place instead of coming back as archives")


def check_backend_flags(args: argparse.Namespace) -> None:
    """The flags checked without opening anything (a bad one is a ConfigError naming it), so that a command can
    refuse them before it writes into ``--out``."""
    from coevo.errors import ConfigError
    from coevo.replicates.backends import parse_cluster

    if args.cluster is not None:
        if parse_cluster(args.cluster)[0] != "address" and args.cluster_timeout is not None:
            raise ConfigError(f"--cluster-timeout goes with --cluster ADDRESS (a scheduler to reach), not {args.cluster}")
        if args.shared_dir is not None and args.shared_dir.exists() and not args.shared_dir.is_dir():
            raise ConfigError(f"--shared-dir {str(args.shared_dir)!r} is not a directory: give the folder where the "
                              "workers see --out")
    elif args.shared_dir is not None or args.cluster_config is not None or args.cluster_timeout is not None:
        raise ConfigError("--shared-dir, --cluster-config and --cluster-timeout go with --cluster")


def backend_of(args: argparse.Namespace, *, default_jobs: int) -> Any:
    """The backend the flags ask for (imports Dask only for ``--cluster``).  With ``--cluster``, says at once on
    stderr where it goes: reaching a scheduler, or starting a cluster, may take a while."""
    from coevo.bus.waiting import still_waiting
    from coevo.replicates.backends import DEFAULT_CONNECT_TIMEOUT, open_backend, parse_cluster

    timeout = DEFAULT_CONNECT_TIMEOUT if args.cluster_timeout is None else args.cluster_timeout
    if args.cluster is not None:
        kind, n = parse_cluster(args.cluster)
        where = {"address": f"connecting to the Dask scheduler at {args.cluster} (giving up after {timeout:g} s; "
                            "--cluster-timeout)",
                 "local": "starting a local Dask cluster"}.get(kind, f"submitting {n or 1} {kind} batch jobs")
        print(f"--cluster: {where}", file=sys.stderr, flush=True)
    with still_waiting(f"{where}" if args.cluster is not None else "starting the local processes"):
        return open_backend(jobs=default_jobs if args.jobs is None else args.jobs, cluster=args.cluster,
                            cluster_config=args.cluster_config, connect_timeout=timeout,
                            shared_dir=None if args.shared_dir is None else args.shared_dir.resolve())
