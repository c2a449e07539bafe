"""Checks of user input shared by the worlds, options, learner and configurations.

Conversion rules (the same everywhere a number is read):

* **whole numbers** (sizes, counts, steps, seeds, cell coordinates): a Python or NumPy integer;
  a float is accepted only when it is a whole number (``1e6`` from a JSON file becomes
  ``1000000``) — ``2.7`` is refused, never truncated. ``bool`` and strings are refused.
* **real numbers** (probabilities, rewards, concentrations): a Python or NumPy integer or float,
  converted with ``float``; it must be finite. ``bool`` and strings (``"0.1"``) are refused.
* **sequences** where a tuple is expected (agents, sizes, a ``(row, col)`` cell): a list or a
  tuple is accepted and stored as a tuple; a bare string is refused (it would be read as its
  characters). Where many whole numbers are expected (states, run indices, seeds:
  :func:`as_int_array`), any 1-D sequence, NumPy array or tensor is accepted, each item by the
  rule for whole numbers (a bool array, a ``NaN`` or ``6.5`` is refused, never cast).
* **devices** (:func:`as_device`): ``cpu`` or ``cuda[:N]``; where something will run on it, only
  a device this machine has (``meta``, ``mps``, ``cuda`` without CUDA are refused naming the
  devices that would work).
* **names that become folders** (:func:`as_folder_name`: a run's or a sweep's name): letters,
  digits, ``_``, ``.``, ``-``, starting with a letter or digit — so never ``.``, ``..`` or a
  path, and what is written under it stays inside its parent folder.
* **files** (:func:`read_text`, :func:`parse_document`): a missing file or a directory given for
  a file is a user mistake (``ValueError``); any other ``OSError`` (permissions, a full disk, a
  failing device) is left to propagate as what it is. JSON and TOML nested deeper than
  :data:`NESTING_MAX` are refused before the parser (which recurses) meets them.

Every refusal is a ``ValueError`` naming the field and what would be right. (A ``TypeError`` is
kept for an argument that is not the kind of object at all, where no conversion rule applies —
a number passed as demonstrations or as a world; those never come from a file or the CLI.)

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
import json
import math
import numbers
import os
import re
import types
import typing
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = [
    "as_int",
    "as_float",
    "as_tuple",
    "as_choice",
    "as_int_array",
    "as_float_array",
    "as_index_tensor",
    "bool_vector",
    "as_device",
    "DEVICE_TYPES",
    "usable_devices",
    "as_folder_name",
    "check_folder_path",
    "read_text",
    "parse_document",
    "nesting_depth",
    "json_depth",
    "NESTING_MAX",
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


#: Largest whole-number setting unless a field declares its own: the product of two counts
#: (``plan_every · backups``, a sweep's budget) then still fits the engines' int64.
COUNT_MAX = 2**31 - 1


def as_int_array(
    where: str, value: Any, minimum: int | None = None, maximum: int | None = None
) -> np.ndarray:
    """A 1-D sequence of whole numbers (a list, tuple, range, NumPy array or tensor) as an int64
    array, every item by :func:`as_int`'s rule and within the bounds; a refusal names the first
    bad item (``where[i]``). A string, a mapping, a set or a scalar is refused."""
    if isinstance(value, (str, bytes, dict, set, frozenset)) or not isinstance(
        value, (Iterable, np.ndarray, torch.Tensor)
    ):
        raise ValueError(
            f"{where} must be a list of whole numbers, got {value!r} ({type(value).__name__})"
        )
    if isinstance(value, (np.ndarray, torch.Tensor)):
        a = value.detach().cpu().numpy() if isinstance(value, torch.Tensor) else value
        if a.ndim != 1:
            raise ValueError(f"{where} must be 1-D, got shape {tuple(a.shape)}")
        if a.dtype.kind == "f":
            bad = np.flatnonzero(~np.isfinite(a) | (a != np.round(a)))
            if bad.size:  # the item's own refusal, by the scalar rule
                as_int(f"{where}[{int(bad[0])}]", a[bad[0]].item())
        elif a.dtype.kind not in "iu":
            raise ValueError(
                f"{where} must hold whole numbers, got dtype {a.dtype} (bools and strings are "
                "never numbers)"
            )
        if a.dtype.kind in "fu" and a.size and float(np.abs(a).max()) >= 2**63:
            raise ValueError(f"{where} holds numbers beyond int64")
        out = a.astype(np.int64)
    else:
        items = [as_int(f"{where}[{i}]", v) for i, v in enumerate(value)]
        if items and (min(items) < -(2**63) or max(items) >= 2**63):
            raise ValueError(f"{where} holds numbers beyond int64")
        out = np.array(items, dtype=np.int64)
    for bound, outside, sign in (
        (minimum, None if minimum is None else out < minimum, "≥"),
        (maximum, None if maximum is None else out > maximum, "≤"),
    ):
        if outside is not None and outside.any():
            i = int(np.flatnonzero(outside)[0])
            raise ValueError(f"{where}[{i}]={int(out[i])} must be {sign} {bound}")
    return out


def as_float_array(where: str, value: Any) -> np.ndarray:
    """A 1-D sequence of real numbers (a list, tuple, NumPy array or tensor) as a float64 array,
    every item by :func:`as_float`'s rule (finite; bools and strings refused); a refusal names
    the first bad item (``where[i]``)."""
    if isinstance(value, (np.ndarray, torch.Tensor)):
        a = value.detach().cpu().numpy() if isinstance(value, torch.Tensor) else value
        if a.ndim != 1:
            raise ValueError(f"{where} must be 1-D, got shape {tuple(a.shape)}")
        if a.dtype.kind not in "iuf":
            raise ValueError(
                f"{where} must hold real numbers, got dtype {a.dtype} (bools and strings are "
                "never numbers)"
            )
        out = a.astype(np.float64)
        bad = np.flatnonzero(~np.isfinite(out))
        if bad.size:
            raise ValueError(f"{where}[{int(bad[0])}]={out[bad[0]]!r} must be a finite number")
        return out
    if isinstance(value, (str, bytes, dict, set, frozenset)) or not isinstance(value, Iterable):
        raise ValueError(
            f"{where} must be a list of numbers, got {value!r} ({type(value).__name__})"
        )
    return np.array([as_float(f"{where}[{i}]", v) for i, v in enumerate(value)], dtype=np.float64)


def as_index_tensor(
    where: str,
    value: Any,
    minimum: int | None = None,
    maximum: int | None = None,
    dim: int | None = None,
) -> torch.Tensor:
    """Whole numbers (state indices, option numbers, step counts) as an int64 tensor, by
    :func:`as_int`'s rule item by item: a tensor or NumPy array of any shape (``dim``: of
    exactly that many axes) keeps its shape (and a tensor its device); a whole number becomes a
    0-d tensor and a list, tuple or range a 1-D one (:func:`as_int_array`). A float item must be
    a finite whole number (``9.0`` is 9; ``9.5`` and ``NaN`` are refused, never truncated);
    bools, complex numbers and strings are refused, and so is anything that holds no numbers
    (``None``, a dict, a path). A refusal is a ``ValueError`` naming ``where``, the first item
    at fault (its index) and what would be right.

    One pass over the values (their lowest and highest), never a Python loop over a tensor.

    >>> as_index_tensor("states", [0, 3.0, 7]).tolist()
    [0, 3, 7]
    >>> as_index_tensor("states", [0, 9.5])
    Traceback (most recent call last):
    ...
    ValueError: states[1]=9.5 is not a whole number (it is never rounded or truncated); give an integer
    """
    if isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        value = torch.from_numpy(value)
    if isinstance(value, torch.Tensor):
        if value.dtype == torch.bool or value.dtype.is_complex:
            raise ValueError(
                f"{where} must hold whole numbers, got a {value.dtype} tensor (bools are masks "
                "and complex numbers never indices); give an integer tensor"
            )
        if value.dtype.is_floating_point:
            finite = torch.isfinite(value)
            whole = finite & (value == torch.round(value))
            if not bool(whole.all()):
                index = [int(i) for i in (~whole).nonzero()[0]]
                item = value[tuple(index)].item()
                shown = f"{where}[{', '.join(map(str, index))}]"
                as_int(shown, item)  # the scalar rule's own refusal
            if value.numel() and float(value.abs().max()) >= 2**63:
                raise ValueError(f"{where} holds numbers beyond int64")
        out = value.detach().to(torch.int64)
    elif isinstance(value, np.ndarray):
        raise ValueError(
            f"{where} must hold whole numbers, got an array of dtype {value.dtype} (bools are "
            "masks; strings and objects are never numbers)"
        )
    elif isinstance(value, (numbers.Number, str, bytes, np.generic)) or value is None:
        out = torch.tensor(as_int(where, value), dtype=torch.int64)
    else:
        out = torch.from_numpy(as_int_array(where, value))
    if dim is not None and out.dim() != dim:
        axes = "a single number" if dim == 0 else f"{dim}-D"
        raise ValueError(f"{where} must be {axes}, got shape {list(out.shape)}")
    if out.numel() and (minimum is not None or maximum is not None):
        low, high = torch.aminmax(out)
        for bound, bad, sign in (
            (minimum, minimum is not None and int(low) < minimum, "≥"),
            (maximum, maximum is not None and int(high) > maximum, "≤"),
        ):
            if bad:
                outside = out < bound if sign == "≥" else out > bound  # type: ignore[operator]
                index = [int(i) for i in outside.nonzero()[0]] if out.dim() else []
                shown = f"{where}[{', '.join(map(str, index))}]" if index else where
                raise ValueError(
                    f"{shown}={int(out[tuple(index)])} must be {sign} {bound}"
                    + ("" if minimum is None or maximum is None else f" ({minimum} … {maximum})")
                )
    return out


def bool_vector(value: Any) -> torch.Tensor | None:
    """``value`` as a 1-D bool tensor if it is one — a bool tensor or array, or a list or tuple
    of bools — else ``None`` (0/1 numbers are not read as bools: a list of state indices is not
    a mask)."""
    if isinstance(value, (list, tuple)) and all(_is_bool(v) for v in value):
        return torch.tensor([bool(v) for v in value], dtype=torch.bool)
    if isinstance(value, np.ndarray) and value.dtype == np.bool_ and value.ndim == 1:
        return torch.from_numpy(value.copy())
    if isinstance(value, torch.Tensor) and value.dtype == torch.bool and value.dim() == 1:
        return value.detach().cpu().clone()
    return None


# ==================================================================================== devices
#: Device types the learner runs on (float64 tables everywhere: Apple's ``mps`` has no float64,
#: ``meta`` tensors hold no values).
DEVICE_TYPES = ("cpu", "cuda")


def usable_devices() -> list[str]:
    """The devices this machine can run the learner on: ``cpu``, and ``cuda``, ``cuda:0`` … when
    torch sees CUDA devices."""
    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    return ["cpu"] + (["cuda"] + [f"cuda:{i}" for i in range(count)] if count else [])


def as_device(where: str, value: Any, available: bool = True) -> torch.device:
    """``value`` (a string or ``torch.device``) as a device of :data:`DEVICE_TYPES`; with
    ``available`` (where something will run) also one this machine has. A configuration that is
    only written down (``ExperimentConfig``) checks ``available=False``: it may name ``cuda`` on
    a machine without, and is refused when it runs there."""
    if isinstance(value, torch.device):
        device = value
    elif isinstance(value, str) and value:
        try:
            device = torch.device(value)
        except RuntimeError:
            raise ValueError(
                f"{where}={value!r} is not a torch device; use one of {usable_devices()}"
            ) from None
    else:
        raise ValueError(
            f"{where} must be a device name such as 'cpu' or 'cuda', got {value!r} "
            f"({type(value).__name__}); use one of {usable_devices()}"
        )
    if device.type not in DEVICE_TYPES:
        raise ValueError(
            f"{where}={value!r}: the learner runs on {' or '.join(DEVICE_TYPES)} devices only; "
            f"use one of {usable_devices()}"
        )
    if available and device.type == "cuda":
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if count == 0:
            raise ValueError(
                f"{where}={value!r}: no CUDA device is available here (a CUDA build of torch "
                f"and a GPU are needed, see README); use one of {usable_devices()}"
            )
        if device.index is not None and device.index >= count:
            raise ValueError(
                f"{where}={value!r}: this machine has {count} CUDA device(s); use one of "
                f"{usable_devices()}"
            )
    return device


# ================================================================================ names, files
_FOLDER_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}")


def as_folder_name(where: str, value: Any) -> str:
    """A name that becomes a folder under another (a run's, a sweep's): 1–100 letters, digits,
    ``_``, ``.``, ``-``, starting with a letter or digit — never ``.``, ``..``, a path or a hidden
    folder, so that what is written under it stays inside its parent."""
    if not isinstance(value, str) or not _FOLDER_NAME.fullmatch(value):
        raise ValueError(
            f"{where}={value!r} must be a folder name: 1–100 letters, digits, '_', '.', '-', "
            "starting with a letter or digit (no '/', not '.' or '..')"
        )
    return value


def check_folder_path(where: str, path: str | os.PathLike) -> Path:
    """``path``, where a folder is to be (a run directory, a sweep's, a demo's output): refused
    with a ``ValueError`` naming ``where`` when it, or a folder above it, is a file (the user's
    mistake, said before anything is written). It need not exist yet."""
    path = Path(path)
    for part in (path, *path.parents):
        if part.exists() and not part.is_dir():
            what = "is a file" if part == path else f"is under {part}, which is a file"
            raise ValueError(f"{where} {path} {what}, not a folder; choose another path")
    return path


def read_text(where: str, path: str | os.PathLike) -> str:
    """The UTF-8 text of the file ``path`` that a user named. A path that names no file (missing,
    a directory, or under something that is not a directory) and a file that is not UTF-8 text
    are the user's mistake: ``ValueError`` naming ``where``. Other ``OSError`` exceptions (permissions,
    a failing disk) propagate unchanged: the file is the right one, the machine failed."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{where} does not exist") from None
    except IsADirectoryError:
        raise ValueError(f"{where} is a directory; give the file itself") from None
    except NotADirectoryError:
        raise ValueError(f"{where}: a part of the path is a file, not a directory") from None
    except UnicodeDecodeError as err:  # e.g. a binary file (a pickle) in its place
        raise ValueError(f"{where} is not UTF-8 text ({err.reason} at byte {err.start})") from None


