"""What decides a run's last bits besides its code and settings: the machine it ran on, as a run directory records it.

The world, the GA and the strength updates compute with basic IEEE operations in a fixed order and with
:mod:`coevo.exactmath`'s elementary functions, so their numbers are the same on every machine
(docs/development.md, "What is exact where").  What could still make a replay differ is recorded: the versions of
Python, numpy, numba and pymunk (a new release may compute a function another way), the BLAS with the kernel its
processor picked, numpy's SIMD code in use, the C library, and the processor.  Each worker appends this record to
its ``machines.jsonl`` at every start; ``coevo replay`` and ``coevo check`` name what differs here when a number
does.
"""

from __future__ import annotations

import os
import platform
import sys
from functools import cache
from importlib import metadata
from typing import Any

__all__ = ["machine", "cpu_flags", "differences"]

#: The processor flags worth recording: those that change which code a library runs (BLAS, numpy, libm; pni: SSE3).
_FLAGS = ("pni", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512vl", "neon", "asimd", "sve")
#: The environment variables that change it.
_ENV = ("OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "NPY_DISABLE_CPU_FEATURES",
        "NPY_ENABLE_CPU_FEATURES", "GLIBC_TUNABLES", "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")


@cache
def cpu_flags() -> frozenset[str]:
    """The processor's feature flags as Linux's ``/proc/cpuinfo`` names them (``pni`` is SSE3); empty elsewhere."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith(("flags", "Features")):
                    return frozenset(line.split(":", 1)[1].split())
    except OSError:
        pass
    return frozenset()


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "?"


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "absent"


def _blas() -> str:
    """numpy's BLAS, its version and the kernel it runs here (threadpoolctl asks the loaded library itself)."""
    import numpy as np
    from threadpoolctl import threadpool_info

    np.ones(1) @ np.ones(1)  # the BLAS is loaded with numpy; a product makes sure
    for lib in threadpool_info():
        if lib.get("user_api") == "blas":
            return f"{lib.get('internal_api', '?')} {lib.get('version', '?')} {lib.get('architecture', '?')}"
    return "none found"


def _numpy_simd() -> str:
    """The optional SIMD targets numpy's dispatcher runs here (baseline + those enabled)."""
    try:
        from numpy._core._multiarray_umath import __cpu_baseline__, __cpu_dispatch__, __cpu_features__
    except ImportError:  # numpy 1.x
        from numpy.core._multiarray_umath import __cpu_baseline__, __cpu_dispatch__, __cpu_features__
    return " ".join([*__cpu_baseline__, *(f for f in __cpu_dispatch__ if __cpu_features__.get(f))])


@cache
def machine() -> dict[str, str]:
    """This machine, as far as it can decide a number: flat strings, so two records compare key by key."""
    flags = cpu_flags()
    record = {
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "numba": _version("numba"),
        "pymunk": _version("pymunk"),
        "blas": _blas(),
        "numpy_simd": _numpy_simd(),
        "libc": " ".join(platform.libc_ver()) or "?",
        "system": f"{platform.system()} {platform.machine()}",
        "processor": _cpu_model(),
        "processor_flags": " ".join(f for f in _FLAGS if f in flags) or "?",
        "byteorder": sys.byteorder,
    }
    record.update({f"env {k}": os.environ[k] for k in _ENV if k in os.environ})
    return record


def differences(recorded: dict[str, Any], here: dict[str, str] | None = None) -> list[str]:
    """What differs between a recorded machine and this one (``here``: :func:`machine`), e.g.
    ``"blas: openblas 0.3.31 Haswell -> openblas 0.3.31 SkylakeX"``; keys only one of them has count too."""
    here = machine() if here is None else here
    return [f"{k}: {recorded.get(k, 'unset')} -> {here.get(k, 'unset')}" for k in sorted(set(recorded) | set(here))
            if k not in ("started", "incarnation") and str(recorded.get(k, "unset")) != str(here.get(k, "unset"))]
