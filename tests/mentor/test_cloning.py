"""Behavioural cloning from observation (:mod:`himit_torch.mentor.cloning`): the inverse model,
the relabelling and the cloning solved by hand on three states, and the refusals."""

import pytest
import torch

from himit_torch.mentor.cloning import clone_policy, inverse_model, relabel

# Three states 0, 1, 2 and two actions. Own transitions s --a--> s' (count):
#   0 --0--> 1 (1);  0 --1--> 1 (2);  0 --1--> 2 (8);
#   1 --0--> 2 (3);  1 --1--> 2 (3);  1 --1--> 0 (1).
# So n(0, 0) = 1, n(0, 1) = 10, n(1, 0) = 3, n(1, 1) = 4.
OWN_S = torch.tensor([0, 0, 0, 1, 1, 1])
OWN_A = torch.tensor([0, 1, 1, 0, 1, 1])
OWN_S2 = torch.tensor([1, 1, 2, 2, 2, 0])
OWN_N = torch.tensor([1.0, 2.0, 8.0, 3.0, 3.0, 1.0], dtype=torch.float64)
# The mentor's observed transitions (count): 0→1 (2), 0→2 (1), 1→2 (1), 2→0 (1), 1→0 (1).
M_S = torch.tensor([0, 0, 1, 2, 1])
M_S2 = torch.tensor([1, 2, 2, 0, 0])
M_N = torch.tensor([2.0, 1.0, 1.0, 1.0, 1.0], dtype=torch.float64)


def _table(model) -> dict:
    return {
        (int(s), int(s2), int(a)): float(p)
        for s, s2, a, p in zip(model.states, model.successors, model.actions, model.probability)
    }


def test_inverse_model_by_hand_counts():
    """p(a | s, s') = n(s, a, s') / Σ_a' n(s, a', s'):
    (0, 1): a0 1/3, a1 2/3; (0, 2): a1 1; (1, 2): a0 3/6, a1 3/6; (1, 0): a1 1."""
    table = _table(inverse_model(OWN_S, OWN_A, OWN_S2, OWN_N, "counts"))
    expected = {
        (0, 1, 0): 1 / 3,
        (0, 1, 1): 2 / 3,
        (0, 2, 1): 1.0,
        (1, 2, 0): 0.5,
        (1, 2, 1): 0.5,
        (1, 0, 1): 1.0,
    }
    assert table.keys() == expected.keys()
    for k, p in expected.items():
        assert table[k] == pytest.approx(p, abs=1e-15), k


def test_inverse_model_by_hand_likelihood():
    """p(a | s, s') ∝ n(s, a, s') / n(s, a):
    (0, 1): a0 1/1 = 1, a1 2/10 = 0.2 → 5/6, 1/6 (the rarely taken action explains 0→1 better);
    (1, 2): a0 3/3 = 1, a1 3/4 → 4/7, 3/7."""
    table = _table(inverse_model(OWN_S, OWN_A, OWN_S2, OWN_N, "likelihood"))
    assert table[(0, 1, 0)] == pytest.approx(5 / 6, abs=1e-15)
    assert table[(0, 1, 1)] == pytest.approx(1 / 6, abs=1e-15)
    assert table[(1, 2, 0)] == pytest.approx(4 / 7, abs=1e-15)
    assert table[(1, 2, 1)] == pytest.approx(3 / 7, abs=1e-15)
    assert table[(0, 2, 1)] == table[(1, 0, 1)] == 1.0


