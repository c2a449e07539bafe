"""Every public function of ``learner/backups.py`` refuses an argument of the wrong rank or shape
(rlax-style asserts at its top) with a ``ValueError`` naming the function and the argument; the
same calls with the right shapes pass. And :func:`mentor_backup_edges`, the mentor term's edge
sum the value cache rebuilds from, by hand."""

from __future__ import annotations

import pytest
import torch

from himit_torch.learner import backups as B
from himit_torch.learner.backups import MentorConfidence


def f64(*shape: int) -> torch.Tensor:
    return torch.zeros(shape, dtype=torch.float64)


def flags(*shape: int) -> torch.Tensor:
    return torch.ones(shape, dtype=torch.bool)


def i64(*shape: int) -> torch.Tensor:
    return torch.zeros(shape, dtype=torch.int64)


def _confidence(own_var=None, mentor_var=None, tested=None) -> MentorConfidence:
    return MentorConfidence(
        own_var=f64(3, 2) if own_var is None else own_var,
        mentor_var=f64(3) if mentor_var is None else mentor_var,
        tested=flags(3) if tested is None else tested,
        z=1.0,
    )


# Each function's good arguments (batch [3], K = J = A = 2, N = 4 edges): the same call must
# pass; every bad case below replaces one of them.
GOOD = {
    "option_backup": dict(reward=f64(3), weights=f64(3, 2), successor_values=f64(3, 2)),
    "option_backup_edges": dict(
        reward=f64(2, 5), runs=i64(4), rows=i64(4), weights=f64(4), successor_values=f64(4)
    ),
    "mentor_backup_edges": dict(
        shape=(2, 5),
        runs=i64(4),
        rows=i64(4),
        counts=f64(4),
        rewards=f64(4),
        discounts=f64(4),
        successor_values=f64(4),
    ),
    "shaped_option_backup": dict(
        reward=f64(3),
        weights=f64(3, 2),
        successor_values=f64(3, 2),
        potential=f64(3),
        successor_potentials=f64(3, 2),
    ),
    "mentor_backup": dict(
        mentor_reward=f64(3), mentor_probs=f64(3, 2), successor_values=f64(3, 2), gamma=0.9
    ),
    "segment_reward": dict(
        last_reward=f64(3),
        delay=torch.ones(3, dtype=torch.float64),
        unseen_step_reward=f64(),
        gamma=0.9,
    ),  # fmt: skip
    "segment_discount": dict(delay=f64(3), gamma=0.9),
    "segment_mentor_backup": dict(
        segment_rewards=f64(3, 2),
        segment_discounts=f64(3, 2),
        mentor_probs=f64(3, 2),
        successor_values=f64(3, 2),
    ),
    "options_only_backup": dict(option_q=f64(3, 2), available=flags(3, 2)),
    "augmented_option_backup": dict(
        option_q=f64(3, 2), available=flags(3, 2), mentor_term=f64(3), mentor_available=flags(3)
    ),
    "augmented_backup": dict(own_value=f64(3), mentor_term=f64(3), mentor_available=flags(3)),
    "primitives_only_backup": dict(
        reward=f64(3, 2), probs=f64(3, 2, 4), successor_values=f64(3, 2, 4), gamma=0.9
    ),
    "augmented_primitive_backup": dict(
        observer_reward=f64(3),
        probs=f64(3, 2, 4),
        successor_values=f64(3, 2, 4),
        mentor_probs=f64(3, 4),
        mentor_successor_values=f64(3, 4),
        mentor_available=flags(3),
        gamma=0.9,
    ),
    "dirichlet_value_moments": dict(counts=f64(3, 2), outcome_values=f64(3, 2)),
    "dirichlet_variance": dict(mean=f64(3), second_moment=f64(3), total=f64(3)),
    "confident_mentor": dict(
        mentor_mean=f64(3),
        mentor_var=f64(3),
        own_mean=f64(3, 2),
        own_var=f64(3, 2),
        own_available=flags(3, 2),
        z=1.0,
    ),
    "mentor_override": dict(observed=flags(3), own_tries=f64(3), override_after=2),
    "feasible_mentor": dict(reached=f64(3, 2), tries=f64(3, 2), enabled=flags(3, 2), min_tries=2),
    "best_mentor": dict(terms=f64(3, 2), observed=flags(3, 2)),
    "faded_mentor_term": dict(mentor_term=f64(3), own_value=f64(3), own_tries=f64(3), fade=2.0),
    "trusted_augmented_backup": dict(
        option_q=f64(3, 2),
        available=flags(3, 2),
        mentor_term=f64(3),
        mentor_observed=flags(3),
        own_tries=f64(3),
        override_after=2,
        confidence=_confidence(),
        fade=2.0,
    ),
}

