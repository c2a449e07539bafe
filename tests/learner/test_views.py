"""The read-only views are one object, ``learner.views``; the old names on the learner itself
are deprecated aliases for one version: they warn and return what the views return."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from himit_torch import Learner, LearnerViews, learner_options
from himit_torch.learner.learner import DEPRECATED_VIEW_NAMES
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import mentor_options

#: The arguments of the views that need some.
ARGS = {"greedy_trajectory": (0, 40)}


def _same(old, new) -> None:
    if isinstance(new, torch.Tensor):
        torch.testing.assert_close(old, new, rtol=0, atol=0, equal_nan=True)
    elif dataclasses.is_dataclass(new):
        for f in dataclasses.fields(new):
            _same(getattr(old, f.name), getattr(new, f.name))
    else:
        assert old == new


@pytest.fixture(scope="module")
def learner(world8):
    demos = record_demonstrations(world8, mentor_policy(world8, mentor_options(world8)), 3, seed=0)
    learner = Learner(
        world8,
        learner_options(world8),
        ["imitation", "options", "imitation_psrl"],
        [0, 1, 2],
        demonstrations=demos,
    )
    learner.run(600)
    return learner


def test_every_view_has_its_old_name_for_one_version():
    views = {n for n in dir(LearnerViews) if not n.startswith("_")}
    assert set(DEPRECATED_VIEW_NAMES) == views


@pytest.mark.parametrize("name", DEPRECATED_VIEW_NAMES)
def test_an_old_name_warns_and_returns_the_view(learner, name):
    with pytest.warns(DeprecationWarning, match=rf"Learner\.{name} is deprecated.*views\.{name}"):
        old = getattr(learner, name)
    new = getattr(learner.views, name)
    if callable(new):
        old, new = old(*ARGS.get(name, ())), new(*ARGS.get(name, ()))
    _same(old, new)
    assert learner.views.t == 600 and int(learner.views.goals.sum()) > 0  # (a run that learned)
