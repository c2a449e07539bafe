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

Settings (the fields of the configuration dataclasses) are declared once with :func:`setting`:
type (the annotation), range, choices and doc, and whether the compiled engine reads them.
:func:`check_settings` applies the rules above to every declared field, so a configuration's
``__post_init__`` lists only its cross-field rules; the CLI's flags and the kernel's packed
settings are generated from the same declarations (:func:`settings_of`).

Sizes: before something large is allocated (a world's tables, a bundle of options, a batch of
runs) its bytes are estimated and refused up front when they exceed :func:`memory_limit` —
by default 80 % of the memory available when asked (``/proc/meminfo``'s ``MemAvailable``, or
the physical memory elsewhere); set the environment variable ``HIMIT_MEMORY_LIMIT`` (bytes, or
with a unit: ``64GiB``, ``500MB``; ``0`` or ``off`` switches the check off) to change it.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import numbers
import os
import re
import types
import typing
from typing import Any

import numpy as np

__all__ = [
    "as_int",
    "as_float",
    "as_tuple",
    "as_choice",
    "COUNT_MAX",
    "Setting",
    "setting",
    "settings_of",
    "DeclaredSetting",
    "check_settings",
    "refuse_unknown_fields",
    "memory_limit",
    "check_memory",
    "format_bytes",
]


def _is_bool(value: Any) -> bool:
    return isinstance(value, (bool, np.bool_))


def as_int(where: str, value: Any, minimum: int | None = None, maximum: int | None = None) -> int:
    """``value`` as an ``int`` by the module's rule for whole numbers, within the bounds.

    >>> as_int("steps", 1e6)
    1000000
    >>> as_int("steps", 2.7)
    Traceback (most recent call last):
    ...
    ValueError: steps=2.7 is not a whole number (it is never rounded or truncated); give an integer
    >>> as_int("seeds", True)
    Traceback (most recent call last):
    ...
    ValueError: seeds must be a whole number, got True (bool)
    """
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


# =================================================================================== settings
#: Largest whole-number setting unless a field declares its own: the product of two counts
#: (``plan_every · backups``, a sweep's budget) then still fits the engines' int64.
COUNT_MAX = 2**31 - 1

#: Key of a field's :class:`Setting` in its ``dataclasses.field`` metadata.
_SETTING_KEY = "himit_setting"


@dataclasses.dataclass(frozen=True)
class Setting:
    """What a configuration field is, beside its name, type (the annotation) and default.

    ``ge``/``gt``/``le``/``lt`` bound a number (a whole number takes ``ge``/``le`` only, and
    ``le`` defaults to :data:`COUNT_MAX`); ``choices`` are the strings a ``str`` field (or every
    item of a ``tuple[str, ...]``) may take; ``hint`` is added to a refusal (what the value
    means). ``kernel``: the compiled engine reads the field, encoded as a number — a choice as
    its index in ``choices``, ``None`` as ``kernel_none``.
    """

    doc: str
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    choices: tuple[str, ...] = ()
    hint: str = ""
    kernel: bool = False
    kernel_none: int | float | None = None


def setting(
    default: Any = dataclasses.MISSING,
    *,
    doc: str,
    default_factory: Any = dataclasses.MISSING,
    **spec: Any,
) -> Any:
    """A dataclass field declared with its :class:`Setting` (``spec``: its other fields).

    Typed ``Any`` so that ``backups: int = setting(10, …)`` reads as the field's default to a
    type checker, as ``dataclasses.field`` does."""
    info = Setting(doc=inspect.cleandoc(doc), **spec)
    return dataclasses.field(
        default=default, default_factory=default_factory, metadata={_SETTING_KEY: info}
    )


@dataclasses.dataclass(frozen=True)
class DeclaredSetting:
    """One declared field of a configuration class: its name, type, default and
    :class:`Setting`. ``kind`` is the type without ``None``: ``int``, ``float``, ``str``,
    ``bool``, ``tuple`` (of ``item``) or a dataclass; ``optional``: ``None`` is allowed."""

    name: str
    kind: Any
    item: Any
    optional: bool
    default: Any
    info: Setting