# (function, argument, bad value, the name the error must give)
BAD = [
    ("option_backup", "weights", f64(), "weights"),  # rank 0: no K
    ("option_backup", "successor_values", f64(3, 4), "successor_values"),
    ("option_backup", "reward", f64(2), "reward"),
    ("option_backup", "reward", 0.5, "reward"),  # not a tensor
    ("option_backup_edges", "reward", f64(10), "reward"),
    ("option_backup_edges", "runs", i64(2, 2), "runs"),
    ("option_backup_edges", "rows", i64(3), "rows"),
    ("option_backup_edges", "weights", f64(4, 1), "weights"),
    ("option_backup_edges", "successor_values", f64(5), "successor_values"),
    ("mentor_backup_edges", "shape", (10,), "shape"),
    ("mentor_backup_edges", "runs", i64(), "runs"),
    ("mentor_backup_edges", "rows", i64(3), "rows"),
    ("mentor_backup_edges", "counts", f64(4, 1), "counts"),
    ("mentor_backup_edges", "rewards", f64(5), "rewards"),
    ("mentor_backup_edges", "discounts", f64(3), "discounts"),
    ("mentor_backup_edges", "successor_values", f64(), "successor_values"),
    ("shaped_option_backup", "weights", f64(), "weights"),
    ("shaped_option_backup", "successor_values", f64(3, 3), "successor_values"),
    ("shaped_option_backup", "successor_potentials", f64(3), "successor_potentials"),
    ("shaped_option_backup", "reward", f64(3, 1), "reward"),
    ("shaped_option_backup", "potential", f64(2), "potential"),
    ("mentor_backup", "mentor_probs", f64(), "mentor_probs"),
    ("mentor_backup", "successor_values", f64(3, 5), "successor_values"),
    ("mentor_backup", "mentor_reward", f64(3, 2), "mentor_reward"),
    ("segment_reward", "delay", f64(2), "delay"),
    ("segment_reward", "unseen_step_reward", f64(2), "unseen_step_reward"),
    ("segment_discount", "delay", 0.5, "delay"),
    ("segment_mentor_backup", "mentor_probs", f64(), "mentor_probs"),
    ("segment_mentor_backup", "segment_rewards", f64(3), "segment_rewards"),
    ("segment_mentor_backup", "segment_discounts", f64(2, 2), "segment_discounts"),
    ("segment_mentor_backup", "successor_values", f64(3, 3), "successor_values"),
    ("options_only_backup", "option_q", f64(), "option_q"),
    ("options_only_backup", "available", flags(3), "available"),
    ("augmented_option_backup", "option_q", f64(), "option_q"),
    ("augmented_option_backup", "available", flags(3, 1), "available"),
    ("augmented_option_backup", "mentor_term", f64(3, 2), "mentor_term"),
    ("augmented_option_backup", "mentor_available", flags(1), "mentor_available"),
    ("augmented_backup", "mentor_term", f64(1), "mentor_term"),  # no broadcasting
    ("augmented_backup", "mentor_available", flags(3, 1), "mentor_available"),
    ("primitives_only_backup", "probs", f64(4), "probs"),
    ("primitives_only_backup", "successor_values", f64(3, 2, 3), "successor_values"),
    ("primitives_only_backup", "reward", f64(3), "reward"),
    ("augmented_primitive_backup", "probs", f64(4), "probs"),
    ("augmented_primitive_backup", "successor_values", f64(3, 2), "successor_values"),
    ("augmented_primitive_backup", "observer_reward", f64(3, 2), "observer_reward"),
    ("augmented_primitive_backup", "mentor_available", flags(2), "mentor_available"),
    ("augmented_primitive_backup", "mentor_probs", f64(), "mentor_probs"),
    ("augmented_primitive_backup", "mentor_probs", f64(2, 4), "mentor_probs"),
    ("augmented_primitive_backup", "mentor_successor_values", f64(3, 5), "mentor_successor_values"),
    ("dirichlet_value_moments", "counts", f64(), "counts"),
    ("dirichlet_value_moments", "outcome_values", f64(3, 3), "outcome_values"),
    ("dirichlet_variance", "second_moment", f64(3, 1), "second_moment"),
    ("dirichlet_variance", "total", f64(), "total"),
    ("confident_mentor", "own_mean", f64(), "own_mean"),
    ("confident_mentor", "own_var", f64(3, 3), "own_var"),
    ("confident_mentor", "own_available", flags(3), "own_available"),
    ("confident_mentor", "mentor_mean", f64(3, 2), "mentor_mean"),
    ("confident_mentor", "mentor_var", f64(1), "mentor_var"),
    ("mentor_override", "own_tries", f64(2), "own_tries"),
    ("feasible_mentor", "reached", f64(), "reached"),
    ("feasible_mentor", "tries", f64(3), "tries"),
    ("feasible_mentor", "enabled", flags(3, 3), "enabled"),
    ("best_mentor", "terms", f64(), "terms"),
    ("best_mentor", "terms", f64(3, 0), "terms"),  # no mentor at all
    ("best_mentor", "observed", flags(3, 1), "observed"),
    ("faded_mentor_term", "own_value", f64(1), "own_value"),
    ("faded_mentor_term", "own_tries", f64(3, 1), "own_tries"),
    ("trusted_augmented_backup", "option_q", f64(), "option_q"),
    ("trusted_augmented_backup", "available", flags(3), "available"),
    ("trusted_augmented_backup", "mentor_term", f64(2), "mentor_term"),
    ("trusted_augmented_backup", "mentor_observed", flags(3, 2), "mentor_observed"),
    ("trusted_augmented_backup", "own_tries", f64(1), "own_tries"),
    ("trusted_augmented_backup", "confidence", _confidence(own_var=f64(3)), "confidence.own_var"),
    (
        "trusted_augmented_backup",
        "confidence",
        _confidence(mentor_var=f64(3, 2)),
        "confidence.mentor_var",
    ),
    ("trusted_augmented_backup", "confidence", _confidence(tested=flags(2)), "confidence.tested"),
    (
        "trusted_augmented_backup",
        "confidence",
        _confidence(tested=flags(3, 3)),
        "confidence.tested",
    ),
]


