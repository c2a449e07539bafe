"""Shared test set-up: one torch thread (tiny tensors; two threads only add contention on a busy
2-core machine) and a seeded generator fixture."""
import pytest
import torch

torch.set_num_threads(1)


@pytest.fixture
def generator() -> torch.Generator:
    return torch.Generator().manual_seed(1234)