@functools.cache
def settings_of(cls: type) -> tuple[DeclaredSetting, ...]:
    """The declared fields of the dataclass ``cls``, in order (fields without a
    :class:`Setting` are left out)."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        info = f.metadata.get(_SETTING_KEY)
        if info is None:
            continue
        kind, optional = hints[f.name], False
        if isinstance(kind, types.UnionType) or typing.get_origin(kind) is typing.Union:
            members = [a for a in typing.get_args(kind) if a is not type(None)]
            if len(members) != 1:
                raise TypeError(f"{cls.__name__}.{f.name}: only `X | None` unions are settings")
            kind, optional = members[0], True
        item = None
        if typing.get_origin(kind) is tuple:
            item, kind = typing.get_args(kind)[0], tuple
        if kind is int and (info.gt is not None or info.lt is not None):
            raise TypeError(f"{cls.__name__}.{f.name}: a whole number is bounded by ge/le")
        if info.kernel and optional and info.kernel_none is None:
            raise TypeError(f"{cls.__name__}.{f.name}: a kernel setting needs kernel_none")
        default = f.default_factory() if callable(f.default_factory) else f.default
        out.append(DeclaredSetting(f.name, kind, item, optional, default, info))
    return tuple(out)


def _convert(where: str, value: Any, kind: Any, info: Setting) -> Any:
    """``value`` of one field (or one tuple item) by the module's rules."""
    if kind is bool:
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"{where} must be true or false, got {value!r}")
        return bool(value)
    if kind is int:
        maximum = COUNT_MAX if info.le is None else int(info.le)
        minimum = None if info.ge is None else int(info.ge)
        return as_int(where, value, minimum, maximum)
    if kind is float:
        low = info.gt if info.gt is not None else info.ge
        high = info.lt if info.lt is not None else info.le
        return as_float(where, value, low, high, info.gt is not None, info.lt is not None)
    if kind is str:
        if info.choices:
            return as_choice(where, value, info.choices)
        if not isinstance(value, str) or not value:
            raise ValueError(f"{where} must be a non-empty string, got {value!r}")
        return value
    raise TypeError(f"{where}: no input rule for {kind!r}")  # pragma: no cover (declaration bug)


def _is_config_class(kind: Any) -> bool:
    """A dataclass type (a nested configuration), as a plain bool (no type narrowing)."""
    return isinstance(kind, type) and dataclasses.is_dataclass(kind)


def check_settings(config: Any) -> None:
    """Convert and check every declared field of the dataclass instance ``config`` in place (the
    rules of this module, the declared ranges and choices); a refusal names
    ``ClassName.field``. Cross-field rules stay with the class."""
    cls: type = type(config)
    for s in settings_of(cls):
        where = f"{cls.__name__}.{s.name}"
        value = getattr(config, s.name)
        try:
            if value is None and s.optional:
                continue
            if _is_config_class(s.kind):
                if isinstance(value, dict):
                    refuse_unknown_fields(value, s.kind, where)
                    value = s.kind(**value)
                elif not isinstance(value, s.kind):
                    raise ValueError(
                        f"{where} must be a {s.kind.__name__} or a dict, got {type(value).__name__}"
                    )
            elif s.kind is tuple:
                items = as_tuple(where, value)
                value = tuple(
                    _convert(f"{where}[{i}]", v, s.item, s.info) for i, v in enumerate(items)
                )
                if not value:
                    raise ValueError(f"{where}=(): needs at least one item")
            else:
                value = _convert(where, value, s.kind, s.info)
        except ValueError as err:
            if s.info.hint:
                raise ValueError(f"{err} ({s.info.hint})") from None
            raise
        setattr(config, s.name, value)


def refuse_unknown_fields(data: dict, cls: type, where: str) -> None:
    """Refuse keys of ``data`` that are not fields of the dataclass ``cls``."""
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"{where}: unknown fields {unknown}; known: {sorted(known)}")


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
