"""Plugins found by name: tasks and kinds of learner, coevo's own included, loaded when first named.

A package declares its plugins as Python entry points, coevo's own in its pyproject.toml exactly as an outside
package declares its own (Gymnasium finds third-party environments the same way, pytest its plugins)::

    [project.entry-points."coevo.tasks"]
    pendulum = "coevo_pendulum:PendulumTask"

An entry point names a class (made with no arguments) or an object.  Reading the installed packages' entry points
imports nothing: a plugin's module is imported the first time its name is asked for (:meth:`Plugins.get`), so a
process imports only the task it runs.  A script, notebook or test adds one without installing anything with
:meth:`Plugins.register` (an object, or a ``"module:attr"`` string imported when first named).

What can go wrong says which package, and breaks nothing else: a plugin that fails to import or is not what its
group holds is a :class:`PluginError` naming its package and the reason, raised where that name is asked for and
listed by ``coevo plugins``; two packages claiming one name are one line naming both, for that name only.
"""

from __future__ import annotations

import importlib
import logging
import os
import re
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

from coevo.errors import ConfigError

__all__ = ["Plugins", "PluginError", "Entry", "TASKS_GROUP", "KINDS_GROUP"]

log = logging.getLogger(__name__)

TASKS_GROUP = "coevo.tasks"
KINDS_GROUP = "coevo.kinds"
REGISTERED = "(registered)"  # the package of a plugin given by register() rather than installed

T = TypeVar("T")


class PluginError(ConfigError):
    """A plugin that cannot be used: it fails to import, is not what its group holds, or its name is claimed twice."""


@dataclass(frozen=True)
class Entry:
    """Where a plugin comes from: its name, its package (distribution and version) and what it names."""

    name: str
    package: str
    target: str  # "module:attr", or the repr of an object given to register()
    obj: object = None  # the object given to register(), if it was given as one


class Plugins(Generic[T]):
    """The plugins of one entry-point group: names without imports, objects on first use.

    ``what`` names one in messages ("task"); ``make(name, obj)`` turns what an entry point called ``name`` names
    into the plugin (a class made, an object checked) or raises TypeError saying what it is instead."""

    def __init__(self, group: str, what: str, make: Callable[[str, object], T]) -> None:
        self.group, self.what, self._make = group, what, make
        self._installed: dict[str, list[Entry]] | None = None
        self._registered: dict[str, Entry] = {}
        self._loaded: dict[str, T] = {}
        self._failed: dict[str, PluginError] = {}

    # -- names, without importing -------------------------------------------------------------------------------
    def _entries(self) -> dict[str, list[Entry]]:
        if self._installed is None:
            found: dict[str, list[Entry]] = {}
            for name, target, package in installed_entry_points(self.group):
                entry = Entry(name, package, target)
                if entry not in found.setdefault(name, []):
                    found[name].append(entry)
            self._installed = {name: sorted(claims, key=lambda e: e.package) for name, claims in found.items()}
        return self._installed

    def names(self) -> list[str]:
        """Every name installed or registered, in order of name."""
        return sorted(set(self._entries()) | set(self._registered))

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and (name in self._registered or name in self._entries())

    def entry(self, name: str) -> Entry:
        """Where ``name`` comes from (a registered one wins over an installed one); a PluginError if two installed
        packages claim it, a ConfigError if none does."""
        if name in self._registered:
            return self._registered[name]
        claims = self._entries().get(name)
        if not claims:
            known = ", ".join(self.names()) or "none installed: reinstall coevo (pip install -e .)"
            raise ConfigError(f"unknown {self.what} {name!r} (known: {known})")
        if len(claims) > 1:
            raise PluginError(f"{self.what} {name!r} is claimed by two packages: "
                              + " and ".join(f"{c.package} ({c.target})" for c in claims)
                              + "; uninstall one of them")
        return claims[0]

    # -- objects, imported on first use -------------------------------------------------------------------------
    def get(self, name: str) -> T:
        """The plugin called ``name``, imported and made the first time it is asked for."""
        if name in self._loaded:
            return self._loaded[name]
        if name in self._failed:
            raise self._failed[name]
        entry = self.entry(name)
        try:
            obj = entry.obj if entry.obj is not None else _load(entry.target)
            plugin = self._make(name, obj)
        except Exception as exc:  # a plugin's own bug or missing dependency: it is that package's, said in one line
            err = PluginError(f"{self.what} {name!r} from {entry.package} ({entry.target}) cannot be used: "
                              f"{type(exc).__name__}: {exc}")
            self._failed[name] = err
            raise err from None
        self._loaded[name] = plugin
        return plugin

    def loaded(self) -> dict[str, T]:
        """The plugins imported so far, by name (none is imported by asking)."""
        return dict(self._loaded)

    def usable(self) -> dict[str, T]:
        """Every plugin that loads, by name; one that does not is logged and left out (it breaks no other)."""
        out: dict[str, T] = {}
        for name in self.names():
            try:
                out[name] = self.get(name)
            except PluginError as exc:
                log.warning("%s", exc)
        return out

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def register(self, name: str, plugin: object, *, package: str = REGISTERED) -> None:
        """Add ``name`` in this process: ``plugin`` is what an entry point would name (a class, an object) or a
        ``"module:attr"`` string imported when first named.  Registering a name again replaces it."""
        if not isinstance(name, str) or not name:
            raise ConfigError(f"a {self.what}'s name must be a non-empty string, not {name!r}")
        if isinstance(plugin, str):
            if ":" not in plugin:
                raise ConfigError(f"{self.what} {name!r}: {plugin!r} is not 'module:attr'")
            entry = Entry(name, package, plugin)
        else:
            entry = Entry(name, package, repr(plugin), obj=plugin)
        self._registered[name] = entry
        self._loaded.pop(name, None)
        self._failed.pop(name, None)

    def unregister(self, name: str) -> None:
        """Forget a name given to :meth:`register` (an installed one stays)."""
        self._registered.pop(name, None)
        self._loaded.pop(name, None)
        self._failed.pop(name, None)

    def listing(self) -> list[tuple[str, str, str, str | None]]:
        """(name, package, target, problem or None) for every name, loading each to find its problems."""
        rows: list[tuple[str, str, str, str | None]] = []
        for name in self.names():
            try:
                entry = self.entry(name)
            except PluginError as exc:  # claimed twice
                rows.append((name, " and ".join(c.package for c in self._entries()[name]), "-", str(exc)))
                continue
            try:
                self.get(name)
                rows.append((name, entry.package, entry.target, None))
            except PluginError as exc:
                rows.append((name, entry.package, entry.target, str(exc)))
        return rows


