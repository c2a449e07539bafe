"""himit_torch: hierarchical goal-based imitation learning from state-only demonstrations.

A learner with its own options watches only a mentor's *states* and learns with the augmented
Bellman equation with options (Friesen & Rao, "Imitation learning with hierarchical actions").
``B`` independent runs advance together as tensors; see ``README.md`` and the documentation
(``make docs``) for a tour.
"""

from himit_torch.exact.greedy_evaluation import (
    UNTRIED_RULES,
    OptionPolicy,
    PolicyEvaluation,
    PolicyEvaluator,
    evaluate_option_choice,
    optimal_policy_evaluation,
    optimal_value,
)
from himit_torch.exact.option_models import (
    OptionModels,
    option_durations,
    option_models,
    option_models_and_durations,
)
from himit_torch.exact.planning import (
    OptimalBaseline,
    PlanResult,
    expected_steps,
    greedy_option_policy,
    optimal_baseline,
    smdp_value_iteration,
    value_iteration,
)
from himit_torch.learner import backups
from himit_torch.learner.agents import AGENTS, AgentVariant
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.inspect import LearnerViews
from himit_torch.learner.learner import Learner
from himit_torch.learner.models import (
    DirichletMentorModel,
    DirichletSMDPModel,
    EdgeStore,
    SuccessorDirichlet,
)
from himit_torch.learner.option_refresh import with_options
from himit_torch.learner.presets import PRESETS, Preset, apply_preset, preset_differences
from himit_torch.learner.prioritized_sweeping import BlockPriorityQueue
from himit_torch.mentor.cloning import InverseModel, clone_policy, inverse_model, relabel
from himit_torch.mentor.demonstrations import DEMONSTRATIONS_FORMAT_VERSION, Demonstrations
from himit_torch.mentor.minari import demonstrations_from_minari, demonstrations_to_minari
from himit_torch.mentor.minigrid import demonstrations_in, minigrid_mentor
from himit_torch.mentor.observation import (
    CoarseDemonstrations,
    observe_at_option_ends,
    observe_every,
)
from himit_torch.mentor.policy import (
    ExactMentorTransitions,
    MentorDetour,
    MentorPolicy,
    MentorRollout,
    exact_mentor_transitions,
    mentor_detour,
    mentor_policy,
    record_demonstrations,
    run_mentor,
)
from himit_torch.mentor.potential import mentor_chain_value, shaping_potential
from himit_torch.mentor.puzzle_box import map_demonstrations, organisation_mentor
from himit_torch.mentor.reward import (
    MENTOR_REWARDS,
    SALIENCE_EVENTS,
    KnownReward,
    MentorReward,
    SalienceReward,
    ZeroReward,
    mentor_reward_module,
)
from himit_torch.options.builders import (
    corner_options,
    doorway_options,
    learner_options,
    mentor_options,
    primitive_options,
    subgoal_options,
)
from himit_torch.options.bundle import OPTION_KINDS, Options
from himit_torch.options.discovery import (
    Subgoals,
    discover_subgoals,
    learned_subgoal_options,
    one_step_counts,
)
from himit_torch.options.minigrid import minigrid_options, minigrid_subgoals
from himit_torch.options.puzzle_box import puzzle_box_options
from himit_torch.options.skewer_routines import (
    SkewerRoutine,
    discover_skewer_routines,
    skewer_routine_options,
)
from himit_torch.options.taxi import taxi_navigation_options
from himit_torch.viz.tensorboard import TensorBoardLogger
from himit_torch.worlds.gym_env import ENV_ID, MultiRoomsEnv, register_envs
from himit_torch.worlds.gymnasium import from_gymnasium
from himit_torch.worlds.minigrid import MINIGRID_TASKS, MiniGridWorld, from_minigrid
from himit_torch.worlds.multirooms import (
    STIMULUS_FEATURES,
    MultiRooms,
    detour_waypoint,
    maze_doorways,
    primitives_only_goal,
)
from himit_torch.worlds.puzzle_box import ORGANISATIONS, PuzzleBox
from himit_torch.worlds.table_world import (
    TableWorld,
    describe_world,
    transition_support,
    world_model,
)
from himit_torch.worlds.tabular import DynamicsTable, TabularWorld

#: The package version: the one source of it (pyproject.toml reads it; ``himit --version`` prints
#: it; CHANGELOG.md lists what changed in each).
__version__ = "0.1.0"

__all__ = [
    # worlds
    "MultiRooms",
    "maze_doorways",
    "primitives_only_goal",
    "TabularWorld",
    "DynamicsTable",
    "MultiRoomsEnv",
    "register_envs",
    "ENV_ID",
    "TableWorld",
    "PuzzleBox",
    "ORGANISATIONS",
    "from_gymnasium",
    "from_minigrid",
    "MiniGridWorld",
    "MINIGRID_TASKS",
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
    "puzzle_box_options",
    "minigrid_options",
    "minigrid_subgoals",
    "OptionModels",
    "option_models",
    "option_durations",
    "option_models_and_durations",
    # exact planning
    "value_iteration",
    "smdp_value_iteration",
    "greedy_option_policy",
    "expected_steps",
    "PlanResult",
    "OptimalBaseline",
    "optimal_baseline",
    # exact evaluation of frozen option policies (greedy policies, the mentor's)
    "OptionPolicy",
    "PolicyEvaluation",
    "PolicyEvaluator",
    "evaluate_option_choice",
    "optimal_policy_evaluation",
    "optimal_value",
    "UNTRIED_RULES",
    # the learner
    "Learner",
    "LearnerViews",
    "LearnerConfig",
    "AGENTS",
    "AgentVariant",
    "PRESETS",
    "Preset",
    "apply_preset",
    "preset_differences",
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
    "organisation_mentor",
    "map_demonstrations",
    "minigrid_mentor",
    "demonstrations_in",
    "demonstrations_from_minari",
    "demonstrations_to_minari",
    # the stresses on the demonstrations (docs/stresses.md)
    "MentorDetour",
    "mentor_detour",
    "detour_waypoint",
    "CoarseDemonstrations",
    "observe_every",
    "observe_at_option_ends",
    # mentor reward
    "MentorReward",
    "KnownReward",
    "SalienceReward",
    "ZeroReward",
    "SALIENCE_EVENTS",
    "STIMULUS_FEATURES",
    "MENTOR_REWARDS",
    "mentor_reward_module",
    # shaping potential from the demonstrations (the pbrs agents)
    "shaping_potential",
    "mentor_chain_value",
    # behavioural cloning from observation (the bco agent)
    "InverseModel",
    "inverse_model",
    "relabel",
    "clone_policy",
    # options discovered from demonstrations
    "Subgoals",
    "discover_subgoals",
    "learned_subgoal_options",
    "one_step_counts",
    "SkewerRoutine",
    "discover_skewer_routines",
    "skewer_routine_options",
    "with_options",
    # logging
    "TensorBoardLogger",
]
