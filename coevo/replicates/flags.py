"""The flags every many-run command shares: ``--jobs``, ``--cluster``, ``--cluster-config``, ``--shared-dir``.

Light on purpose (argparse only): commands declare these at ``coevo --help`` time.
"""

from __future__ import annotations

import argparse
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
        parse_cluster(args.cluster)
        if args.shared_dir is not None and args.shared_dir.exists() and not args.shared_dir.is_dir():
            raise ConfigError(f"--shared-dir {str(args.shared_dir)!r} is not a directory: give the folder where the "
                              "workers see --out")
    elif args.shared_dir is not None or args.cluster_config is not None:
        raise ConfigError("--shared-dir and --cluster-config go with --cluster")


def backend_of(args: argparse.Namespace, *, default_jobs: int) -> Any:
    """The backend the flags ask for (imports Dask only for ``--cluster``)."""
    from coevo.replicates.backends import open_backend

    return open_backend(jobs=default_jobs if args.jobs is None else args.jobs, cluster=args.cluster,
                        cluster_config=args.cluster_config,
                        shared_dir=None if args.shared_dir is None else args.shared_dir.resolve())
