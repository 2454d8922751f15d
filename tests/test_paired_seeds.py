"""benchmarks/paired_seeds.py: variants paired by seed, and a clear error for a folder that is no summary."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "paired_seeds.py"


def _summary(folder: Path, values: dict[int, float]) -> str:
    folder.mkdir()
    runs = [{"behaviour": "docking", "seed": s, "docking_from_random_starts": v} for s, v in values.items()]
    (folder / "summary.json").write_text(json.dumps({"runs": runs}))
    return str(folder)


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(SCRIPT), *args], check=False, capture_output=True, text=True, timeout=60)


def test_variants_are_paired_by_the_seeds_they_share(tmp_path: Path) -> None:
    base = _summary(tmp_path / "a", {0: 40.0, 1: 50.0, 2: 60.0, 3: 70.0})
    more = _summary(tmp_path / "b", {1: 55.0, 2: 66.0, 3: 77.0, 9: 0.0})  # seed 0 missing, seed 9 extra
    r = _run(base, more)
    assert r.returncode == 0, r.stderr
    assert "3 seeds in common (1-3)" in r.stdout
    row = r.stdout.splitlines()[-1].split()
    assert row[1:6] == ["66.0", "66.0", "+6.0", "0.6", "3/3"]  # median, mean, mean difference (5, 6, 7), its se 1/sqrt(3), wins


def test_a_folder_without_a_summary_is_named(tmp_path: Path) -> None:
    r = _run(str(tmp_path / "nowhere"), _summary(tmp_path / "b", {0: 1.0, 1: 2.0}))
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "nowhere" in r.stderr and "coevo seeds" in r.stderr


def test_an_empty_folder_name_in_a_variant_is_named(tmp_path: Path) -> None:
    good = _summary(tmp_path / "a", {0: 1.0, 1: 2.0})
    r = _run(good, f"{good},,{good}")
    assert r.returncode == 1 and "Traceback" not in r.stderr and "empty folder name" in r.stderr
