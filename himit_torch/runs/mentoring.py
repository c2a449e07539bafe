"""What a multi-room experiment's mentor shows: each seed's recorded episodes, with the stresses
on them (``ExperimentConfig``'s ``mentor_goal``, ``mentor_noise``, ``mentor_detour``,
``mentor_coverage``). Shared by the studies that watch that mentor (the experiments,
:mod:`himit_torch.runs.experiment`; discovery, :mod:`himit_torch.runs.discovery`), which may not
import one another."""

from __future__ import annotations

from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.observation import first_part
from himit_torch.mentor.policy import mentor_detour, record_demonstrations
from himit_torch.runs.config import ExperimentConfig
from himit_torch.worlds.multirooms import MultiRooms

__all__ = ["recorded_mentor_episodes", "mentor_detour_of"]


def recorded_mentor_episodes(config: ExperimentConfig, world: MultiRooms, mentor, seeds) -> dict:
    """Each seed's recorded mentor episodes (that seed's own generator), ``{seed:
    Demonstrations}``, with the stresses on what the mentor shows (``mentor_goal``, its noise,
    detour and coverage); its policy, the "% of mentor" reference, stays undisturbed. ``mentor``
    is the experiment's mentor in ``world`` (a moved goal's mentor is built here)."""
    if config.mentor_goal != "same":  # walking to the top-right corner, in the learner's world
        leg = mentor_detour_of(config, world)
        recorded = {
            s: Demonstrations(
                record_demonstrations(
                    leg.first_leg,
                    leg.to_waypoint,
                    config.mentor_episodes,
                    seed=s,
                    noise=config.mentor_noise,
                ).episodes,
                world,
            )
            for s in seeds
        }
    else:
        detour = mentor_detour_of(config, world) if config.mentor_detour else None
        recorded = {
            s: record_demonstrations(
                world,
                mentor,
                config.mentor_episodes,
                seed=s,
                noise=config.mentor_noise,
                detour=detour,
            )
            for s in seeds
        }
    if config.mentor_coverage < 1:  # only the first part of each route (mentor_coverage)
        recorded = {s: first_part(d, config.mentor_coverage) for s, d in recorded.items()}
    return recorded


def mentor_detour_of(config: ExperimentConfig, world: MultiRooms):
    """The mentor's walk by the top-right corner (its options and preference as the mentor's)."""
    return mentor_detour(
        world, corners=config.corner_options, prefer_extended_within=config.mentor_preference
    )
