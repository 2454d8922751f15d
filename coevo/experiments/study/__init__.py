"""Studies: factors × seeds, each cell a regime comparison or a set of learning runs (``learn``), run through the
replicate runner, with one report.

``declaration`` reads a study (a TOML file and ``--factor`` flags) into a :class:`~.declaration.StudySpec`,
checks every cell's settings with the validators the flags use, and derives each cell's seeds; ``experiment``
lays out the study's folder, runs its cells' replicates (:mod:`coevo.replicates`), resumes it, marks it complete
and tells its progress as plain data; ``intervals`` holds the proportions' intervals and the multiple-comparison
correction; ``report`` (``learn_report`` for learning runs) and ``plots`` write it down.  Nothing is imported here,
so that ``coevo study --help`` loads no statistics or plotting library.  See docs/studies.md.
"""
