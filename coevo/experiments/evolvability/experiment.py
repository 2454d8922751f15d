"""The report's Appendix D experiment: every model on every landscape class and base rate.

The grid is landscape classes × base rates × models × landscapes × runs (default
2 × 8 × 4 × 10 × 10 = 6400 runs of 200 generations, population 100).  All runs on
one landscape (every model, rate and replicate) advance together as one batch of
:func:`~coevo.experiments.evolvability.bitga.run_batch`.

Seeds: landscape ``i`` of a class comes from ``(seed, class, i)`` and is the same
whatever else the grid holds; the runs on it draw from ``(seed, class, i, 1)``, so a
run's numbers depend on the batch it ran in (the same options give the same numbers).
GM ignores the base rate; it is run at every rate anyway, as in the report.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from coevo.errors import ConfigError
from coevo.experiments.evolvability.bitga import RunParams, run_batch
from coevo.experiments.evolvability.landscape import CLASSES, DynamicLandscape
from coevo.ga.mutation import MODEL_NAMES
from coevo.replicates.backends import Backend, LocalBackend
from coevo.replicates.replicate import Replicate
from coevo.replicates.runner import run_replicates

__all__ = ["GridSpec", "GridResults", "RATES", "run_grid", "run_landscape", "replicates", "collect"]

RATES = (0.001, 0.003, 0.01, 0.03, 0.06, 0.1, 0.2, 0.3)


@dataclass(frozen=True)
class GridSpec:
    """What to run; :meth:`make` validates every value before anything runs."""

    classes: tuple[str, ...] = tuple(CLASSES)
    rates: tuple[float, ...] = RATES
    models: tuple[str, ...] = MODEL_NAMES
    landscapes: int = 10
    runs: int = 10
    generations: int = 200
    population: int = 100
    seed: int = 0
    alpha_m: float = 0.03
    hyper: float = 0.2
    alpha_h: float = 0.05
    crossover_rate: float = 0.6

    @staticmethod
    def make(**values: object) -> GridSpec:
        spec = GridSpec(**{k: v for k, v in values.items() if v is not None})  # type: ignore[arg-type]
        for name in ("classes", "rates", "models"):
            seq = getattr(spec, name)
            if not seq:
                raise ConfigError(f"--{name}: give at least one value")
            if len(set(seq)) != len(seq):
                raise ConfigError(f"--{name}: {list(seq)} repeats a value")
        for c in spec.classes:
            if c not in CLASSES:
                raise ConfigError(f"--classes: unknown landscape class {c!r}: choose from {', '.join(CLASSES)}")
        for m in spec.models:
            if m not in MODEL_NAMES:
                raise ConfigError(f"--models: unknown mutation model {m!r}: choose from {', '.join(MODEL_NAMES)}")
        for r in spec.rates:
            if not (isinstance(r, (int, float)) and 0 <= r <= 1):
                raise ConfigError(f"--rates: base mutation rate {r!r} is not a number in [0, 1]")
        for name in ("landscapes", "runs", "generations"):
            v = getattr(spec, name)
            if not (isinstance(v, int) and v >= 1):
                raise ConfigError(f"--{name} must be a whole number >= 1, got {v!r}")
        if not (isinstance(spec.population, int) and spec.population >= 2 and spec.population % 2 == 0):
            raise ConfigError(f"--population must be an even number >= 2, got {spec.population!r}")
        for name in ("alpha_m", "hyper", "alpha_h", "crossover_rate"):
            v = getattr(spec, name)
            if not 0 <= v <= 1:
                raise ConfigError(f"{name} {v!r} is not in [0, 1]")
        return GridSpec(**{**asdict(spec), "rates": tuple(sorted(float(r) for r in spec.rates))})

    @property
    def total_runs(self) -> int:
        return len(self.classes) * len(self.rates) * len(self.models) * self.landscapes * self.runs

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


@dataclass
class GridResults:
    """Per class, arrays of shape (models, rates, landscapes, runs, generations)."""

    spec: GridSpec
    mean: dict[str, np.ndarray] = field(default_factory=dict)
    best: dict[str, np.ndarray] = field(default_factory=dict)
    control: dict[str, np.ndarray] = field(default_factory=dict)
    changes: dict[str, list[int]] = field(default_factory=dict)  # generations at which each class's landscape moves
    seconds: float = 0.0

    def save(self, path: str) -> None:
        arrays = {f"{kind}_{c}": getattr(self, kind)[c] for kind in ("mean", "best", "control") for c in self.mean}
        np.savez_compressed(path, **arrays)

    @staticmethod
    def load(out: Path) -> GridResults:
        """The results a finished grid wrote to ``out`` (``results.json`` and ``curves.npz``)."""
        try:
            meta = json.loads((out / "results.json").read_text(encoding="utf-8"))
            curves = np.load(out / "curves.npz")
        except (OSError, ValueError) as exc:
            raise ConfigError(f"{out} holds no finished evolvability grid: {exc}") from exc
        spec = GridSpec.make(**{k: tuple(v) if isinstance(v, list) else v for k, v in meta["spec"].items()})
        res = GridResults(spec, changes={c: list(v) for c, v in meta["changes"].items()}, seconds=meta["seconds"] or 0.0)
        for c in spec.classes:
            for kind in ("mean", "best", "control"):
                getattr(res, kind)[c] = curves[f"{kind}_{c}"]
        return res


def _part(root: Path, cname: str, li: int) -> Path:
    return Path(root) / "landscapes" / f"{cname}-{li:02d}.npz"


def run_landscape(root: Path, *, spec: dict[str, Any], cname: str, li: int) -> None:
    """One replicate of the grid: every model, rate and run on landscape ``li`` of class ``cname``, as one batch;
    its curves go to ``root/landscapes/CLASS-LI.npz`` (written whole or not at all)."""
    g = GridSpec.make(**spec)
    M, K, N, T = len(g.models), len(g.rates), g.runs, g.generations
    models = [m for m in g.models for _ in g.rates for _ in range(N)]
    rates = [r for _ in g.models for r in g.rates for _ in range(N)]
    params = RunParams.make(models, rates, alpha_m=g.alpha_m, hyper=g.hyper, alpha_h=g.alpha_h)
    ci = list(CLASSES).index(cname)
    land = DynamicLandscape(CLASSES[cname], seed=np.random.SeedSequence([g.seed, ci, li]), generations=T)
    tr = run_batch(land, params, population=g.population, generations=T, crossover_rate=g.crossover_rate,
                   seed=np.random.SeedSequence([g.seed, ci, li, 1]))
    f = _part(root, cname, li)
    f.parent.mkdir(parents=True, exist_ok=True)
    tmp = f.with_name(f.stem + ".partial.npz")
    np.savez(tmp, changes=np.asarray(land.changes(), dtype=np.int64),
             **{name: getattr(tr, name).reshape(M, K, N, T) for name in ("mean", "best", "control")})
    os.replace(tmp, f)


def _has_part(cname: str, li: int, root: Path) -> bool:
    return _part(root, cname, li).exists()


def replicates(spec: GridSpec) -> list[Replicate]:
    """The grid as replicates for :mod:`coevo.replicates`: one per landscape (every model, rate and run on it
    advance together as one batch, as before); a landscape's numbers do not depend on where it ran."""
    out = []
    for cname in spec.classes:
        for li in range(spec.landscapes):
            out.append(Replicate(name=f"{cname}-{li:02d}", output=f"landscapes/{cname}-{li:02d}.npz",
                                 finished=partial(_has_part, cname, li), function=run_landscape,
                                 kwargs={"spec": spec.as_dict(), "cname": cname, "li": li}, weight=2,
                                 cost=spec.generations))
    return out


