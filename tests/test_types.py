"""The type checker over the package, with the settings of ``[tool.mypy]`` in pyproject.toml.

The core and the service (rules, GA, wire, broker, workers) are checked strictly; the rest with mypy's
defaults; no module is excused (``ignore_errors``), and a strict package's never may be.
"""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
STRICT = {"coevo.policy.*", "coevo.ga.*", "coevo.bus.*", "coevo.broker.*", "coevo.agents.*"}


def _overrides() -> list[dict[str, object]]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]["overrides"]


def test_the_strict_packages_stay_strict() -> None:
    strict = [o for o in _overrides() if o.get("disallow_untyped_defs") and o.get("warn_return_any")]
    assert strict and STRICT <= set(strict[0]["module"]), "the strict packages must keep --strict's flags"
    for o in _overrides():
        if o.get("ignore_errors"):
            excused = {m for m in o["module"] if any(m.startswith(s.rstrip("*")) for s in STRICT)}
            assert not excused, f"a strict package's module may not be excused from the type check: {excused}"


@pytest.mark.slow
def test_the_package_type_checks() -> None:
    done = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"mypy found errors:\n{done.stdout[-6000:]}{done.stderr[-2000:]}"
