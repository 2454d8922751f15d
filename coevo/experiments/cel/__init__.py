"""``coevo cel-experiment``: Appendix B's Figure 3 over live CEL runs, with a report."""
