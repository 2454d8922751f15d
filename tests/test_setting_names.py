"""A misspelt ``--ga``/``--world`` name is one line naming the nearest known name and listing them all (issue 55:
``--ga mutation_rat=0.1`` said only pydantic's "Extra inputs are not permitted"), as a study's ``--factor`` does."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from coevo.config import GAConfig, build, did_you_mean
from coevo.errors import ConfigError


def test_a_misspelt_setting_names_the_nearest_and_lists_every_setting() -> None:
    with pytest.raises(ConfigError) as caught:
        build(GAConfig, {"mutation_rat": 0.1})
    msg = str(caught.value)
    assert msg.startswith("GAConfig: mutation_rat=0.1: unknown setting; did you mean mutation_rate? Known settings: ")
    assert all(name in msg for name in GAConfig.model_fields) and "Extra inputs" not in msg
    with pytest.raises(ConfigError, match=r"zzz=1: unknown setting\. Known settings: generations, "):
        build(GAConfig, {"zzz": 1})  # nothing near: no guess, the list
    with pytest.raises(ConfigError, match=r"population=0: Input should be greater"):  # other errors as before
        build(GAConfig, {"population": 0})
    assert did_you_mean("max_led", ["max_lead", "model"]) == "; did you mean max_lead?"
    assert did_you_mean("arena_sise", ["arena"], prefix="world.") == "; did you mean world.arena?"
    assert did_you_mean("qqq", ["arena"]) == ""


def test_the_command_line_says_it_before_anything_runs(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    r = subprocess.run([sys.executable, "-m", "coevo", "compare", "--out", str(out), "--world", "arena_sise=300"],
                       capture_output=True, text=True, timeout=120, check=False)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "arena_sise=300: unknown setting; did you mean arena? Known settings: arena, " in r.stderr
    assert not out.exists()