def collect(spec: GridSpec, out: Path) -> GridResults:
    """The grid's results from its finished landscapes in ``out``."""
    res = GridResults(spec)
    L = spec.landscapes
    for cname in spec.classes:
        for kind in ("mean", "best", "control"):
            getattr(res, kind)[cname] = np.empty((len(spec.models), len(spec.rates), L, spec.runs, spec.generations))
        for li in range(L):
            with np.load(_part(out, cname, li)) as part:
                for kind in ("mean", "best", "control"):
                    getattr(res, kind)[cname][:, :, li] = part[kind]
                if li == 0:
                    res.changes[cname] = [int(t) for t in part["changes"]]
    return res


def run_grid(spec: GridSpec, *, out: Path | None = None, backend: Backend | None = None,
             on_progress: Callable[[int, int], None] | None = None) -> GridResults:
    """Run the grid's unfinished landscapes (in ``out``, a temporary folder if None) on ``backend`` (this
    machine, one at a time, if None); ``on_progress(done, total)`` counts batch-generations.  Raises
    :class:`~coevo.errors.ConfigError` naming the landscapes that failed."""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="coevo-evolvability-") as tmp:
        where = Path(out) if out is not None else Path(tmp)
        prog = run_replicates(replicates(spec), where, backend or LocalBackend(1),
                              on_progress=None if on_progress is None else lambda p: on_progress(p.done, p.total),
                              poll=0.05)
        if prog.failed:
            raise ConfigError("landscapes failed: " + "; ".join(f"{k}: {v}" for k, v in prog.failed.items())
                              + (f" (logs in {where / 'logs'}; --resume runs them again)" if out is not None else ""))
        res = collect(spec, where)
    res.seconds = time.perf_counter() - t0
    return res
