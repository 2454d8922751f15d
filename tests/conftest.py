from __future__ import annotations

import numpy as np
import pytest
from procs import broker  # noqa: F401  (a fixture for every test module)

from coevo.config import GAConfig
from coevo.tasks.fuel.settings import WorldConfig


@pytest.fixture
def world_cfg() -> WorldConfig:
    return WorldConfig()


@pytest.fixture
def small_ga() -> GAConfig:
    return GAConfig(generations=2, population=6, episodes=20, best_episodes=20, initial_rules=8)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


# ---------------------------------------------------------------- the two test sets
def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--all", action="store_true",
                     help="also run the tests that start processes (service, faults, trust, deploy, whole comparisons): "
                          "the whole suite, what CI runs")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Without --all, the fast set: tests marked service or slow (and any using the broker fixture, a process) are
    left out, and say so in the summary."""
    for item in items:
        if "broker" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.service)
    if config.getoption("--all"):
        return
    keep = [i for i in items if not (i.get_closest_marker("service") or i.get_closest_marker("slow"))]
    dropped = [i for i in items if i not in keep]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = keep
