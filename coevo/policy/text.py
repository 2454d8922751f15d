"""Readable rule-set text: ``IF … THEN SET … (strength …)``, one rule a line, and back.

    # behaviour: tracking
    IF range = [35, 45] AND bearing = [340, 35] THEN SET turn = -24 AND speed = 4 (strength 0.8)
    IF ANY THEN SET turn = 0 AND speed = 0 (strength 0.5)

Conditions show bin labels (lower edges); a condition over a sensor's whole range
is left out, and a rule with none says ``IF ANY``.  Strengths print with Python's
shortest round-trip float repr, so ``parse(format(rs)) == rs`` exactly.
Blank lines and ``#`` comments are ignored, except the ``# behaviour:`` header.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from coevo.errors import ConfigError, RuleParseError, RuleSetError
from coevo.policy.rules import RuleSet
from coevo.policy.schema import Schema, known, registered, schema

__all__ = ["format_ruleset", "parse_ruleset", "format_rule", "read_rule_file"]

_RULE = re.compile(r"^IF\s+(?P<cond>.+?)\s+THEN\s+SET\s+(?P<act>.+?)\s*\(\s*strength\s+(?P<s>[^)]*)\)\s*$", re.IGNORECASE)
_COND = re.compile(r"^(?P<name>\w+)\s*=\s*\[\s*(?P<a>[-+0-9.eE]+)\s*,\s*(?P<b>[-+0-9.eE]+)\s*\]$")
_ACT = re.compile(r"^(?P<name>\w+)\s*=\s*(?P<v>\S+)$")
_HEADER = re.compile(r"^#\s*behaviour\s*:\s*(?P<b>\w+)\s*$", re.IGNORECASE)


def format_rule(rs: RuleSet, i: int) -> str:
    sch = rs.schema
    conds = []
    for j, s in enumerate(sch.sensors):
        lo, hi = int(rs.lo[i, j]), int(rs.hi[i, j])
        full = (lo == 0 and hi == s.bins - 1) or (s.circular and lo == hi + 1)
        if not full:
            conds.append(f"{s.name} = [{s.label(lo)}, {s.label(hi)}]")
    acts = [f"{a.name} = {a.values[int(rs.action[i, k])]}" for k, a in enumerate(sch.actions)]
    cond = " AND ".join(conds) if conds else "ANY"
    return f"IF {cond} THEN SET {' AND '.join(acts)} (strength {float(rs.strength[i])!r})"


def format_ruleset(rs: RuleSet) -> str:
    lines = [f"# behaviour: {rs.behaviour}"]
    lines += [format_rule(rs, i) for i in range(len(rs))]
    return "\n".join(lines) + "\n"


def _parse_rule(line: str, sch: Schema, lineno: int) -> tuple[list[int], list[int], list[int], float]:
    m = _RULE.match(line)
    if not m:
        raise RuleParseError(f"expected 'IF <conditions> THEN SET <actions> (strength <s>)', got {line!r}", line=lineno)
    lo = [0] * sch.n_sensors
    hi = [s.bins - 1 for s in sch.sensors]
    seen: set[str] = set()
    cond = m.group("cond").strip()
    if cond.upper() != "ANY":
        for part in re.split(r"\s+AND\s+", cond, flags=re.IGNORECASE):
            c = _COND.match(part.strip())
            if not c:
                raise RuleParseError(f"condition {part.strip()!r} is not 'sensor = [low, high]'", line=lineno)
            name = c.group("name")
            j = sch.sensor_index(name)
            if j is None:
                names = ", ".join(s.name for s in sch.sensors)
                raise RuleParseError(f"unknown {sch.behaviour} sensor {name!r} (sensors: {names})", line=lineno)
            if name in seen:
                raise RuleParseError(f"sensor {name!r} appears twice in one rule", line=lineno)
            seen.add(name)
            s = sch.sensors[j]
            for key in ("a", "b"):
                try:
                    value = float(c.group(key))
                except ValueError:
                    raise RuleParseError(f"{name} bound {c.group(key)!r} is not a number", line=lineno) from None
                k = s.bin_of_label(value)
                if k is None:
                    raise RuleParseError(
                        f"{name} bound {c.group(key)} is not a bin of {name} "
                        f"(0 to {s.label(s.bins - 1)} in steps of {s.label(1)} {s.unit})",
                        line=lineno,
                    )
                if key == "a":
                    lo[j] = k
                else:
                    hi[j] = k
    action = [-1] * len(sch.actions)
    for part in re.split(r"\s+AND\s+", m.group("act").strip(), flags=re.IGNORECASE):
        a = _ACT.match(part.strip())
        if not a:
            raise RuleParseError(f"action {part.strip()!r} is not 'name = value'", line=lineno)
        k = sch.action_index(a.group("name"))
        if k is None:
            names = ", ".join(x.name for x in sch.actions)
            raise RuleParseError(f"unknown {sch.behaviour} action {a.group('name')!r} (actions: {names})", line=lineno)
        idx = sch.actions[k].index_of(a.group("v"))
        if idx is None:
            allowed = ", ".join(str(v) for v in sch.actions[k].values)
            raise RuleParseError(f"{a.group('name')} = {a.group('v')} is not one of {allowed}", line=lineno)
        action[k] = idx
    missing = [sch.actions[k].name for k, v in enumerate(action) if v < 0]
    if missing:
        raise RuleParseError(f"rule sets no {', '.join(missing)}", line=lineno)
    try:
        strength = float(m.group("s"))
    except ValueError:
        raise RuleParseError(f"strength {m.group('s').strip()!r} is not a number", line=lineno) from None
    if not (0.0 <= strength <= 1.0):
        raise RuleParseError(f"strength {m.group('s').strip()} is not in [0, 1]", line=lineno)
    return lo, hi, action, strength


def parse_ruleset(text: str, behaviour: str | None = None) -> RuleSet:
    """Parse rule-set text; the behaviour comes from the argument or the ``# behaviour:`` header."""
    declared: str | None = None
    rules: list[tuple[int, str]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            h = _HEADER.match(line)
            if h:
                declared = h.group("b").lower()
                if not known(declared):
                    raise RuleParseError(f"unknown behaviour {h.group('b')!r} in header", line=lineno)
            continue
        rules.append((lineno, line))
    if behaviour is not None:
        wanted = str(behaviour)
        if not known(wanted):
            raise RuleParseError(f"unknown behaviour {behaviour!r}")
        if declared is not None and declared != wanted:
            raise RuleParseError(f"rule set is for {declared}, expected {wanted}")
        declared = wanted
    if declared is None:
        raise RuleParseError(f"no behaviour: add a '# behaviour: {'|'.join(registered())}' header")
    if not rules:
        raise RuleParseError("rule set has no rules")
    sch = schema(declared)
    parsed = [_parse_rule(line, sch, lineno) for lineno, line in rules]
    try:
        return RuleSet(
            declared,
            np.array([p[0] for p in parsed]),
            np.array([p[1] for p in parsed]),
            np.array([p[2] for p in parsed]),
            np.array([p[3] for p in parsed]),
        )
    except RuleSetError as exc:
        # Map "rule i" back to its line for the user.
        m = re.match(r"rule (\d+): (.*)", str(exc))
        if m:
            raise RuleParseError(m.group(2), line=rules[int(m.group(1))][0]) from exc
        raise RuleParseError(str(exc)) from exc


def read_rule_file(path: Path, behaviour: str | None = None) -> RuleSet:
    """A rule file parsed, its errors naming the file."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{str(path)!r} is a directory, expected a rule file")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"no such file: {str(path)!r}") from None
    except UnicodeDecodeError:
        raise RuleSetError(f"{path}: not a coevo rule file (not UTF-8 text)") from None
    except OSError as exc:
        raise ConfigError(f"cannot read rule file {str(path)!r}: {exc.strerror or exc}") from None
    try:
        return parse_ruleset(text, behaviour)
    except RuleSetError as exc:
        raise RuleSetError(f"{path}: not a coevo rule file: {exc}") from None
