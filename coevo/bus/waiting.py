"""Waits on something outside this process (a router, a scheduler) are never silent: they say so while they last."""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["still_waiting"]


@contextmanager
def still_waiting(what: str, *, after: float = 1.0, every: float = 1.5) -> Iterator[None]:
    """While the block waits on something outside this process (a router, a scheduler), say so on stderr, first after
    ``after`` seconds and then every ``every``: ``still opening the zenoh status session (connecting to ...): 4 s``,
    so that no wait is silent for longer (nothing is said of a wait that ends sooner)."""
    done = threading.Event()
    t0 = time.monotonic()

    def tick() -> None:
        wait = after
        while not done.wait(wait):
            print(f"still {what}: {time.monotonic() - t0:.0f} s", file=sys.stderr, flush=True)
            wait = every

    ticker = threading.Thread(target=tick, name="still-waiting", daemon=True)
    ticker.start()
    try:
        yield
    finally:
        done.set()
