"""See what was learned: recorded episodes of a robot as pictures, animations and rule tables.

``coevo show`` (:mod:`coevo.show.command`) resolves what to show (:mod:`.source`): the task of a run
directory, rule file or default rule set, and the robot that task makes of it.  The task plays it,
turns the recording into a task-agnostic :class:`~coevo.scene.Scene` and lists its rules (the show
hooks of :class:`~coevo.tasks.base.Task`); :mod:`coevo.scene` renders the scene and :mod:`.rules_view`
prints the rules.  Nothing here names a task: each task owns its pictures.
"""
