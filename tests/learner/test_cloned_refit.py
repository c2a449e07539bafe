"""BCO's compiled refit (``himit_torch.learner.cloned_refit``, the CPU's way) against the torch
functions of ``himit_torch.mentor.cloning`` it stands for (``ClonedPolicy.actions_in_torch``,
the slow obvious computation): the same cloned actions exactly, after real runs, with several
mentors, and with counts chosen to make the sums' order and the ties matter."""

import pytest
import torch

from himit_torch import LearnerConfig, mentor_options, mentor_policy, record_demonstrations
from himit_torch.mentor.cloning import INVERSE_MODELS
from tests.learner.helpers import build_learner

pytest.importorskip("numba")

AGENTS = ["bco", "imitation", "bco", "bco", "primitives", "bco"]


def _compiled_and_reference(learner) -> tuple[torch.Tensor, torch.Tensor]:
    """The cloning runs' actions by ``refit`` (compiled on the CPU) and by the torch functions."""
    cloning, S = learner.cloning, learner.num_states
    runs = cloning.runs()
    cloning.action.fill_(-1)
    learner.refit_cloned_policy()
    compiled = cloning.action[runs, :S].clone()
    return compiled, cloning.actions_in_torch(runs, learner.model, learner.mentor)


def _learner(world, demos, kind, **config):
    config = LearnerConfig(window=500, bco_every=100, bco_inverse_model=kind, **config)
    return build_learner(world, demos, AGENTS, config=config)


@pytest.mark.parametrize("kind", INVERSE_MODELS)
def test_after_a_run(world12, mentor_demos12, kind):
    learner = _learner(world12, mentor_demos12, kind)
    learner.run(1500)
    compiled, reference = _compiled_and_reference(learner)
    assert torch.equal(compiled, reference)
    assert int((reference >= 0).sum()) > 10 and int((reference == -1).sum()) > 10
    assert bool((learner.cloning.action[[1, 4]] == -1).all())  # the runs that do not clone


@pytest.mark.parametrize("kind", INVERSE_MODELS)
@pytest.mark.parametrize("counts", ["ties", "fractions"])
def test_with_counts_whose_order_and_ties_matter(world12, mentor_demos12, kind, counts):
    """Own and mentor counts replaced: small whole numbers (and zeros, left out), which tie
    probabilities and votes often, or fractions, whose sums depend on their order."""
    learner = _learner(world12, mentor_demos12, kind)
    learner.run(1500)
    generator = torch.Generator().manual_seed(3)
    for store in (learner.model, learner.mentor):
        used = torch.arange(store.capacity) < store.num_edges[:, None]
        shape = store.edge_count.shape
        if counts == "ties":
            new = torch.randint(0, 3, shape, generator=generator).double()
            if store is learner.mentor:
                new += 1  # (a mentor edge is seen at least once)
        else:
            new = torch.rand(shape, generator=generator, dtype=torch.float64) * 3 + 1e-3
        store.edge_count[used] = new[used]
    compiled, reference = _compiled_and_reference(learner)
    assert torch.equal(compiled, reference)
    assert int((reference >= 0).sum()) > 10


def test_with_several_mentors(world12, mentor_demos12):
    """Two mentors' rows (``k·S + s``) are pooled by state, as the torch functions pool them."""
    noisy = record_demonstrations(
        world12, mentor_policy(world12, mentor_options(world12)), 5, seed=7, noise=0.5
    )
    learner = _learner(world12, [mentor_demos12, noisy], "likelihood", mentors=2)
    learner.run(1500)
    assert int(learner.mentor.edge_row[0, : int(learner.mentor.num_edges[0])].max()) >= 144
    compiled, reference = _compiled_and_reference(learner)
    assert torch.equal(compiled, reference)
    assert int((reference >= 0).sum()) > 10
