"""The exact option models are remembered per (world, options) while both live: a second call
returns what the first computed, without computing again, and nothing stale is ever returned."""

import pytest
import torch

import himit_torch.exact.option_models as om
from himit_torch import MultiRooms, learner_options
from himit_torch.exact import reference_cache
from himit_torch.exact.option_models import (
    option_durations,
    option_models,
    option_models_and_durations,
)
from tests.exact.helpers import counting_option_models


@pytest.fixture(autouse=True)
def _nothing_shared_by_content():
    """These tests count computations: no models of the same content from earlier tests."""
    reference_cache._BY_CONTENT.clear()
    yield
    reference_cache._BY_CONTENT.clear()


def _same(a, b) -> None:
    assert torch.equal(a.row_state, b.row_state) and torch.equal(a.reward, b.reward)
    assert torch.equal(a.transition.to_dense(), b.transition.to_dense())


def test_a_second_call_reuses_the_models_and_they_equal_a_fresh_computation(monkeypatch):
    world = MultiRooms(12, 2)
    options = learner_options(world)
    fresh = om._option_models(world, options, [(None, None), (1.0, torch.ones(144, 4))])
    calls = counting_option_models(monkeypatch)
    first = option_models(world, options)
    both = option_models_and_durations(world, options)
    durations = option_durations(world, options)
    assert calls == [1, 1]  # the discounted models once, the durations once
    assert both[0] is first and durations is both[1]
    _same(first, fresh[0])
    _same(durations, fresh[1])


def test_other_options_worlds_rewards_and_options_written_in_place_are_computed_anew(
    monkeypatch,
):
    """Other rewards, discounts and options written in place are computed anew; an equal
    bundle or world of another object shares the models by content (exact.reference_cache)."""
    world = MultiRooms(12, 2)
    options = learner_options(world)
    calls = counting_option_models(monkeypatch)
    first = option_models(world, options)
    assert option_models(world, learner_options(world)) is first  # an equal bundle: by content
    assert option_models(MultiRooms(12, 2), options) is first  # an equal world: by content
    option_models(world, options, step_reward=torch.full((144, 4), 2.0))  # not remembered
    option_models(world, options, step_reward=torch.full((144, 4), 2.0))
    option_models(world, options, gamma=0.5)  # another discount
    option_models(MultiRooms(12, 2, slip=0.2), options)  # another world's dynamics
    assert calls == [1] * 5
    options.termination[-1, :] = 1.0  # written in place (a doorway option): its models changed
    again = option_models(world, options)
    assert len(calls) == 6 and again is not first
    assert option_models(world, options) is again and len(calls) == 6
