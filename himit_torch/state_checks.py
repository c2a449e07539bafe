"""Checks of state read back from a file, before anything computes with it.

A checkpoint's checksum proves only that the file is the one its header describes; anyone can
write a file and a checksum to match. So every owner of learner state checks what its
``load_state_dict`` is given — each tensor's type, dtype and shape, and the ranges its invariants
need (indices within their tables, counts within their capacities) — and refuses anything else
with :class:`DamagedState`, naming the field. The compiled engine indexes memory with these
values unchecked; it must never see one that this code could not have written.

The checks are whole-tensor reductions (one pass each), never Python loops over elements: a
resume spends far longer reading the file than checking it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import torch

__all__ = [
    "DamagedState",
    "section",
    "whole",
    "tensor",
    "tensor_of",
    "in_range",
    "all_finite",
    "same_plain",
    "private_copy",
    "saved",
]


class DamagedState(ValueError):
    """State read back from a file is not one this code could have written (a field missing, of
    another type, dtype or shape, or a value outside what its invariants allow).

    ``field`` names the piece (``model.edge_successor``), ``problem`` says what is wrong with it.
    :class:`~himit_torch.runs.checkpoints.DamagedCheckpoint` is one (the field being the file):
    a resume treats both alike, falling back to the previous checkpoint generation."""

    def __init__(self, field: str, problem: str):
        super().__init__(f"{field}: {problem}")
        self.field, self.problem = field, problem


def section(state: Any, where: str, keys: Iterable[str], optional: Iterable[str] = ()) -> dict:
    """``state`` itself, checked to be a dict holding exactly ``keys`` (plus any of
    ``optional``)."""
    if not isinstance(state, dict):
        raise DamagedState(where, f"is a {type(state).__name__}, not a dict of state")
    keys, optional = set(keys), set(optional)
    missing = sorted(keys - set(state))
    extra = sorted(map(str, set(state) - keys - optional))
    if missing or extra:
        problems = [f"lacks {missing}" if missing else "", f"has unknown {extra}" if extra else ""]
        raise DamagedState(where, " and ".join(p for p in problems if p))
    return state


def whole(state: Mapping, key: str, where: str, minimum: int, maximum: int) -> int:
    """``state[key]``, checked to be a Python ``int`` (not a ``bool``) in ``minimum … maximum``."""
    value = state[key]
    if type(value) is not int:
        raise DamagedState(f"{where}.{key}", f"is a {type(value).__name__}, not a whole number")
    if not minimum <= value <= maximum:
        raise DamagedState(f"{where}.{key}", f"{value} lies outside {minimum}…{maximum}")
    return value


def tensor(
    state: Mapping, key: Any, where: str, dtype: torch.dtype, shape: tuple[int | None, ...]
) -> torch.Tensor:
    """``state[key]``, checked by :func:`tensor_of` (named ``where.key``)."""
    return tensor_of(state[key], f"{where}.{key}", dtype, shape)


def tensor_of(
    value: Any, field: str, dtype: torch.dtype, shape: tuple[int | None, ...]
) -> torch.Tensor:
    """``value``, checked to be a plain dense tensor of ``dtype`` and ``shape`` (``None``: any
    length along that axis)."""
    if type(value) is not torch.Tensor:
        raise DamagedState(field, f"is a {type(value).__qualname__}, not a tensor")
    if value.dtype != dtype:
        raise DamagedState(field, f"has dtype {value.dtype}, not {dtype}")
    if value.layout != torch.strided:
        raise DamagedState(field, f"is a {value.layout} tensor, not a dense one")
    if value.dim() != len(shape) or any(
        n is not None and n != m for n, m in zip(shape, value.shape)
    ):
        want = ", ".join("any" if n is None else str(n) for n in shape)
        raise DamagedState(field, f"has shape {list(value.shape)}, not [{want}]")
    return value


def in_range(
    value: torch.Tensor,
    field: str,
    low: float,
    high: float,
    meaning: str,
    where: torch.Tensor | None = None,
) -> None:
    """Every entry of ``value`` (where ``where``, if given) lies in ``low … high`` (NaN never
    does); otherwise :class:`DamagedState` naming the first entry outside, its index and
    ``meaning`` (what the range is).

    The check is the lowest and the highest entry (NaN propagates into both); the entry at
    fault is looked for only once it has failed."""
    bounds = _bounds(value, where)
    if bounds is None or (bounds[0] >= low and bounds[1] <= high):
        return
    bad = ~((value >= low) & (value <= high))
    if where is not None:
        bad &= where
    index = [int(i) for i in bad.nonzero()[0]]
    count = int(bad.sum())
    raise DamagedState(
        field,
        f"{value[tuple(index)].item()} at index {index} lies outside {low}…{high} "
        f"({meaning}; {count} entr{'y' if count == 1 else 'ies'} outside)",
    )


def _bounds(value: torch.Tensor, where: torch.Tensor | None) -> tuple[Any, Any] | None:
    """The lowest and the highest entry of ``value`` where ``where`` (NaN if one is NaN), or
    ``None`` if there is none. On a CPU by NumPy: one SIMD pass each, where torch's reductions
    can take tens of milliseconds whatever the size (waiting on their thread pool, measured in a
    process that has run the compiled engine)."""
    if value.device.type == "cpu":
        a = value.detach().resolve_neg().resolve_conj().numpy()
        if where is not None:
            a = a[where.numpy()]
        return (a.min(), a.max()) if a.size else None
    if where is not None:
        value = value[where]
    if value.numel() == 0:
        return None
    lo, hi = torch.aminmax(value)
    return lo.item(), hi.item()


_LARGEST = float(np.finfo(np.float64).max)


def all_finite(value: torch.Tensor, field: str, minimum: float = -_LARGEST) -> None:
    """Every entry of the float tensor ``value`` is finite and at least ``minimum``."""
    meaning = "a finite number" if minimum == -_LARGEST else f"a finite number ≥ {minimum}"
    in_range(value, field, minimum, _LARGEST, meaning)


def same_plain(a: Any, b: Any) -> bool:
    """Whether two plain values (``bool``/``int``/``float``/``str``/``None`` in lists, tuples and
    dicts) are equal, types included — ``True`` is not ``1``; a tensor, which ``==`` would
    compare elementwise, is never equal to a plain value."""
    if type(a) is not type(b):
        return False
    if type(a) in (list, tuple):
        return len(a) == len(b) and all(same_plain(x, y) for x, y in zip(a, b))
    if type(a) is dict:
        return a.keys() == b.keys() and all(same_plain(a[k], b[k]) for k in a)
    if type(a) in (bool, int, float, str, type(None)):
        return a == b
    return False


def saved(tensors: Mapping[str, torch.Tensor], copy: bool) -> dict[str, torch.Tensor]:
    """What an owner's ``state_dict`` returns of its ``tensors``: copies, or with ``copy=False``
    the tensors themselves (its live tensors and views of them), for a writer that stores them
    before the owner changes again (:meth:`~himit_torch.Learner.state_dict`)."""
    return {name: t.clone() if copy else t for name, t in tensors.items()}


def private_copy(value: torch.Tensor, device: torch.device) -> torch.Tensor:
    """A contiguous copy of a checked tensor on ``device``, sharing memory with nothing and
    tracking no gradient (what the engines, which work in place on it, need). CPU to CPU by
    NumPy (see ``_bounds``: ≈ 10× faster than torch's copy in such a process)."""
    value = value.detach().resolve_neg().resolve_conj()
    if value.device.type == "cpu" and torch.device(device).type == "cpu":
        return torch.from_numpy(np.array(value.numpy(), order="C", copy=True))
    return torch.empty(value.shape, dtype=value.dtype, device=device).copy_(value)
