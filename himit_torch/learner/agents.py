"""The agent variants a run of a batch can be."""

from __future__ import annotations

__all__ = ["AGENTS"]

#: Agent variants: which options a run may use, whether it imitates, and whether its mentor term
#: is confidence-tested. ``imitation`` — options + mentor (eq. 2); ``options`` — options only;
#: ``primitives`` — primitive options only; ``imitation_primitives`` — primitives + mentor (eq. 1,
#: Price & Boutilier); ``…_confident`` — the same with Price & Boutilier's confidence test
#: (:attr:`LearnerConfig.confidence_z`); ``…_psrl`` — the same options and mentor term, planned on
#: a model drawn from the posterior instead of its mean (posterior sampling,
#: :mod:`himit_torch.learner.posterior_sampling`; resampled per :attr:`LearnerConfig.resample_every`).
#: Fields: options, mentor term, confidence test, posterior sampling.
AGENTS = {
    "imitation": ("all", True, False, False),
    "imitation_confident": ("all", True, True, False),
    "options": ("all", False, False, False),
    "primitives": ("primitive", False, False, False),
    "imitation_primitives": ("primitive", True, False, False),
    "imitation_primitives_confident": ("primitive", True, True, False),
    "imitation_psrl": ("all", True, False, True),
    "options_psrl": ("all", False, False, True),
    "primitives_psrl": ("primitive", False, False, True),
    "imitation_primitives_psrl": ("primitive", True, False, True),
}
