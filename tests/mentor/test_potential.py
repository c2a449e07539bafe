"""The shaping potential of the demonstrations (:mod:`himit_torch.mentor.potential`): a
hand-solved chain, the boundary values, and the refusals."""

import pytest
import torch

from himit_torch.mentor.potential import mentor_chain_value, shaping_potential

# States: 0 = a, 1 = b, 2 = goal (terminal), 3 = c, 4 = d (never left by the mentor), 5 = e.
TERMINAL = torch.tensor([False, False, True, False, False, False])
# Moves seen (count): a→b (1), b→goal (1), c→a (2), c→d (1), e→e (1), e→b (1).
SOURCES = torch.tensor([0, 1, 3, 3, 5, 5])
SUCCESSORS = torch.tensor([1, 2, 0, 4, 5, 1])
COUNTS = torch.tensor([1.0, 1.0, 2.0, 1.0, 1.0, 1.0], dtype=torch.float64)
# r_m: −0.01 for entering any state, +1 for entering the goal.
REWARDS = torch.tensor([-0.01, 1.0, -0.01, -0.01, -0.01, -0.01], dtype=torch.float64)
GAMMA, V0 = 0.9, -1.0


def test_chain_value_solved_by_hand():
    """W(b) = 1 (into the goal, W(goal) = 0);
    W(a) = −0.01 + 0.9 · W(b) = 0.89;
    W(c) = −0.01 + 0.9 · (2/3 · W(a) + 1/3 · W(d)), with W(d) = v0 = −1 (never left):
         = −0.01 + 0.9 · (0.59333… − 0.33333…) = −0.01 + 0.234 = 0.224;
    W(e) = −0.01 + 0.9 · (½ W(e) + ½ W(b))  ⇒  0.55 W(e) = 0.44  ⇒  W(e) = 0.8 (a loop: solved,
    not iterated)."""
    W, seen = mentor_chain_value(SOURCES, SUCCESSORS, COUNTS, REWARDS, GAMMA, TERMINAL, V0)
    expected = torch.tensor([0.89, 1.0, 0.0, 0.224, -1.0, 0.8], dtype=torch.float64)
    torch.testing.assert_close(W, expected, atol=1e-12, rtol=0)
    assert seen.tolist() == [True, True, False, True, False, True]


def test_potential_is_chain_value_minus_v0_on_the_mentors_states_and_0_elsewhere():
    phi = shaping_potential(SOURCES, SUCCESSORS, COUNTS, REWARDS, GAMMA, TERMINAL, V0)
    # W − v0 = W + 1 where the mentor was seen leaving; 0 at the goal and at d.
    expected = torch.tensor([1.89, 2.0, 0.0, 1.224, 0.0, 1.8], dtype=torch.float64)
    torch.testing.assert_close(phi, expected, atol=1e-12, rtol=0)
    # Another v0 moves the boundary value of d and the offset together: v0 = 0 gives
    # W(c) = −0.01 + 0.9 · 2/3 · 0.89 = 0.524, and Φ = W.
    phi0 = shaping_potential(SOURCES, SUCCESSORS, COUNTS, REWARDS, GAMMA, TERMINAL, 0.0)
    assert phi0[3].item() == pytest.approx(0.524, abs=1e-12)
    assert phi0[0].item() == pytest.approx(0.89, abs=1e-12)


def test_repeated_moves_add_up_like_counts():
    """The same move listed twice with count 1 is the move with count 2."""
    src = torch.tensor([0, 1, 3, 3, 3])
    dst = torch.tensor([1, 2, 0, 0, 4])
    ones = torch.ones(5, dtype=torch.float64)
    rew = torch.tensor([-0.01, 1.0, -0.01, -0.01, -0.01], dtype=torch.float64)
    W, _ = mentor_chain_value(src, dst, ones, rew, GAMMA, TERMINAL, V0)
    assert W[3].item() == pytest.approx(0.224, abs=1e-12)


def test_no_demonstrations_no_potential():
    empty = torch.zeros(0, dtype=torch.int64)
    phi = shaping_potential(empty, empty, empty.double(), empty.double(), GAMMA, TERMINAL, V0)
    assert torch.equal(phi, torch.zeros(6, dtype=torch.float64))


def test_refusals():
    with pytest.raises(ValueError, match="terminal"):  # a move out of the goal
        mentor_chain_value(
            torch.tensor([2]), torch.tensor([0]), torch.ones(1), torch.zeros(1), GAMMA, TERMINAL, V0
        )
    with pytest.raises(ValueError, match="no unique solution"):  # γ = 1, a loop with no exit
        mentor_chain_value(
            torch.tensor([0, 1]),
            torch.tensor([1, 0]),
            torch.ones(2),
            torch.zeros(2),
            1.0,
            TERMINAL,
            V0,
        )
    with pytest.raises(ValueError, match="positive"):
        mentor_chain_value(
            torch.tensor([0]),
            torch.tensor([1]),
            torch.zeros(1),
            torch.zeros(1),
            GAMMA,
            TERMINAL,
            V0,
        )
    with pytest.raises(ValueError, match="four"):
        mentor_chain_value(
            torch.tensor([0]),
            torch.tensor([1, 2]),
            torch.ones(1),
            torch.zeros(1),
            GAMMA,
            TERMINAL,
            V0,
        )
