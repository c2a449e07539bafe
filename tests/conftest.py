"""Shared test set-up: one torch thread (tiny tensors; two threads only add contention on a busy
2-core machine) and a seeded generator fixture."""
import pytest
import torch

from himit_torch.world import MultiRooms

torch.set_num_threads(1)


@pytest.fixture
def generator() -> torch.Generator:
    return torch.Generator().manual_seed(1234)


@pytest.fixture(scope="module")
def world8() -> MultiRooms:
    """8×8 world, 2×2 rooms: small enough for learning tests that must finish in seconds."""
    return MultiRooms(8, 2)
