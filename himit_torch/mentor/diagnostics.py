"""Where the mentor term still decides eq. 2, and by how much.

At a state ``s`` the mentor observed, eq. 2 takes ``max(own(s), m(s))``: ``own`` the best own
option tried there (its ``Q``), ``m`` the mentor term ``R_m(s) + γ Σ p_m(s'|s) V(s')``. Where
``m`` wins, ``V(s)`` is the mentor's value — an estimate the run may not be able to realise with
its own options, which biases ``V`` upwards there and upstream. These functions read a learner's
caches (no planning, nothing changed).
"""

from __future__ import annotations

import torch

__all__ = ["mentor_margins", "mentor_margin_summary"]


def mentor_margins(learner) -> dict[str, torch.Tensor]:
    """Per run and mentor-observed state, the mentor term against the best own option tried.

    Returns ``[B, S]`` float64 tensors (NaN where the mentor was not observed, or for runs
    without a mentor term): ``mentor`` (``m(s)``), ``own`` (best ``Q`` over the run's tried,
    usable own options; ``-inf`` where none was tried), ``margin`` (``m − own``; ``+inf`` where
    nothing was tried) and a bool ``wins`` (the mentor term is the max of eq. 2 as the learner
    computes it, with its override and confidence rules).
    """
    cache, B, S = learner.cache, learner.batch, learner.num_states
    dev = learner.device
    runs = torch.arange(B, device=dev)[:, None]
    states = torch.arange(S, device=dev)[None].expand(B, -1)
    _, q, usable, _, _, n = cache.own_values(runs, states)
    tried = usable & (n > 0)
    own = torch.where(tried, q, torch.full_like(q, float("-inf"))).amax(-1)
    m = cache.mentor_term(runs, states)
    _, _, wins = cache.state_backup(runs, states)
    observed = learner.mentor.observed() & learner.rows.use_mentor[:, None]
    nan = torch.full_like(m, float("nan"))
    return {
        "mentor": torch.where(observed, m, nan),
        "own": torch.where(observed, own, nan),
        "margin": torch.where(observed, m - own, nan),
        "wins": wins & observed,
    }


def mentor_margin_summary(learner) -> dict[str, list[float]]:
    """Per run: ``observed`` (mentor states), ``win_share`` (share of them where the mentor term
    wins), ``untried_share`` (share where no own option was tried), and over the states where
    it wins with some own option tried: ``mean_margin``, ``median_margin``, ``max_margin``
    (``m − own``, in value units; one step costs 0.01 in the paper's worlds). NaN for runs
    without a mentor term."""
    d = mentor_margins(learner)
    out: dict[str, list[float]] = {
        k: []
        for k in (
            "observed",
            "win_share",
            "untried_share",
            "mean_margin",
            "median_margin",
            "max_margin",
        )
    }
    for b in range(learner.batch):
        obs = ~d["mentor"][b].isnan()
        k = int(obs.sum())
        if k == 0:
            for key in out:
                out[key].append(float("nan"))
            continue
        wins = d["wins"][b] & obs
        untried = obs & torch.isinf(d["own"][b])
        finite = wins & ~untried
        margins = d["margin"][b][finite]
        out["observed"].append(float(k))
        out["win_share"].append(float(wins.sum()) / k)
        out["untried_share"].append(float(untried.sum()) / k)
        if margins.numel():
            out["mean_margin"].append(float(margins.mean()))
            out["median_margin"].append(float(margins.median()))
            out["max_margin"].append(float(margins.max()))
        else:
            for key in ("mean_margin", "median_margin", "max_margin"):
                out[key].append(float("nan"))
    return out