#: Deepest nesting of lists and tables accepted in a file the package reads (specs, configs):
#: theirs is at most 3; JSON's and TOML's parsers recurse, so a file nested thousands deep would
#: end in a ``RecursionError`` instead of a refusal.
NESTING_MAX = 32

_JSON_TOKENS = re.compile(r'"(?:\\.|[^"\\])*"|[\[\]{}]')
#: One TOML key segment: bare, or a basic or literal string.
_TOML_KEY = r'(?:[A-Za-z0-9_-]+|"(?:\\.|[^"\\\n])*"|\'[^\'\n]*\')'
_TOML_TOKENS = re.compile(
    r'"""(?:\\.|[^\\])*?"""|\'\'\'[\s\S]*?\'\'\''  # multi-line strings
    rf"|(?P<key>{_TOML_KEY}(?:[ \t]*\.[ \t]*{_TOML_KEY})+)"  # a dotted key (a float: one dot)
    r'|"(?:\\.|[^"\\\n])*"|\'[^\'\n]*\'|#[^\n]*|[\[\]{}]'
)
_TOML_SEGMENT = re.compile(_TOML_KEY)


def _text_depth(text: str, tokens: re.Pattern) -> int:
    """Deepest nesting in ``text`` that the parser would recurse or loop into: of ``[``/``{``
    outside strings (and TOML comments), and of a TOML dotted key's segments (``a.b.c``: 3;
    tomllib's time and memory grow with their square)."""
    depth = deepest = 0
    for match in tokens.finditer(text):
        token = match.group()
        if token in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif token in "]}":
            depth -= 1
        elif match.lastgroup == "key":  # its segments, dots inside quoted ones not counted
            deepest = max(deepest, len(_TOML_SEGMENT.findall(token)) - 1)
    return deepest


