"""The compiled engine's settings are generated from the config schema, with fixed types."""

import pytest

from himit_torch import Learner, LearnerConfig, MultiRooms, learner_options
from himit_torch.learner.config import KERNEL_FIELDS
from himit_torch.learner.engines.settings import DERIVED, KernelSettings, kernel_settings


def test_the_kernel_reads_every_kernel_field_of_the_schema_and_the_derived_values():
    assert KernelSettings._fields == KERNEL_FIELDS + tuple(DERIVED)
    assert {"mentor_fade", "tie_break", "eps_schedule", "backups"} <= set(KERNEL_FIELDS)


@pytest.mark.parametrize(
    "config",
    [
        LearnerConfig(),
        LearnerConfig(
            mentor_fade=20,
            tie_break="first",
            eps_schedule="paper",
            mentor_override_after=3,
            untried_value=0,
            mentor_choice="match",
            concentration=1,
        ),
    ],
)
def test_settings_have_one_type_per_field_whatever_the_config(config):
    """Numba specialises on types: a setting given as an int, a None or a choice must still give
    the field's one type, or the kernels would compile again for each configuration."""
    world = MultiRooms(8, 2)
    learner = Learner(world, learner_options(world), ["imitation"], [0], config, engine="torch")
    settings = kernel_settings(learner.state)
    baseline = kernel_settings(
        Learner(world, learner_options(world), ["imitation"], [0], engine="torch").state
    )
    assert [type(v) for v in settings] == [type(v) for v in baseline]
    assert settings.tie_break == (1 if config.tie_break == "first" else 0)
    assert settings.mentor_fade == (config.mentor_fade or 0.0)
    assert settings.mentor_override_after == (
        -1 if config.mentor_override_after is None else config.mentor_override_after
    )
    assert settings.gamma == world.gamma and settings.start_state == world.start_state
