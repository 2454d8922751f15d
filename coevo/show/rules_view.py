"""Print a task's rule tables (:class:`~coevo.tasks.showing.RuleTable`): rich tables on a terminal,
plain text otherwise, one rule a line."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from coevo.tasks.showing import RuleTable

__all__ = ["print_tables"]


def print_tables(tables: Sequence[RuleTable], *, console: Any | None = None, plain: bool | None = None) -> None:
    """Print each rule table: rule number, strength, fire count, rule (unfired rules dim)."""
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    plain = (not console.is_terminal) if plain is None else plain
    for tab in tables:
        if plain:
            console.print(tab.title, markup=False, highlight=False, soft_wrap=True)
            for r in tab.rows:
                console.print(f"  {tab.letter}{r.number:<3} {r.strength:6.3f} {r.fired:5d}  {r.text}",
                              markup=False, highlight=False, soft_wrap=True)
            continue
        t = Table(title=tab.title, title_justify="left")
        t.add_column("#", justify="right")
        t.add_column("strength", justify="right")
        t.add_column("fired", justify="right")
        t.add_column("rule")
        for r in tab.rows:
            t.add_row(f"{tab.letter}{r.number}", f"{r.strength:.3f}", str(r.fired), r.text, style=None if r.fired else "dim")
        console.print(t)