def installed_entry_points(group: str) -> list[tuple[str, str, str]]:
    """(name, target, "package version") of every entry point of ``group`` the packages on ``sys.path`` declare,
    read from their metadata (``*.dist-info``, ``*.egg-info``) as importlib.metadata reads it, a package found
    twice counting once (the first on the path), but without importing importlib.metadata, which costs a start-up
    more than the reading itself (50-100 ms measured here, the reading 2-14 ms).  Read once per process."""
    global _SCANNED
    if _SCANNED is None:
        _SCANNED = _scan()
    return list(_SCANNED.get(group, []))


_SCANNED: dict[str, list[tuple[str, str, str]]] | None = None


def _scan() -> dict[str, list[tuple[str, str, str]]]:
    out: dict[str, list[tuple[str, str, str]]] = {}
    seen: set[str] = set()
    for base in sys.path:
        try:
            names = sorted(os.listdir(base or "."))
        except OSError:
            continue
        for info in names:
            if not info.endswith((".dist-info", ".egg-info")):
                continue
            key = re.sub(r"[-_.]+", "_", info.rsplit(".", 1)[0].split("-", 1)[0]).lower()
            if key in seen:
                continue
            seen.add(key)
            where = Path(base or ".") / info
            try:
                text = (where / "entry_points.txt").read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError):
                continue
            sections = _sections(text)
            if any(g.startswith("coevo.") for g in sections):  # only coevo's groups are ever asked for
                package = _package(where, info)
                for g, points in sections.items():
                    out.setdefault(g, []).extend((name, target, package) for name, target in points)
    return out


def _sections(text: str) -> dict[str, list[tuple[str, str]]]:
    """The ``name = target`` lines of each section of an entry_points.txt (an INI file)."""
    sections: dict[str, list[tuple[str, str]]] = {}
    current: list[tuple[str, str]] | None = None
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        if line.startswith("[") and line.endswith("]"):
            current = sections.setdefault(line[1:-1].strip(), [])
        elif current is not None and "=" in line:
            name, _, target = line.partition("=")
            current.append((name.strip(), target.split("[", 1)[0].strip()))
    return sections


def _package(where: Path, info: str) -> str:
    """"name version" of a distribution, from its metadata's Name and Version (else its directory's name)."""
    fields: dict[str, str] = {}
    for file in ("METADATA", "PKG-INFO"):
        try:
            with open(where / file, encoding="utf-8") as fh:
                for line in fh:
                    if not line.strip():
                        break  # the headers end at the first blank line
                    key, _, value = line.partition(":")
                    if key in ("Name", "Version"):
                        fields.setdefault(key, value.strip())
        except (OSError, UnicodeDecodeError):
            continue
        break
    name, _, version = info.rsplit(".", 1)[0].partition("-")
    return f"{fields.get('Name', name)} {fields.get('Version', version or '?')}"


def _load(target: str) -> object:
    """What ``"module:attr.attr"`` names."""
    module, _, attr = target.partition(":")
    obj: Any = importlib.import_module(module.strip())
    for part in attr.strip().split(".") if attr.strip() else []:
        obj = getattr(obj, part)
    return obj
