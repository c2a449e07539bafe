"""himit_torch: hierarchical goal-based imitation from state-only demonstrations, in PyTorch."""
from .world import MultiRooms, TabularWorld
from .options import (Options, primitive_options, doorway_options, corner_options,
                      learner_options, mentor_options)
from .option_models import OptionModels, option_models, option_durations
from .planning import value_iteration, smdp_value_iteration, expected_steps, PlanResult
