"""Appendix C (Moriarty, Schultz, Grefenstette): EA vs TD learning on the survey's grid and hidden-state worlds.

``gridworld`` and ``hidden`` are the two worlds, ``qlearning`` a reusable batched tabular Q-learner,
``earl1`` the survey's one-gene-per-state EA, ``report`` the files and figures, ``command`` the CLI verb.
"""

from __future__ import annotations
