"""Many runs, one way: a list of replicates run ``--jobs`` at a time here, or on a Dask cluster.

Every experiment that repeats runs (``coevo compare``, ``coevo evolvability``, ...) describes its
replicates (:class:`~coevo.replicates.replicate.Replicate`: a command or a function, the folder it
writes, what it reads, what it waits for) and hands them to
:func:`~coevo.replicates.runner.run_replicates` with a backend from
:func:`~coevo.replicates.backends.open_backend`.  The runner owns the job loop, the progress,
``--resume`` (finished replicates are skipped) and the list of failures with their reasons.

This module stays light: ``coevo --help`` imports no Dask.  See docs/cluster.md.
"""