def test_relabel_and_clone_by_hand():
    """Relabelling (argmax, ties to the lowest action, −1 where never seen) and cloning (majority
    of the weighted labels out of each state, ties to the lowest, −1 where none):

    counts:     0→1: a1 (2/3);  0→2: a1;  1→2: tie ½ ½ → a0;  2→0: unseen → −1;  1→0: a1.
                π(0): a1 with weight 2 + 1 = 3;  π(1): a0 1 vs a1 1, a tie → a0;  π(2): −1.
    likelihood: 0→1: a0 (5/6); the rest as above.
                π(0): a0 weight 2 vs a1 weight 1 → a0;  π(1): a0;  π(2): −1."""
    counts = inverse_model(OWN_S, OWN_A, OWN_S2, OWN_N, "counts")
    labels = relabel(counts, M_S, M_S2)
    assert labels.tolist() == [1, 1, 0, -1, 1]
    assert clone_policy(M_S, labels, M_N, 3, 2).tolist() == [1, 0, -1]

    likelihood = inverse_model(OWN_S, OWN_A, OWN_S2, OWN_N, "likelihood")
    labels = relabel(likelihood, M_S, M_S2)
    assert labels.tolist() == [0, 1, 0, -1, 1]
    assert clone_policy(M_S, labels, M_N, 3, 2).tolist() == [0, 0, -1]


def test_repeated_transitions_add_up_and_zero_counts_are_left_out():
    """0 --1--> 2 listed as 3 + 5 is 0 --1--> 2 counted 8; a count of 0 explains nothing."""
    s = torch.cat([OWN_S, torch.tensor([0, 2])])
    a = torch.cat([OWN_A, torch.tensor([1, 0])])
    s2 = torch.cat([OWN_S2, torch.tensor([2, 0])])
    n = torch.cat([OWN_N, torch.tensor([0.0, 0.0], dtype=torch.float64)])
    n[2] = 3.0
    split = torch.cat([s[:3], torch.tensor([0]), s[3:]])
    split_a = torch.cat([a[:3], torch.tensor([1]), a[3:]])
    split_s2 = torch.cat([s2[:3], torch.tensor([2]), s2[3:]])
    split_n = torch.cat([n[:3], torch.tensor([5.0], dtype=torch.float64), n[3:]])
    model = inverse_model(split, split_a, split_s2, split_n)
    assert _table(model) == _table(inverse_model(OWN_S, OWN_A, OWN_S2, OWN_N))
    assert relabel(model, torch.tensor([2]), torch.tensor([0])).tolist() == [-1]


def test_cloning_weighs_by_how_often_a_transition_was_seen():
    """State 0 seen twice with label 1 and three times with label 0: π(0) = 0; with the weights
    reversed, 1. Unlabelled transitions do not vote."""
    states = torch.tensor([0, 0, 0])
    labels = torch.tensor([1, 0, -1])
    heavy = torch.tensor([2.0, 3.0, 9.0], dtype=torch.float64)
    assert clone_policy(states, labels, heavy, 1, 2).tolist() == [0]
    assert clone_policy(states, labels, heavy[[1, 0, 2]], 1, 2).tolist() == [1]


def test_no_own_experience_labels_nothing():
    empty = torch.zeros(0, dtype=torch.int64)
    model = inverse_model(empty, empty, empty, torch.zeros(0, dtype=torch.float64))
    labels = relabel(model, M_S, M_S2)
    assert labels.tolist() == [-1] * 5
    assert clone_policy(M_S, labels, M_N, 3, 2).tolist() == [-1, -1, -1]


def test_refusals():
    with pytest.raises(ValueError, match="kind"):
        inverse_model(OWN_S, OWN_A, OWN_S2, OWN_N, "uniform")
    with pytest.raises(ValueError, match="one length"):
        inverse_model(OWN_S, OWN_A[:-1], OWN_S2, OWN_N)
    with pytest.raises(ValueError, match="counts"):
        inverse_model(OWN_S, OWN_A, OWN_S2, -OWN_N)
    with pytest.raises(ValueError, match="int64"):
        inverse_model(OWN_S.float(), OWN_A, OWN_S2, OWN_N)
    with pytest.raises(ValueError, match="weights"):
        clone_policy(M_S, M_S, torch.zeros(5, dtype=torch.float64), 3, 2)
    with pytest.raises(ValueError, match="labels"):
        clone_policy(M_S, M_S + 5, M_N, 3, 2)
