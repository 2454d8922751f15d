"""Continuous and Embedded Learning as live processes on the bus (Appendix B, ``coevo cel``).

* :mod:`coevo.cel_service.learner`: the learning module as a worker process (``coevo worker
  --behaviour door`` in a run whose ``run.json`` has a ``cel`` block), the co-evolution worker
  with the CEL learner plugged into its seam;
* :mod:`coevo.cel_service.robot`: the execution module and its monitor as a process
  (``coevo execution``).

What they run is :mod:`coevo.cel` (the in-process modules, no network); how a whole CEL run is
started on one machine is :mod:`coevo.cel_service.run`.
"""
