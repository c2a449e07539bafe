"""Checks of user input shared by the worlds, options, learner and configurations.

Conversion rules (the same everywhere a number is read):

* **whole numbers** (sizes, counts, steps, seeds, cell coordinates): a Python or NumPy integer;
  a float is accepted only when it is a whole number (``1e6`` from a JSON file becomes
  ``1000000``) — ``2.7`` is refused, never truncated. ``bool`` and strings are refused.
* **real numbers** (probabilities, rewards, concentrations): a Python or NumPy integer or float,
  converted with ``float``; it must be finite. ``bool`` and strings (``"0.1"``) are refused.
* **sequences** where a tuple is expected (agents, sizes, a ``(row, col)`` cell): a list or a
  tuple is accepted and stored as a tuple; a bare string is refused (it would be read as its
  characters).

Every refusal is a ``ValueError`` naming the field and what would be right.

Sizes: before something large is allocated (a world's tables, a bundle of options, a batch of
runs) its bytes are estimated and refused up front when they exceed :func:`memory_limit` —
by default 80 % of the memory available when asked (``/proc/meminfo``'s ``MemAvailable``, or
the physical memory elsewhere); set the environment variable ``HIMIT_MEMORY_LIMIT`` (bytes, or
with a unit: ``64GiB``, ``500MB``; ``0`` or ``off`` switches the check off) to change it.
"""

from __future__ import annotations

import math
import numbers
import os
import re
from typing import Any

import numpy as np

__all__ = [
    "as_int",
    "as_float",
    "as_tuple",
    "as_choice",
    "memory_limit",
    "check_memory",
    "format_bytes",
]


def _is_bool(value: Any) -> bool:
    return isinstance(value, (bool, np.bool_))


def as_int(where: str, value: Any, minimum: int | None = None, maximum: int | None = None) -> int:
    """``value`` as an ``int`` by the module's rule for whole numbers, within the bounds."""
    if _is_bool(value) or isinstance(value, (str, bytes)):
        raise ValueError(f"{where} must be a whole number, got {value!r} ({type(value).__name__})")
    if isinstance(value, numbers.Integral):
        out = int(value)
    elif isinstance(value, numbers.Real):
        f = float(value)
        if not math.isfinite(f):
            raise ValueError(f"{where} must be a whole number, got {value!r}")
        if f != int(f):
            raise ValueError(
                f"{where}={value!r} is not a whole number (it is never rounded or "
                "truncated); give an integer"
            )
        out = int(f)
    else:
        raise ValueError(f"{where} must be a whole number, got {value!r} ({type(value).__name__})")
    if minimum is not None and out < minimum:
        raise ValueError(f"{where}={out} must be ≥ {minimum}")
    if maximum is not None and out > maximum:
        raise ValueError(f"{where}={out} must be ≤ {maximum}")
    return out


def as_float(
    where: str,
    value: Any,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a finite ``float`` by the module's rule for real numbers, within
    ``[low, high]`` (``low_open`` / ``high_open``: excluding that end)."""
    if _is_bool(value) or isinstance(value, (str, bytes)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{where} must be a number, got {value!r} ({type(value).__name__})")
    out = float(value)
    if not math.isfinite(out):
        raise ValueError(f"{where}={value!r} must be a finite number")
    too_low = low is not None and (out < low or (low_open and out == low))
    too_high = high is not None and (out > high or (high_open and out == high))
    if too_low or too_high:
        if low is not None and high is not None:
            span = f"lie in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        elif low is not None:
            span = f"be {'>' if low_open else '≥'} {low:g}"
        else:
            span = f"be {'<' if high_open else '≤'} {high:g}"
        raise ValueError(f"{where}={out!r} must {span}")
    return out


def as_tuple(where: str, value: Any) -> tuple:
    """A list or tuple as a tuple; anything else (a string, a number, a set) is refused."""
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{where} must be a list or tuple, got {value!r} ({type(value).__name__})")
    return tuple(value)


def as_choice(where: str, value: Any, choices: tuple[str, ...]) -> str:
    """One of the strings ``choices``."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{where}={value!r}: use one of {list(choices)}")
    return value


# ===================================================================================== memory
_UNITS = {
    "": 1,
    "b": 1,
    "kb": 10**3,
    "mb": 10**6,
    "gb": 10**9,
    "tb": 10**12,
    "kib": 2**10,
    "mib": 2**20,
    "gib": 2**30,
    "tib": 2**40,
}


def _available_bytes() -> int:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 1 << 62  # unknown: no limit


def memory_limit() -> int | None:
    """Bytes one structure may take (``None``: no check): ``HIMIT_MEMORY_LIMIT`` if set, else
    80 % of the memory available now."""
    text = os.environ.get("HIMIT_MEMORY_LIMIT", "").strip().lower()
    if not text:
        return int(0.8 * _available_bytes())
    if text in ("0", "off", "none"):
        return None
    m = re.fullmatch(r"([0-9]*\.?[0-9]+(?:e[0-9]+)?)\s*([a-z]*)", text)
    if m is None or m.group(2) not in _UNITS:
        raise ValueError(f"HIMIT_MEMORY_LIMIT={text!r}: give bytes, e.g. 8GiB, 500MB or 0 (off)")
    return int(float(m.group(1)) * _UNITS[m.group(2)])


def format_bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.1f} PiB"  # pragma: no cover


def check_memory(what: str, estimate: float, hint: str = "") -> None:
    """Refuse building ``what`` when its estimated bytes exceed :func:`memory_limit`."""
    limit = memory_limit()
    if limit is not None and estimate > limit:
        raise ValueError(
            f"{what} would need about {format_bytes(estimate)}, more than the limit "
            f"{format_bytes(limit)} (80 % of available memory, or "
            f"HIMIT_MEMORY_LIMIT){'; ' + hint if hint else ''}"
        )
