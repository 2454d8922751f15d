"""A run's directory: every file it holds (:mod:`coevo.rundir.layout`) and the settings all of
its processes share (:mod:`coevo.rundir.settings`, its ``run.json``).

It sits between the bus and the processes: the workers, the broker, the CEL modules and the
run tools all read and write a run directory through it, and it knows none of them.
"""
