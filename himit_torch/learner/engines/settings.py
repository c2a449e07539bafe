"""The compiled engine's settings: one named tuple of scalars, built from a batch's state.

Its fields are generated from the config schema: every
:class:`~himit_torch.learner.config.LearnerConfig` field declared ``kernel=True``
(:data:`~himit_torch.learner.config.KERNEL_FIELDS`, encoded by
:func:`~himit_torch.learner.config.kernel_fields`: ``None`` as the field's declared sentinel, a
choice as its index in its choices), then the few values the kernel derives from the
rest of the state (:data:`DERIVED`). A new setting the kernel reads is one ``kernel=True`` in its
declaration; nothing here is listed by hand but the derived values.

Every field has one fixed type (``float``, ``int`` or ``bool``), whatever the configuration, so
that Numba compiles the kernels once for all of them.
"""

from __future__ import annotations

from collections import namedtuple
from typing import TYPE_CHECKING, Any

from himit_torch.learner.config import (
    EPS_SCHEDULES,
    MENTOR_CHOICES,
    TIE_BREAKS,
    kernel_field_types,
    kernel_fields,
)

if TYPE_CHECKING:
    from himit_torch.learner.state import BatchState

__all__ = ["KernelSettings", "kernel_settings", "DERIVED"]

# The codes the kernel compares against (Numba reads module globals as constants).
EPS_DECISION, EPS_STEP, EPS_GOALS, EPS_PAPER = (EPS_SCHEDULES.index(s) for s in EPS_SCHEDULES)
MATCH = MENTOR_CHOICES.index("match")
TIE_FIRST = TIE_BREAKS.index("first")
# How eq. 2 treats a row never tried (``untried_mode``): the Dirichlet prior's value
# (concentration > 0), left out (untried_value None), or valued at untried_value.
UNTRIED_PRIOR, UNTRIED_SKIP, UNTRIED_VALUE = 0, 1, 2

#: The values the kernel derives from the state rather than reads from the config, and their
#: types.
DERIVED: dict[str, type] = {
    "gamma": float,  # the world's discount
    "round_size": int,  # states backed up together (Sweeper.round_size)
    "untried_mode": int,  # UNTRIED_PRIOR, UNTRIED_SKIP or UNTRIED_VALUE
    "any_confidence": bool,  # some run tests the mentor term's confidence
    "any_mentor": bool,  # some run uses the mentor term
    "stochastic": bool,  # the options' policies are distributions (else one action each)
    "start_state": int,  # -1: drawn from the world's start distribution at each episode
}
_TYPES: dict[str, type] = {**kernel_field_types(), **DERIVED}

#: The scalars the kernel reads: the config's kernel fields (same names), then :data:`DERIVED`.
KernelSettings: Any = namedtuple("KernelSettings", list(_TYPES))  # type: ignore[misc]  # (fields generated)


def kernel_settings(state: BatchState) -> Any:
    """The kernel's settings for ``state`` (a :data:`KernelSettings`): its config's kernel fields as
    :func:`~himit_torch.learner.config.kernel_fields` encodes them, plus what the state derives
    (each value cast to its field's fixed type)."""
    cfg = state.config
    tables = state.tables
    if cfg.concentration > 0:
        untried_mode = UNTRIED_PRIOR
    else:
        untried_mode = UNTRIED_SKIP if cfg.untried_value is None else UNTRIED_VALUE
    values: dict[str, Any] = dict(kernel_fields(cfg))
    values.update(
        gamma=tables.gamma,
        round_size=state.sweeper.round_size,
        untried_mode=untried_mode,
        any_confidence=state.cache.any_confidence,
        any_mentor=state.cache.any_mentor,
        stochastic=tables.options.policy is None,
        start_state=-1 if tables.start_cdf is not None else tables.start_state,
    )
    return KernelSettings(**{name: _TYPES[name](v) for name, v in values.items()})