def json_depth(text: str | bytes) -> int:
    """How deeply the arrays and objects of JSON ``text`` nest (0: a bare value), counted without
    parsing it: Python's ``json`` recurses once per level and raises ``RecursionError`` on a few
    thousand, so a reader of untrusted JSON checks this first."""
    if isinstance(text, (bytes, bytearray)):
        text = bytes(text).decode("utf-8", "replace")
    return _text_depth(text, _JSON_TOKENS)


def nesting_depth(data: Any) -> int:
    """Nesting of lists and dicts in ``data`` (a scalar: 0, ``[1]``: 1), without recursion."""
    deepest, stack = 0, [(data, 0)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            item = list(item.values())
        elif not isinstance(item, (list, tuple)):
            continue
        deepest = max(deepest, depth + 1)
        stack.extend((child, depth + 1) for child in item)
    return deepest


def parse_document(where: str, text: str, kind: str, limit: int = NESTING_MAX) -> Any:
    """``text`` parsed as ``kind`` (``"json"`` or ``"toml"``); ``ValueError`` naming ``where`` for
    text that is not valid, or nested deeper than ``limit``: the brackets are counted before the
    parser (which recurses) runs, and the result measured after (TOML's dotted keys and table
    headers nest without brackets)."""
    tokens = _JSON_TOKENS if kind == "json" else _TOML_TOKENS
    if _text_depth(text, tokens) > limit:
        raise ValueError(
            f"{where} nests lists, tables or dotted keys more than {limit} deep; a spec or config "
            "needs a few levels"
        )
    if kind == "json":
        try:
            data = json.loads(text)
        except ValueError as err:  # JSONDecodeError, or an integer of more than 4300 digits
            raise ValueError(f"{where} is not valid JSON: {err}") from None
    else:
        try:
            import tomllib
        except ModuleNotFoundError:  # Python 3.10
            import tomli as tomllib
        try:
            data = tomllib.loads(text)
        except ValueError as err:  # TOMLDecodeError, or an integer of more than 4300 digits
            raise ValueError(f"{where} is not valid TOML: {err}") from None
    if nesting_depth(data) > limit:
        raise ValueError(
            f"{where} nests keys more than {limit} deep; a spec or config needs a few levels"
        )
    return data


# =================================================================================== settings

#: Key of a field's :class:`Setting` in its ``dataclasses.field`` metadata.
_SETTING_KEY = "himit_setting"


@dataclasses.dataclass(frozen=True)
class Setting:
    """What a configuration field is, beside its name, type (the annotation) and default.

    ``ge``/``gt``/``le``/``lt`` bound a number (a whole number takes ``ge``/``le`` only, and
    ``le`` defaults to :data:`COUNT_MAX`); ``choices`` are the strings a ``str`` field (or every
    item of a ``tuple[str, ...]``) may take; ``hint`` is added to a refusal (what the value
    means). ``kernel``: the compiled engine reads the field, encoded as a number — a choice as
    its index in ``choices``, ``None`` as ``kernel_none``. ``folder``: a ``str`` field that
    names a folder (:func:`as_folder_name`). ``empty``: a tuple field may hold no item (by
    default it needs at least one). ``mentor_term``: a setting of eq. 2's mentor term, read
    only by the agents that have one (a run's records name it for those agents alone:
    :func:`~himit_torch.learner.presets.agent_settings`).
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
    folder: bool = False
    empty: bool = False
    mentor_term: bool = False


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
        if info.folder:
            return as_folder_name(where, value)
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
                if not value and not s.info.empty:
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
