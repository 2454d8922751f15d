"""coevo: asynchronous co-evolution of robot behaviours with SAMUEL-style rule GAs.

The core (``coevo.policy``, ``coevo.ga``) and the tasks (``coevo.tasks``) are plain deterministic
library code with no network; ``coevo.agents`` and ``coevo.broker`` put it on
Eclipse Zenoh.
"""

from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["__version__"]
