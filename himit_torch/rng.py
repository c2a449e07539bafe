"""Counter-based random numbers: one independent stream per run, whatever the batch.

A batch of runs drawing from one ``torch.Generator`` would give run ``b`` different numbers in a
batch of 15 than alone. Here each number is a hash (SplitMix64, Steele et al. 2014) of
``(run seed, step counter, lane)``, so run ``b``'s stream depends only on its own seed — the
property behind "run b inside a batch is identical to the same run alone" — and is the same on
every device.
"""

from __future__ import annotations

import torch

__all__ = ["splitmix64", "uniforms", "seed_streams"]

_GOLDEN = 0x9E3779B97F4A7C15 - (1 << 64)
_MUL1 = 0xBF58476D1CE4E5B9 - (1 << 64)
_MUL2 = 0x94D049BB133111EB - (1 << 64)
_TWO_POW_MINUS_53 = 1.0 / (1 << 53)


def _shr(x: torch.Tensor, k: int) -> torch.Tensor:
    """Logical right shift of int64 (torch's ``>>`` is arithmetic)."""
    return (x >> k) & ((1 << (64 - k)) - 1)


def splitmix64(x: torch.Tensor) -> torch.Tensor:
    """The SplitMix64 finaliser on int64 tensors (wrapping arithmetic)."""
    z = x + _GOLDEN
    z = (z ^ _shr(z, 30)) * _MUL1
    z = (z ^ _shr(z, 27)) * _MUL2
    return z ^ _shr(z, 31)


def seed_streams(seeds: torch.Tensor) -> torch.Tensor:
    """Scramble user seeds ``[B]`` into stream keys so that nearby seeds give unrelated streams."""
    return splitmix64(splitmix64(seeds.to(torch.int64)))


def uniforms(
    keys: torch.Tensor, counter: int | torch.Tensor, lanes: int, dtype=torch.float64
) -> torch.Tensor:
    """Uniforms in [0, 1) for draw number ``counter`` of each run's stream.

    Args:
        keys: ``[B]`` int64 stream keys from :func:`seed_streams`.
        counter: which draw (e.g. the step number), an int → ``[B, lanes]``, or ``[C]`` int64
            draws at once → ``[C, B, lanes]`` (the same numbers as ``C`` separate calls).
        lanes: how many numbers per run and draw (at most 1024).
    """
    if lanes > 1024:
        raise ValueError(f"lanes={lanes}: at most 1024 numbers per draw")
    lane = torch.arange(lanes, device=keys.device, dtype=torch.int64)
    counter = torch.as_tensor(counter, device=keys.device, dtype=torch.int64)
    salt = splitmix64(counter[..., None] * 1024 + lane)  # [..., lanes]
    x = keys[:, None] ^ salt[..., None, :]  # [..., B, lanes]
    bits = _shr(splitmix64(x), 11)
    return (bits.to(torch.float64) * _TWO_POW_MINUS_53).to(dtype)
