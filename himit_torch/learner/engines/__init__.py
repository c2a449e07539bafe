"""Engines that carry out a learner's ticks on its state.

* :class:`TorchEngine` — batched tensor ops on any device: the readable reference, and the path
  for GPUs.
* :class:`NumbaEngine` — a compiled per-run loop (the runs on parallel threads), working in
  place on the same tensors' memory: the fast path on a CPU.

Both carry out the same algorithm on the same state, draw the same random numbers, and are
tested to make the same decisions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from himit_torch.learner.engines.torch_engine import TorchEngine

if TYPE_CHECKING:
    from himit_torch.learner.state import BatchState

__all__ = ["TorchEngine", "NumbaEngine", "numba_available", "make_engine", "ENGINES"]

ENGINES = ("auto", "numba", "torch")


def numba_available() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def __getattr__(name):
    if name == "NumbaEngine":
        from himit_torch.learner.engines.numba_engine import NumbaEngine

        return NumbaEngine
    raise AttributeError(name)


def make_engine(name: str, state: BatchState):
    """The engine ``name`` (``"auto"``, ``"numba"`` or ``"torch"``) for a batch's ``state``.

    ``"auto"`` picks the compiled engine on a CPU when Numba is installed and the world has a
    ``dynamics_table()``, the torch engine otherwise.
    """
    if name not in ENGINES:
        raise ValueError(f"engine={name!r}: use one of {ENGINES}")
    why_not = _numba_unusable(state)
    if name == "auto":
        name = "torch" if why_not else "numba"
    if name == "numba":
        if why_not:
            raise ValueError(
                f"engine='numba' cannot run this learner: {why_not}; use engine='torch'"
            )
        from himit_torch.learner.engines.numba_engine import NumbaEngine

        return NumbaEngine(state)
    return TorchEngine(state)


def _numba_unusable(state: BatchState) -> str | None:
    if state.device.type != "cpu":
        return f"it runs on the CPU only (this learner is on {state.device})"
    if state.tables.dynamics is None:
        return (
            "the world has no dynamics_table() (a DynamicsTable of successors, cdf and "
            "rewards); the compiled loop cannot call a Python step()"
        )
    if not numba_available():
        return "numba is not installed (pip install numba)"
    return None
