"""The compiled engine's settings: one named tuple of scalars, built from a batch's state.

Every field has one fixed type (``float``, ``int`` or ``bool``), whatever the configuration, so
that Numba compiles the kernels once for all of them. Settings that may be ``None`` or a string
in :class:`~himit_torch.learner.config.LearnerConfig` get a number here: the rule for each is in
:data:`FROM_CONFIG`, the one list of the configuration fields the kernel reads.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple, get_type_hints

from himit_torch.learner.config import EPS_SCHEDULES, LearnerConfig

if TYPE_CHECKING:
    from himit_torch.learner.state import BatchState

__all__ = ["KernelSettings", "kernel_settings", "FROM_CONFIG"]

# The codes the kernel compares against (Numba reads module globals as constants).
EPS_DECISION, EPS_STEP, EPS_GOALS, EPS_PAPER = (EPS_SCHEDULES.index(s) for s in EPS_SCHEDULES)
MENTOR_CHOICES = LearnerConfig._CHOICES["mentor_choice"]
TIE_BREAKS = LearnerConfig._CHOICES["tie_break"]
MATCH = MENTOR_CHOICES.index("match")
TIE_FIRST = TIE_BREAKS.index("first")
# How eq. 2 treats a row never tried (``untried_mode``): the Dirichlet prior's value
# (concentration > 0), left out (untried_value None), or valued at untried_value.
UNTRIED_PRIOR, UNTRIED_SKIP, UNTRIED_VALUE = 0, 1, 2


class KernelSettings(NamedTuple):
    """The scalars the kernel reads. The first group comes from the config field of the same
    name (encoded by :data:`FROM_CONFIG`), the second is derived from the rest of the state."""

    backups: int
    plan_every: int
    max_option_steps: int
    priority_threshold: float
    initial_value: float
    concentration: float
    mentor_concentration: float
    confidence_z: float
    eps_decay: float
    eps_min: float
    eps_goals: int
    eps_schedule: int  # its index in EPS_SCHEDULES
    mentor_fade: float  # 0.0: None (no fading)
    mentor_override_after: int  # -1: None (never overridden)
    untried_value: float  # 0.0: None (read only when untried_mode is UNTRIED_VALUE)
    resample_every: int
    mentor_choice: int  # its index in MENTOR_CHOICES
    tie_break: int  # its index in TIE_BREAKS
    # ---- derived
    gamma: float  # the world's discount
    round_size: int  # states backed up together (Sweeper.round_size)
    untried_mode: int  # UNTRIED_PRIOR, UNTRIED_SKIP or UNTRIED_VALUE
    any_confidence: bool  # some run tests the mentor term's confidence
    any_mentor: bool  # some run uses the mentor term
    stochastic: bool  # the options' policies are distributions (else one action each)
    start_state: int  # -1: drawn from the world's start distribution at each episode


def _none_as(code: float | int) -> Callable[[Any], Any]:
    return lambda value: code if value is None else value


# Config field -> how its value becomes the kernel's scalar (then cast to the field's type).
FROM_CONFIG: dict[str, Callable[[Any], Any]] = {
    "backups": int,
    "plan_every": int,
    "max_option_steps": int,
    "priority_threshold": float,
    "initial_value": float,
    "concentration": float,
    "mentor_concentration": float,
    "confidence_z": float,
    "eps_decay": float,
    "eps_min": float,
    "eps_goals": int,
    "eps_schedule": EPS_SCHEDULES.index,
    "mentor_fade": _none_as(0.0),
    "mentor_override_after": _none_as(-1),
    "untried_value": _none_as(0.0),
    "resample_every": int,
    "mentor_choice": MENTOR_CHOICES.index,
    "tie_break": TIE_BREAKS.index,
}
_DERIVED = (
    "gamma",
    "round_size",
    "untried_mode",
    "any_confidence",
    "any_mentor",
    "stochastic",
    "start_state",
)
if tuple(FROM_CONFIG) + _DERIVED != KernelSettings._fields:
    raise ValueError(
        "KernelSettings' fields must be FROM_CONFIG's names then _DERIVED's, in that order"
    )
_TYPES: dict[str, type] = get_type_hints(KernelSettings)


def kernel_settings(state: BatchState) -> KernelSettings:
    """The kernel's settings for ``state``: its config encoded by :data:`FROM_CONFIG`, plus what
    the state derives (each value cast to its field's fixed type)."""
    cfg = state.config
    tables = state.tables
    if cfg.concentration > 0:
        untried_mode = UNTRIED_PRIOR
    else:
        untried_mode = UNTRIED_SKIP if cfg.untried_value is None else UNTRIED_VALUE
    values: dict[str, Any] = {name: rule(getattr(cfg, name)) for name, rule in FROM_CONFIG.items()}
    values.update(
        gamma=tables.gamma,
        round_size=state.sweeper.round_size,
        untried_mode=untried_mode,
        any_confidence=state.cache.any_confidence,
        any_mentor=state.cache.any_mentor,
        stochastic=tables.policy is None,
        start_state=-1 if tables.start_cdf is not None else tables.start_state,
    )
    return KernelSettings(**{name: _TYPES[name](v) for name, v in values.items()})
