"""Fault injection for the suite's own processes, kept out of the product.

A process started with this folder first on ``PYTHONPATH`` imports this module before anything else (Python's
``site`` does, for any ``sitecustomize`` on the path).  With ``COEVO_TEST_HANG_AFTER=N`` in its environment, a coevo
worker's main thread hangs after generation N: its Zenoh threads, and so its liveliness token, live on, while its
heartbeats stop (tests/test_faults.py, a hung worker shows "stalled").
"""

from __future__ import annotations

import os
import time

HANG_ENV = "COEVO_TEST_HANG_AFTER"

if os.environ.get(HANG_ENV):
    import logging

    from coevo.agents.worker import Worker

    _after = int(os.environ[HANG_ENV])
    _one_generation = Worker.one_generation

    def _hanging(self: Worker, *args: object, **kwargs: object) -> object:
        rep = _one_generation(self, *args, **kwargs)  # type: ignore[arg-type]
        if rep.generation >= _after:
            logging.getLogger("coevo.agents.worker").warning("%s: hanging after generation %d (fault injection, $%s)",
                                                             self.worker_id, rep.generation, HANG_ENV)
            while True:
                time.sleep(1.0)
        return rep

    Worker.one_generation = _hanging  # type: ignore[method-assign]
