"""Helpers shared by the learner tests."""

from himit_torch import Learner, learner_options


def build_learner(world, demos, agents, seeds=None, engine="numba", *, config):
    """A learner over ``world``'s learner options, one run per agent (seeds 0, 1, … unless
    given), watching ``demos`` (``None``: none)."""
    return Learner(
        world,
        learner_options(world),
        agents,
        list(range(len(agents))) if seeds is None else seeds,
        config=config,
        demonstrations=demos,
        engine=engine,
    )