def test_every_public_function_is_covered():
    functions = {n for n in B.__all__ if callable(getattr(B, n)) and n != "MentorConfidence"}
    assert functions == set(GOOD)
    assert {case[0] for case in BAD} == functions


@pytest.mark.parametrize("function", sorted(GOOD))
def test_good_shapes_pass(function):
    getattr(B, function)(**GOOD[function])


@pytest.mark.parametrize(
    ("function", "argument", "value", "named"),
    BAD,
    ids=[f"{f}-{named}-{i}" for i, (f, _, _, named) in enumerate(BAD)],
)
def test_bad_shape_is_refused_by_name(function, argument, value, named):
    kwargs = dict(GOOD[function], **{argument: value})
    with pytest.raises(ValueError, match=rf"^{function}: {named}\b") as error:
        getattr(B, function)(**kwargs)
    assert "expected" in str(error.value)


def test_a_broadcastable_tested_and_a_number_for_the_unseen_step_pass():
    """What the value cache passes: ``tested`` of the runs' shape ``[R, 1]`` against ``[R, n]``
    states, a number (or a 0-d tensor) as the unseen step's reward."""
    B.trusted_augmented_backup(
        f64(2, 3, 4),
        flags(2, 3, 4),
        f64(2, 3),
        flags(2, 3),
        confidence=MentorConfidence(f64(2, 3, 4), f64(2, 3), flags(2, 1), 1.0),
    )
    B.segment_reward(f64(3), torch.ones(3, dtype=torch.float64), -0.01, 0.9)
    B.segment_reward(f64(3), torch.ones(3, dtype=torch.float64), f64(3), 0.9)


def test_mentor_backup_edges_by_hand():
    """Two runs, mentor rows 0…2. Run 0 saw ``0 → a`` twice (r = −0.01, d = γ = 0.9,
    V(a) = 0.5) and ``0 → b`` once in 3 steps (r = −0.0271, d = 0.729, V(b) = 1); run 1 saw
    ``2 → c`` once (r = 1, d = 0.9, V(c) = 0). Run 0, row 0:
    2 (−0.01 + 0.9 · 0.5) + 1 (−0.0271 + 0.729 · 1) = 0.88 + 0.7019 = 1.5819; run 1, row 2: 1."""
    n = B.mentor_backup_edges(
        (2, 3),
        runs=torch.tensor([0, 0, 1]),
        rows=torch.tensor([0, 0, 2]),
        counts=torch.tensor([2.0, 1.0, 1.0], dtype=torch.float64),
        rewards=torch.tensor([-0.01, -0.0271, 1.0], dtype=torch.float64),
        discounts=torch.tensor([0.9, 0.729, 0.9], dtype=torch.float64),
        successor_values=torch.tensor([0.5, 1.0, 0.0], dtype=torch.float64),
    )
    torch.testing.assert_close(
        n, torch.tensor([[1.5819, 0.0, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    )
    # divided by the row's count it is the segment form of the mentor term
    term = B.segment_mentor_backup(
        torch.tensor([-0.01, -0.0271], dtype=torch.float64),
        torch.tensor([0.9, 0.729], dtype=torch.float64),
        torch.tensor([2 / 3, 1 / 3], dtype=torch.float64),
        torch.tensor([0.5, 1.0], dtype=torch.float64),
    )
    torch.testing.assert_close(n[0, 0] / 3, term)
    empty = B.mentor_backup_edges((2, 3), i64(0), i64(0), f64(0), f64(0), f64(0), f64(0))
    assert torch.equal(empty, f64(2, 3))
