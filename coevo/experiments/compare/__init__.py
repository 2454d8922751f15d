"""Regime comparisons: many real runs per regime, the report's Table 1, curves and a verdict.

``experiment`` plans, runs and resumes the replicates; ``table1`` classes a run
as the report's Table 1 does; ``stats`` compares two regimes; ``plots`` draws
the learning curves; ``report`` writes it all down.  Nothing is imported here, so that
``coevo compare --help`` loads no statistics or plotting library.
"""
