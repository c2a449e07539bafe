"""The agent variants a run of a batch can be."""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["AGENTS", "AgentVariant"]


class AgentVariant(NamedTuple):
    """What an agent variant of :data:`AGENTS` does (a tuple: ``AGENTS[a][1]`` is ``mentor``)."""

    options: str
    """``"all"`` the batch's options, ``"primitive"`` its primitive options only, or
    ``"extended"`` its extended options, with primitives only at states where no extended
    option starts (an options-only learner: it cannot act at the grain of a primitive mentor)."""
    mentor: bool
    """The mentor term of eq. 2 (eq. 1 with primitives)."""
    confident: bool
    """Price & Boutilier's confidence test of the mentor term."""
    sampling: bool
    """Planning on a posterior sample (:mod:`himit_torch.learner.posterior_sampling`)."""
    shaping: bool = False
    """Potential-based shaping from the demonstrations (:mod:`himit_torch.mentor.potential`)."""
    cloning: bool = False
    """Behavioural cloning from observation, BCO (:mod:`himit_torch.mentor.cloning`): the greedy
    choice is the cloned action where the cloned policy has one."""

    @property
    def uses_demonstrations(self) -> bool:
        """Whether the variant reads the demonstrations' rewards (mentor term or shaping
        potential), and so needs a mentor-reward module ``R_m`` (``bco`` reads the
        demonstrations' states only, and needs none)."""
        return self.mentor or self.shaping


#: Agent variants: which options a run may use, whether it imitates, and whether its mentor term
#: is confidence-tested. ``imitation`` — options + mentor (eq. 2); ``options`` — options only;
#: ``primitives`` — primitive options only; ``imitation_primitives`` — primitives + mentor (eq. 1,
#: Price & Boutilier); ``…_confident`` — the same with Price & Boutilier's confidence test
#: (:attr:`LearnerConfig.confidence_z`); ``…_psrl`` — the same options and mentor term, planned on
#: a model drawn from the posterior instead of its mean (posterior sampling,
#: :mod:`himit_torch.learner.posterior_sampling`; resampled per :attr:`LearnerConfig.resample_every`);
#: ``pbrs``, ``pbrs_primitives`` — all options / primitives only, no mentor term, with
#: potential-based reward shaping from the demonstrations (Ng, Harada & Russell 1999; Brys et al.
#: 2015; :mod:`himit_torch.mentor.potential`); ``bco`` — primitives only, no mentor term, greedy
#: choices replaced by the policy cloned from the demonstrations relabelled with an inverse model
#: of the run's own transitions where it has one (behavioural cloning from observation, Torabi,
#: Warnell & Stone 2018; :mod:`himit_torch.mentor.cloning`, ``LearnerConfig.bco_every``);
#: ``imitation_extended``, ``options_extended`` — eq. 2 and the plain learner acting through
#: extended options only, with primitives only where no extended option starts (doorway cells).
#: Fields: :class:`AgentVariant`.
AGENTS = {
    "imitation": AgentVariant("all", True, False, False),
    "imitation_confident": AgentVariant("all", True, True, False),
    "options": AgentVariant("all", False, False, False),
    "primitives": AgentVariant("primitive", False, False, False),
    "imitation_primitives": AgentVariant("primitive", True, False, False),
    "imitation_primitives_confident": AgentVariant("primitive", True, True, False),
    "imitation_psrl": AgentVariant("all", True, False, True),
    "options_psrl": AgentVariant("all", False, False, True),
    "primitives_psrl": AgentVariant("primitive", False, False, True),
    "imitation_primitives_psrl": AgentVariant("primitive", True, False, True),
    "pbrs": AgentVariant("all", False, False, False, shaping=True),
    "pbrs_primitives": AgentVariant("primitive", False, False, False, shaping=True),
    "bco": AgentVariant("primitive", False, False, False, cloning=True),
    "imitation_extended": AgentVariant("extended", True, False, False),
    "options_extended": AgentVariant("extended", False, False, False),
}
