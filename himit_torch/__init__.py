"""himit_torch: hierarchical goal-based imitation learning from state-only demonstrations.

A learner with its own options watches only a mentor's *states* and learns with the augmented
Bellman equation with options (Friesen & Rao, "Imitation learning with hierarchical actions").
``B`` independent runs advance together as tensors; see ``README.md`` for a tour.
"""

from . import backups
from .demonstrations import DEMONSTRATIONS_FORMAT_VERSION, Demonstrations
from .dirichlet_models import (
    DirichletMentorModel,
    DirichletSMDPModel,
    EdgeStore,
    SuccessorDirichlet,
)
from .discovery import Subgoals, discover_subgoals, learned_subgoal_options, one_step_counts
from .exact_option_models import OptionModels, option_durations, option_models
from .exact_planning import (
    OptimalBaseline,
    PlanResult,
    expected_steps,
    greedy_option_policy,
    optimal_baseline,
    smdp_value_iteration,
    value_iteration,
)
from .gym_adapter import from_gymnasium, taxi_navigation_options
from .gym_env import ENV_ID, MultiRoomsEnv, register_envs
from .learner import AGENTS, Learner, LearnerConfig
from .mentor import (
    ExactMentorTransitions,
    MentorPolicy,
    MentorRollout,
    exact_mentor_transitions,
    mentor_policy,
    record_demonstrations,
    run_mentor,
)
from .option_refresh import with_options
from .options import (
    OPTION_KINDS,
    Options,
    corner_options,
    doorway_options,
    learner_options,
    mentor_options,
    primitive_options,
    subgoal_options,
)
from .reward import (
    MENTOR_REWARDS,
    SALIENCE_EVENTS,
    KnownReward,
    MentorReward,
    SalienceReward,
    ZeroReward,
    mentor_reward_module,
)
from .sweep_queue import BlockPriorityQueue
from .table_world import TableWorld, describe_world, transition_support, world_model
from .tensorboard_logger import TensorBoardLogger
from .world import STIMULUS_FEATURES, DynamicsTable, MultiRooms, TabularWorld

__version__ = "0.1.0"

__all__ = [
    # worlds
    "MultiRooms",
    "TabularWorld",
    "DynamicsTable",
    "MultiRoomsEnv",
    "register_envs",
    "ENV_ID",
    "TableWorld",
    "from_gymnasium",
    "world_model",
    "transition_support",
    "describe_world",
    # options and their exact models
    "Options",
    "OPTION_KINDS",
    "primitive_options",
    "doorway_options",
    "corner_options",
    "learner_options",
    "mentor_options",
    "subgoal_options",
    "taxi_navigation_options",
    "OptionModels",
    "option_models",
    "option_durations",
    # exact planning
    "value_iteration",
    "smdp_value_iteration",
    "greedy_option_policy",
    "expected_steps",
    "PlanResult",
    "OptimalBaseline",
    "optimal_baseline",
    # the learner
    "Learner",
    "LearnerConfig",
    "AGENTS",
    "DirichletSMDPModel",
    "DirichletMentorModel",
    "SuccessorDirichlet",
    "EdgeStore",
    "BlockPriorityQueue",
    "backups",
    # mentor and demonstrations
    "MentorPolicy",
    "MentorRollout",
    "mentor_policy",
    "run_mentor",
    "record_demonstrations",
    "ExactMentorTransitions",
    "exact_mentor_transitions",
    "Demonstrations",
    "DEMONSTRATIONS_FORMAT_VERSION",
    # mentor reward
    "MentorReward",
    "KnownReward",
    "SalienceReward",
    "ZeroReward",
    "SALIENCE_EVENTS",
    "STIMULUS_FEATURES",
    "MENTOR_REWARDS",
    "mentor_reward_module",
    # options discovered from demonstrations
    "Subgoals",
    "discover_subgoals",
    "learned_subgoal_options",
    "one_step_counts",
    "with_options",
    # logging
    "TensorBoardLogger",
]
