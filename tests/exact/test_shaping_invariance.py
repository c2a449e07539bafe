"""Potential-based shaping leaves the optimal options unchanged (Ng, Harada & Russell 1999), over
options with multi-time models: value iteration on the shaped and the unshaped exact option models
of a small slippery world, for arbitrary potentials (0 at terminal states)."""

from dataclasses import replace

import pytest
import torch

from himit_torch.exact.option_models import option_models
from himit_torch.exact.planning import smdp_value_iteration
from himit_torch.learner.backups import shaped_option_backup
from himit_torch.options.builders import learner_options
from himit_torch.worlds.multirooms import MultiRooms


@pytest.mark.parametrize("seed, scale", [(0, 1.0), (1, 10.0), (2, 0.05)])
def test_shaping_leaves_the_optimal_options_unchanged(seed, scale):
    world = MultiRooms(size=8, rooms=2, slip=0.1)
    models = option_models(world, learner_options(world))
    S = models.num_states
    has_option = torch.zeros(S, dtype=torch.bool)
    has_option[models.row_state] = True
    assert not bool(has_option[world.terminal_mask].any())
    gen = torch.Generator().manual_seed(seed)
    phi = scale * torch.randn(S, generator=gen, dtype=torch.float64)
    phi[~has_option] = 0.0  # terminal states (and walls, never entered): Φ = 0
    # r'(s, o) = r(s, o) + Σ P^o[s, s'] Φ(s') − Φ(s): the telescoped shaping, P^o carrying γ^k.
    shaped_reward = models.reward + (models.transition @ phi[:, None])[:, 0] - phi[models.row_state]
    shaped = replace(models, reward=shaped_reward)
    assert float((shaped_reward - models.reward).abs().max()) > 0.01 * scale  # not a no-op

    plain_plan = smdp_value_iteration(models, tol=1e-13)
    shaped_plan = smdp_value_iteration(shaped, tol=1e-13)
    # V' = V − Φ and Q'(s, o) = Q(s, o) − Φ(s) at every state with an option.
    torch.testing.assert_close(
        shaped_plan.values[has_option], (plain_plan.values - phi)[has_option], atol=1e-8, rtol=0
    )
    torch.testing.assert_close(
        shaped_plan.q, plain_plan.q - phi[models.row_state], atol=1e-8, rtol=0
    )
    # The shaped Q is shaped_option_backup of the shaped values, row by row (dense successors).
    dense = models.transition.to_dense()
    recomputed = shaped_option_backup(
        models.reward,
        dense,
        shaped_plan.values.expand(models.num_rows, S),
        phi[models.row_state],
        phi.expand(models.num_rows, S),
    )
    torch.testing.assert_close(recomputed, shaped_plan.q, atol=1e-8, rtol=0)

    # The same greedy option wherever the best option is clear of the second best; where two
    # tie (equal paths), each plan's choice is optimal in the other's model.
    live = has_option.nonzero()[:, 0]
    same = plain_plan.policy[live] == shaped_plan.policy[live]
    clear = torch.zeros(live.numel(), dtype=torch.bool)
    for i, s in enumerate(live.tolist()):
        q = plain_plan.q[models.row_state == s].sort(descending=True).values
        clear[i] = q.numel() == 1 or bool(q[0] - q[1] > 1e-6)
        for plan, other in ((plain_plan, shaped_plan), (shaped_plan, plain_plan)):
            chosen = (models.row_state == s) & (models.row_option == plan.policy[s])
            assert float(other.q[chosen]) >= float(other.values[s]) - 1e-8, s
    assert int(clear.sum()) >= 10, int(clear.sum())  # (the rest tie: symmetric paths)
    assert bool(same[clear].all())
