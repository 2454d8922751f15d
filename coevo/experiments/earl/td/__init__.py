"""A TD baseline on our own tasks (docs/ea-vs-td.md): Q-learning on Tracking, Docking and the door task.

By role: :mod:`.spec` (a comparison's settings and curves), :mod:`.encoders` (what the learner observes),
:mod:`.qtable` (the hashed table), :mod:`.envs` (the tasks as batched environments), :mod:`.measures` (a
policy on fresh trials), :mod:`.runs` (the TD and GA runs and one task's comparison); :mod:`.replicates`,
:mod:`.report` and :mod:`.command` make it ``coevo td-baseline``.

The learner sees what the GA's rules see: the task's discretised sensors (its rule schema's bins) and
its joint actions (turn x speed: 13 x 6 = 78 on the fuel task, 7 x 8 = 56 on the door). It is paid what
the GA is paid: the task's own payoff, given at the episode's end (``sparse``); Tracking also has a
``shaped`` variant, +1/T for every step in range, with the episode's return kept equal to its payoff
(a collision takes back what the episode had earned, as the payoff's 0 on collision does).

**Why the table stays tractable** *(ours)*. A dense table over the schemas' bins would have
4.0e7 (Tracking), 6.4e12 (Docking) and 1.1e9 (door) observations, times 56-78 actions. Two things
keep it small:

* the table is *hashed*: a row exists only for an observation some robot has met (a dict from the
  observation's code to a row, rows allocated on first visit), so its size is bounded by the
  experience, not the product of the bins; and
* the observation is an :class:`Encoder`: the sensors that matter for the behaviour, each the
  schema's bins merged ``k`` at a time (e.g. Tracking's Target bearing in 30 degree sectors, the
  schema's 5 degree bins six at a time). The ``full`` encoders keep every sensor at the schema's
  bins; they are there to measure how the table grows without the reduction.

**Many worlds, one table.** Each independent run (a seed) is one table fed by ``lanes`` worlds at
once (Gymnasium's vector environment); several runs share one batched world. :mod:`.qlearning`'s
learner keeps a dense table per lane over synchronised episodes, which fits neither. When several
lanes update the same (observation, action) in one step, the update is the one that ``k``
sequential updates toward the targets' mean would make: ``Q += (1 - (1 - alpha)**k) * (mean - Q)``
(exact when the targets are equal; with ``alpha = 1/n`` it is the running mean, exactly).

**Experience** is counted in robot-steps, one per robot per decision, on both sides: the TD learner's
lanes as they step, the GA's evaluations from what they played (the fuel task's ``Outcome.steps``,
the door's decision log), its best's re-evaluation included (:class:`CountingEvaluator`).
Measurements on fresh trials are not experience for either.
"""
