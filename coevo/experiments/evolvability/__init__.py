"""Evolvability in dynamic landscapes (report Appendix D): landscapes, a bit-string GA, the experiment."""

from __future__ import annotations
