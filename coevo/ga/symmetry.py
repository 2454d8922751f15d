"""Symmetric rules *(ours)*: in a world that is its own mirror image, each rule also stands for its mirror image.

A rule learned on one side of the world is then right on the other side as well, so the GA learns each
situation once instead of twice (docs/docking-learning.md, Round 6: Docking's approach to the dock from
the left and from the right).  The GA's individuals stay the rules it breeds (its genotypes); what is
played is each one followed by its mirror images (:func:`with_mirror_images`, the policy as played).

- :class:`MirroredEvaluator` plays the policies as played and folds what the mirror images did back
  onto the rules they are images of (:func:`fold`), so strengths, crossover's clusters and every
  Lamarckian operator see one rule, in its own frame, wherever it fired.
- The policy as played is what the GA publishes and writes (``GA.played``): a plain rule set, read
  by everyone else as any other, with nothing to know about symmetry.

A rule set and its mirror images share the matcher's 64 rules, so a symmetric GA breeds at most 32.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from coevo.errors import RuleSetError
from coevo.ga.evaluator import ChildRng, Evaluation, Evaluator, Partners, Tick
from coevo.ga.operators import Experience
from coevo.policy.rules import MAX_RULES, RuleSet, mirror_image
from coevo.policy.schema import Schema

__all__ = ["MAX_SYMMETRIC_RULES", "with_mirror_images", "fold", "MirroredEvaluator"]

#: The most rules a symmetric policy may breed: they and their mirror images fill the matcher's 64.
MAX_SYMMETRIC_RULES = MAX_RULES // 2


def with_mirror_images(rs: RuleSet) -> RuleSet:
    """The policy as played: ``rs``'s rules followed by their mirror images, rule ``i``'s image at ``len(rs) + i``.

    Nothing is merged: a rule that is its own mirror image appears twice, harmlessly (the same conditions
    and action), so the policy as played is exactly the one evaluated."""
    if len(rs) > MAX_SYMMETRIC_RULES:
        raise RuleSetError(f"a symmetric rule set holds at most {MAX_SYMMETRIC_RULES} rules (its mirror images "
                           f"fill the rest of the {MAX_RULES}); this one has {len(rs)}")
    return RuleSet.concat(rs.behaviour, [rs, mirror_image(rs)])


def fold(exp: Experience, n_rules: int, sch: Schema) -> Experience:
    """``exp`` of a policy as played (:func:`with_mirror_images`) as the experience of its ``n_rules`` rules:
    an image's firings count as its rule's, and the decisions an image took are seen in the rule's own frame
    (each :attr:`~coevo.policy.schema.Sensor.mirrored` sensor's bin ``k`` read as ``bins - 1 - k``, as
    :func:`~coevo.policy.rules.mirror_image` reflects a condition)."""
    n, own = np.uint64(n_rules), np.uint64((1 << n_rules) - 1)
    fired = (exp.fired & own) | ((exp.fired >> n) & own)
    by_image = exp.rule >= n_rules
    seen = exp.bins.copy()
    for j, s in enumerate(sch.sensors):
        if s.mirrored:
            seen[by_image, j] = s.bins - 1 - exp.bins[by_image, j]
    return dataclasses.replace(exp, fired=fired, rule=np.where(by_image, exp.rule - n_rules, exp.rule), bins=seen)


class MirroredEvaluator(Evaluator):
    """An evaluator that plays each policy with its mirror images and reports on the policy itself."""

    def __init__(self, inner: Evaluator) -> None:
        self.inner = inner
        self.behaviour = inner.behaviour

    def evaluate(self, policies: list[RuleSet], partners: Partners, rng: np.random.Generator, *,
                 episodes: int | None = None, tick: Tick | None = None) -> Evaluation:
        ev = self.inner.evaluate([with_mirror_images(p) for p in policies], partners, rng, episodes=episodes, tick=tick)
        return dataclasses.replace(ev, experience=[fold(e, len(p), p.schema) for e, p in zip(ev.experience, policies)])

    def measures(self, best: RuleSet, partners: Partners, check: Evaluation, child_rng: ChildRng) -> dict[str, float | None]:
        return self.inner.measures(with_mirror_images(best), partners, check, child_rng)
