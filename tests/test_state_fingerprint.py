"""The before/after check of docs/extending.md (``benchmarks/state_fingerprint.py``): it hashes
what the learner learned, not the record of its configuration, so a new setting at its default
leaves the lines as they were, and a change of what is learned does not."""

from __future__ import annotations

import dataclasses

from benchmarks.state_fingerprint import fingerprint
from himit_torch import Learner, LearnerConfig, learner_options
from himit_torch.validation import setting


@dataclasses.dataclass
class ToyConfig(LearnerConfig):
    """``LearnerConfig`` with one more setting, declared the recipe's way (off by default)."""

    mentor_toy: float | None = setting(
        None, gt=0.0, mentor_term=True, doc="A toy weight of the mentor term (None: off)."
    )


def _fingerprint(world, config, steps=300) -> str:
    learner = Learner(world, learner_options(world), ["options", "primitives"], [0, 1], config)
    learner.run(steps)
    return fingerprint(learner)


def test_a_new_setting_at_its_default_keeps_the_fingerprint(world8):
    before = _fingerprint(world8, LearnerConfig(window=100))
    assert _fingerprint(world8, ToyConfig(window=100)) == before
    # what the learner learned is in it: other settings, or more steps, are other lines
    state, curves = before.split()
    other = _fingerprint(world8, LearnerConfig(window=100, eps_start=0.5)).split()
    assert other[0] != state and other[1] != curves
    assert _fingerprint(world8, LearnerConfig(window=100), steps=400).split()[0] != state
