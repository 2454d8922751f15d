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
