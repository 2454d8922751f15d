"""The door task's command-line spellings, light enough for a parser (the task itself is imported when used)."""

from __future__ import annotations

import argparse

__all__ = ["SONARS_HELP", "sonars_arg"]

#: How every ``--fail`` spells a sonar, for its help: the names as printed, and the report's hyphens taken too.
SONARS_HELP = "e.g. front,front_right,right (front-right, as the report writes it, is the same)"


def sonars_arg(text: str) -> str:
    """A ``--fail`` list of door sonars in any spelling (``front-right`` or ``front_right``) -> the names as every
    command prints them, comma-separated in left-to-right order; an unknown name is a one-line usage error."""
    from coevo.tasks.door.settings import sonar_names

    try:
        names = sonar_names(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return ",".join(names) if names else text  # none named: as given, for the command's own word on it
