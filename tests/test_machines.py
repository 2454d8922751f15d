"""The same numbers on every machine: the exactness fixture replayed as other processors would compute it.

What decides the last bits of a floating-point result, besides the code: the BLAS kernel OpenBLAS picks for the
processor (``OPENBLAS_CORETYPE`` forces one), numpy's SIMD code chosen at run time (``NPY_DISABLE_CPU_FEATURES``
turns it off), libm's code paths for processors with and without FMA (``GLIBC_TUNABLES``).  Each variant runs
``tests/test_exact_curves.py --paths`` in a subprocess, with numpy's world and, where it matters, the compiled one,
and must give ``tests/data/exact_curves.json`` exactly; and Appendix D's landscapes must give the values they give
in this process.  A core type this processor lacks (SkylakeX without
AVX-512) would crash OpenBLAS, so only those it supports run; the others skip, saying why.  (Threads decide no
order of sums: nothing exact calls the BLAS, and the compiled loops run on one thread.)
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from coevo.rundir.machine import cpu_flags, numpy_dispatch

HERE = Path(__file__).parent
FIXTURE = HERE / "data" / "exact_curves.json"

# OpenBLAS core type -> the processor flags (as /proc/cpuinfo names them) its kernels use
_CORETYPES = {
    "Prescott": {"pni"},  # SSE3
    "Haswell": {"avx2", "fma"},  # also what OpenBLAS runs on Zen
    "SkylakeX": {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"},
}


def _uses_openblas() -> bool:
    try:
        blas = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
    except (KeyError, TypeError):
        return False
    return "openblas" in str(blas.get("name", "")).lower()


def _variants() -> list[object]:
    flags, x86 = cpu_flags(), platform.machine() in ("x86_64", "AMD64")
    out = []
    for core, needs in _CORETYPES.items():
        why = ("numpy's BLAS is not OpenBLAS" if not _uses_openblas() else "not an x86-64 processor" if not x86
               else f"this processor lacks {', '.join(sorted(needs - flags))}" if needs - flags else "")
        out.append(pytest.param({"OPENBLAS_CORETYPE": core}, "numpy", id=f"openblas-{core}",
                                marks=[pytest.mark.skip(reason=why)] if why else []))
    simd = numpy_dispatch()
    out.append(pytest.param({"NPY_DISABLE_CPU_FEATURES": " ".join(simd)}, "numpy,compiled", id="numpy-no-simd",
                            marks=[] if simd else [pytest.mark.skip(reason="numpy runs no optional SIMD code here")]))
    glibc = platform.libc_ver()[0] == "glibc" and x86 and "fma" in flags
    out.append(pytest.param({"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA"}, "numpy", id="libm-no-fma",
                            marks=[] if glibc else [pytest.mark.skip(reason="not glibc on an x86-64 with FMA")]))
    return out


def landscape_digest() -> str:
    """Appendix D's landscapes, their exponentials, logarithms and products: a hash of fitness values of random
    points, in float64 and float32, in the dense path and the cells'."""
    import hashlib

    from coevo.experiments.evolvability.landscape import CLASSES, DynamicLandscape

    h = hashlib.sha256()
    for name, spec in sorted(CLASSES.items()):
        land = DynamicLandscape(spec, seed=3, generations=25)
        x = np.random.default_rng(4).uniform(spec.low - 5, spec.high, (600, spec.dim))
        for t in (0, 24):
            for dtype in (np.float64, np.float32):
                h.update(land.fitness(x, t, dtype=dtype).tobytes())
    return h.hexdigest()


@pytest.mark.service
@pytest.mark.parametrize(("env", "paths"), _variants())
def test_fixture_replays_under(env: dict[str, str], paths: str) -> None:
    variant = {**os.environ, **env}
    land = subprocess.run([sys.executable, __file__, "--landscape"], env=variant, capture_output=True, text=True,
                          timeout=120)
    assert land.returncode == 0 and land.stdout.strip() == landscape_digest(), land.stderr[-3000:]
    proc = subprocess.run([sys.executable, str(HERE / "test_exact_curves.py"), "--paths", paths],
                          env=variant, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    got = json.loads(proc.stdout)
    expected = json.loads(FIXTURE.read_text(encoding="utf-8"))
    sys.path.insert(0, str(HERE))
    from test_exact_curves import _diff

    for path, numbers in got.items():
        diffs = _diff(numbers, expected)
        assert not diffs, f"{env} ({path}): {len(diffs)} differences, first: " + "\n".join(diffs[:10])


@pytest.mark.service
def test_run_recorded_under_other_kernels_checks_exact_here(tmp_path: Path) -> None:
    """A whole ``coevo run`` recorded with another BLAS kernel and without numpy's SIMD code replays exactly under
    this process's defaults; and when a number does differ, ``coevo replay`` names what differs between the machines."""
    flags, simd = cpu_flags(), numpy_dispatch()
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": " ".join(simd)}
    if _uses_openblas() and platform.machine() in ("x86_64", "AMD64"):
        env["OPENBLAS_CORETYPE"] = "Haswell" if {"avx2", "fma"} <= flags else "Prescott"
    run = subprocess.run([sys.executable, "-m", "coevo", "run", "--run", "elsewhere", "--root", str(tmp_path),
                          "--generations", "3", "--population", "6", "--episodes", "10", "--ga", "best_episodes=10",
                          "--ga", "initial_rules=8", "--quiet"], env=env, capture_output=True, text=True, timeout=180)
    assert run.returncode == 0, run.stdout + run.stderr
    rundir = tmp_path / "elsewhere"
    machines = rundir / "workers" / "tracking" / "machines.jsonl"
    recorded = [json.loads(line) for line in machines.read_text().splitlines()]
    assert len(recorded) == 1 and recorded[0]["numpy"] == np.__version__
    check = subprocess.run([sys.executable, "-m", "coevo", "check", str(rundir)], capture_output=True, text=True,
                           timeout=180)
    assert check.returncode == 0 and "replay exact" in check.stdout, check.stdout + check.stderr
    curve = rundir / "workers" / "tracking" / "curve.jsonl"
    rows = [json.loads(line) for line in curve.read_text().splitlines()]
    rows[1]["population_mean"] += 1e-12  # a number that differs
    curve.write_text("".join(json.dumps(r) + "\n" for r in rows))
    replay = subprocess.run([sys.executable, "-m", "coevo", "replay", str(rundir)], capture_output=True, text=True,
                            timeout=180)
    assert replay.returncode == 1
    line = next(x for x in replay.stdout.splitlines() if x.startswith("tracking"))
    assert "DIFFERS at generation 2: population_mean" in line
    if simd:
        assert "env NPY_DISABLE_CPU_FEATURES" in line and "numpy_simd" in line


if __name__ == "__main__":
    if sys.argv[1:] == ["--landscape"]:
        print(landscape_digest())
