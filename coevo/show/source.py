"""Which robot to show: a rule file, a run directory, or a behaviour's default rules.

A :class:`Robot` is the three controllers plus the world they were learned in.  A
Tracking or Docking rule set alone drives the trivial Executive that always picks
it; an Executive needs its partners, and every way of naming them is checked here
so that the error names the missing file.

    FILE.rules                      its behaviour from the '# behaviour:' header
    runs/ID/  (coevo run)           workers/{executive,tracking,docking}/best.rules, world from run.json
    runs/learn-.../ (coevo learn)   best.rules, world from config.json; an Executive's partners from the
                                    tracking.rules / docking.rules learn wrote beside it
    --default tracking|docking      the shipped default rule set
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from coevo.errors import ConfigError, RunDirError
from coevo.policy.rules import RuleSet
from coevo.policy.text import read_rule_file
from coevo.rundir.layout import LearnPaths, RunPaths
from coevo.tasks.fuel import HAS_DEFAULT, default_ruleset
from coevo.tasks.fuel.behaviours import Behaviour
from coevo.tasks.fuel.settings import WorldConfig

__all__ = ["Robot", "robot_from_path", "robot_from_default", "robot_from_rules"]

ROLES = (Behaviour.EXECUTIVE, Behaviour.TRACKING, Behaviour.DOCKING)


@dataclass(frozen=True)
class Robot:
    """A robot to play: an Executive (None: the trivial one) and the policies it can pick."""

    name: str
    world: WorldConfig
    executive: RuleSet | None
    tracking: RuleSet | None
    docking: RuleSet | None

    @property
    def combined(self) -> bool:
        """True when an Executive chooses between Tracking and Docking."""
        return self.executive is not None

    def rulesets(self) -> dict[Behaviour, RuleSet]:
        pairs = ((Behaviour.EXECUTIVE, self.executive), (Behaviour.TRACKING, self.tracking), (Behaviour.DOCKING, self.docking))
        return {b: rs for b, rs in pairs if rs is not None}


def robot_from_rules(name: str, world: WorldConfig, rules: dict[Behaviour, RuleSet]) -> Robot:
    """A robot from whichever rule sets are given; an Executive needs both partners."""
    ex, tr, do = (rules.get(b) for b in ROLES)
    if ex is not None and (tr is None or do is None):
        missing = " and ".join(b.value for b, rs in ((Behaviour.TRACKING, tr), (Behaviour.DOCKING, do)) if rs is None)
        raise ConfigError(f"{name}: an Executive needs its partners; missing {missing} "
                          "(give --tracking FILE --docking FILE)")
    if ex is None and tr is not None and do is not None:
        raise ConfigError(f"{name}: Tracking and Docking without an Executive: show them one at a time, or add an Executive")
    if ex is None and tr is None and do is None:
        raise ConfigError(f"{name}: no policies to show")
    return Robot(name=name, world=world, executive=ex, tracking=tr, docking=do)


def robot_from_default(behaviour: str, world: WorldConfig) -> Robot:
    try:
        b = Behaviour(behaviour)
    except ValueError:
        b = None
    if b not in HAS_DEFAULT:
        raise ConfigError(f"--default {behaviour!r}: only {' and '.join(x.value for x in HAS_DEFAULT)} have default rules")
    rs = default_ruleset(b)
    if rs is None:  # HAS_DEFAULT and the shipped files disagree: a packaging bug, said plainly
        raise ConfigError(f"--default {behaviour!r}: its default rule set is missing from this installation")
    return robot_from_rules(f"default-{b.value}", world, {b: rs})


def robot_from_path(path: Path, *, world: WorldConfig | None = None,
                    partners: dict[Behaviour, RuleSet] | None = None) -> Robot:
    """The robot held by a rule file or a run directory; ``partners`` overrides or completes it.

    ``world`` (settings from the command line) applies to rule files; run directories
    bring their own.
    """
    path = Path(path)
    partners = dict(partners or {})
    if not path.exists():
        raise ConfigError(f"no such file or directory: {str(path)!r}")
    if path.is_dir():
        if RunPaths(path).run_json.exists():
            return _from_run(path, partners)
        if LearnPaths(path).best_rules.exists() or LearnPaths(path).config.exists():
            return _from_learn(path, partners)
        raise RunDirError(f"{str(path)!r} holds no policies: neither a coevo run (run.json, workers/*/best.rules) "
                          "nor a coevo learn directory (best.rules)")
    rs = read_rule_file(path)
    return robot_from_rules(path.stem, world or WorldConfig(), {**partners, rs.behaviour: rs})


def _world_of(f: Path, section: str = "world") -> WorldConfig:
    try:
        meta = json.loads(f.read_text(encoding="utf-8"))
        return WorldConfig(**meta[section])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RunDirError(f"{str(f)!r} cannot be read: {type(exc).__name__}: {exc}") from None


def _from_run(d: Path, partners: dict[Behaviour, RuleSet]) -> Robot:
    """A co-evolution run: its three workers' final best rule sets."""
    world = _world_of(RunPaths(d).run_json)
    rules: dict[Behaviour, RuleSet] = {}
    missing = []
    for b in ROLES:
        f = RunPaths(d).worker(b).best_rules
        if b in partners:
            rules[b] = partners[b]
        elif f.exists():
            rules[b] = read_rule_file(f, b)
        else:
            missing.append(str(f))
    if missing:
        raise RunDirError(f"run directory {str(d)!r} holds no policies for its combined robot: missing {', '.join(missing)} "
                          "(is the run finished?)")
    return robot_from_rules(d.name, world, rules)


def _from_learn(d: Path, partners: dict[Behaviour, RuleSet]) -> Robot:
    """A ``coevo learn`` directory: its best rule set, with the trivial Executive or its recorded partners."""
    best = LearnPaths(d).best_rules
    if not best.exists():
        raise RunDirError(f"learn directory {str(d)!r} holds no best.rules (was the run interrupted?)")
    config = LearnPaths(d).config
    world = _world_of(config) if config.exists() else WorldConfig()
    rs = read_rule_file(best)
    rules = {rs.behaviour: rs}
    if rs.behaviour == Behaviour.EXECUTIVE:
        for b in (Behaviour.TRACKING, Behaviour.DOCKING):
            f = LearnPaths(d).partner_rules(b)
            if b in partners:
                rules[b] = partners[b]
            elif f.exists():
                rules[b] = read_rule_file(f, b)
            else:
                raise RunDirError(f"executive learn directory {str(d)!r} does not hold its {b.value} partner ({f.name}; "
                                  f"learn runs before coevo show did not keep it): give --{b.value} FILE")
    return robot_from_rules(d.name, world, rules)
