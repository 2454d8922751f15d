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

import importlib
import os
import platform
import sys
from functools import cache
from importlib import metadata
from typing import Any

__all__ = ["machine", "cpu_flags", "numpy_dispatch", "differences"]

#: The processor flags worth recording: those that change which code a library runs (BLAS, numpy, libm; pni: SSE3).
_FLAGS = ("pni", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512vl", "neon", "asimd", "sve")
#: The environment variables that change it.
_ENV = ("OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "NPY_DISABLE_CPU_FEATURES",
        "NPY_ENABLE_CPU_FEATURES", "GLIBC_TUNABLES", "NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES")


@cache
def _cpuinfo() -> dict[str, str]:
    """The first processor's fields in Linux's ``/proc/cpuinfo`` (empty elsewhere)."""
    out: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, sep, value = line.partition(":")
                if not sep:
                    if out:
                        break  # the first processor's block ended
                    continue
                out.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    return out


def cpu_flags() -> frozenset[str]:
    """The processor's feature flags as Linux's ``/proc/cpuinfo`` names them (``pni`` is SSE3); empty elsewhere."""
    info = _cpuinfo()
    return frozenset((info.get("flags") or info.get("Features") or "").split())


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


def _umath() -> Any:
    """numpy's compiled core, which lists the SIMD targets (``numpy._core`` since numpy 2, ``numpy.core`` before)."""
    try:
        return importlib.import_module("numpy._core._multiarray_umath")
    except ImportError:
        return importlib.import_module("numpy.core._multiarray_umath")


def numpy_dispatch() -> list[str]:
    """numpy's optional SIMD targets this processor runs (those ``NPY_DISABLE_CPU_FEATURES`` may turn off)."""
    umath = _umath()
    return [f for f in umath.__cpu_dispatch__ if umath.__cpu_features__.get(f)]


def _numpy_simd() -> str:
    """The SIMD targets numpy's dispatcher runs here: its baseline and the optional ones enabled."""
    return " ".join([*_umath().__cpu_baseline__, *numpy_dispatch()])


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
        "processor": _cpuinfo().get("model name") or platform.processor() or "?",
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
