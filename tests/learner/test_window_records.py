"""The per-window records' two derived numbers, by hand: the mentor term's win share (from the
compiled engine's counts) and the mean episode length (NaN where no episode ended)."""

import math

import numpy as np
import torch

from himit_torch.learner.inspect import mentor_win_share_of
from himit_torch.learner.run_state import mean_episode_steps


def test_mentor_win_share_by_hand():
    wins, seen = np.array([2, 0, 3]), np.array([4, 0, 3])
    share = mentor_win_share_of(wins, seen, np.array([True, True, False]))
    # 2/4; a run that saw no mentor state while another did: 0/1; no mentor term: NaN
    assert share[0] == 0.5 and share[1] == 0.0 and math.isnan(share[2])
    # a record in which no run has seen a mentor: NaN for all (here the first of two windows)
    both = mentor_win_share_of(
        np.array([[0, 0], [1, 0]]), np.array([[0, 0], [2, 1]]), np.array([True, True])
    )
    assert np.isnan(both[0]).all() and both[1].tolist() == [0.5, 0.0]


def test_mean_episode_steps_by_hand():
    out = mean_episode_steps(torch.tensor([30, 0, 7]), torch.tensor([3, 0, 2]))
    assert out.dtype == torch.float64
    assert out[0] == 10.0 and math.isnan(out[1]) and out[2] == 3.5
