"""The counter-based random streams, as :func:`himit_torch.rng.uniforms` draws them."""

from __future__ import annotations

import numpy as np
from numba import njit

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MUL1 = np.uint64(0xBF58476D1CE4E5B9)
_MUL2 = np.uint64(0x94D049BB133111EB)
_TWO_POW_MINUS_53 = 1.0 / 9007199254740992.0


@njit(inline="always")
def splitmix(x):
    """SplitMix64's finaliser (:func:`himit_torch.rng.splitmix64`)."""
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MUL1
    z = (z ^ (z >> np.uint64(27))) * _MUL2
    return z ^ (z >> np.uint64(31))


@njit(inline="always")
def uniform(key, counter, lane):
    """Lane ``lane`` of draw ``counter`` of the stream ``key`` (:func:`himit_torch.rng.uniforms`)."""
    salt = splitmix(np.uint64(counter * 1024 + lane))
    return np.float64(splitmix(key ^ salt) >> np.uint64(11)) * _TWO_POW_MINUS_53
