"""Exact option models computed once: kept on disk by content, shared by every batch, process and
run that models the same options in the same world.

A study builds the exact models of the same options in the same world again and again: the
mentor's policy and the exact evaluation of it, the greedy tracker, the optimum over primitives,
for every batch, preset and process (≈ 1 s each on the paper's largest worlds). An entry here is
keyed by what the models are computed from, never by an object's identity:

* the world's content fingerprint (``himit_torch.worlds.table_world.model_fingerprint``:
  its dynamics, rewards, terminal states and start),
* the options' content (:func:`options_fingerprint`: initiation sets, terminations, policies),
* the setting: the discount and the per-step reward (the world's, or unit costs for the
  durations).

Entries are NumPy ``.npz`` files read with ``allow_pickle=False``: arrays and a JSON header,
never pickled objects. An entry is trusted only after it is checked when read: its header names
the key asked for, its arrays have the dtypes and shapes a model of these options has (one row
per available ``(state, option)``, indices in range, a well-formed CSR matrix), and their
SHA-256 is the one written with them. A file that fails any of these is removed and the models
are computed again (and stored anew); a damaged entry is never used. Entries are written
atomically (a temporary file, then a rename), so processes sharing the folder read whole
entries or none.

What is computed from such models alone is kept by their key too: the value iteration that
gives the mentor's policy and the optimum over primitives (:func:`plan_key`, :func:`store_plan`,
:func:`load_plan`; ``values``, ``policy`` and ``q`` with the iteration count, checked as a
models entry is).

Where: the folder ``$HIMIT_EXACT_CACHE``; without it, ``exact`` under ``$XDG_CACHE_HOME/himit_torch``
(``~/.cache/himit_torch`` where that is unset). ``HIMIT_EXACT_CACHE=off`` turns the disk cache
off (the models are then computed in every process; within a process they are still shared).
:func:`clear_cache` empties it.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import tempfile
import weakref
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "CACHE_ENV",
    "cache_dir",
    "clear_cache",
    "options_fingerprint",
    "models_key",
    "load_models",
    "store_models",
    "remember_key",
    "key_of",
    "plan_key",
    "load_plan",
    "store_plan",
]

#: The environment variable naming the cache's folder (``off``: no disk cache).
CACHE_ENV = "HIMIT_EXACT_CACHE"
#: The layout of an entry; an entry of another format is never read.
_FORMAT = 1
_ARRAYS = ("row_state", "row_option", "reward", "indptr", "indices", "data")
_DTYPES = {
    "row_state": np.int64,
    "row_option": np.int64,
    "reward": np.float64,
    "indptr": np.int64,
    "indices": np.int64,
    "data": np.float64,
}


def cache_dir() -> Path | None:
    """The cache's folder (not created here), or ``None`` where ``HIMIT_EXACT_CACHE=off``."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen is not None:
        if chosen.strip().lower() in ("", "off", "0", "no", "false"):
            return None
        return Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "himit_torch" / "exact"


def clear_cache() -> int:
    """Remove every entry of the cache (and what an interrupted write left); the number of
    files removed. Also forgets the models and plans this process shares by content."""
    _BY_CONTENT.clear()
    _PLANS.clear()
    folder = cache_dir()
    if folder is None or not folder.is_dir():
        return 0
    removed = 0
    for path in folder.glob("*.npz*"):
        try:
            path.unlink()
            removed += 1
        except FileNotFoundError:
            pass
    return removed


# The options' fingerprints, by bundle while it is alive and unchanged (its tensors' version
# counters): hashing the [O, S] tables of a large bundle takes a fraction of a second.
_FINGERPRINTS: dict[int, tuple[weakref.ref, tuple[int, ...], str]] = {}


def options_fingerprint(options) -> str:
    """SHA-256 of an :class:`~himit_torch.Options` bundle's content: its initiation sets,
    terminations and policies (dtypes, shapes and bytes) and whether it is stochastic.
    Bundles with the same content have the same fingerprint, whatever their names."""
    tensors = (options.initiation, options.termination, options.policy)
    versions = tuple(t._version for t in tensors)
    known = _FINGERPRINTS.get(id(options))
    if known is not None and known[0]() is options and known[1] == versions:
        return known[2]
    digest = hashlib.sha256()
    digest.update(f"stochastic={bool(options.stochastic)}".encode())
    for t in tensors:
        array = t.detach().cpu().contiguous().numpy()
        digest.update(f"|{array.dtype.str}{array.shape}|".encode())
        digest.update(array.data.cast("B"))
    fingerprint = digest.hexdigest()
    try:
        _FINGERPRINTS[id(options)] = (weakref.ref(options), versions, fingerprint)
        weakref.finalize(options, _FINGERPRINTS.pop, id(options), None)
    except TypeError:  # (an object that takes no weak reference: not remembered)
        pass
    return fingerprint


def models_key(world, options, gamma: float, reward: str) -> str:
    """The cache's key of the exact models of ``options`` in ``world`` at discount ``gamma``
    with per-step reward ``reward`` (``"world"``: the world's; ``"ones"``: unit costs, the
    durations)."""
    from himit_torch.worlds.table_world import model_fingerprint

    described = {
        "format": _FORMAT,
        "world": model_fingerprint(world),
        "num_states": int(world.num_states),
        "num_actions": int(world.num_actions),
        "options": options_fingerprint(options),
        "gamma": float(gamma).hex(),
        "reward": reward,
    }
    return hashlib.sha256(json.dumps(described, sort_keys=True).encode()).hexdigest()


#: The models this process has computed or read last, by key (shared by every batch of the
#: process): at most :data:`_KEPT`, the least recently used dropped first (a large world's
#: models are tens of MB).
_BY_CONTENT: OrderedDict[str, object] = OrderedDict()
_KEPT = 8


def _keep(key: str, models) -> None:
    _BY_CONTENT[key] = models
    _BY_CONTENT.move_to_end(key)
    while len(_BY_CONTENT) > _KEPT:
        _BY_CONTENT.popitem(last=False)


def _digest(arrays: dict[str, np.ndarray], names: tuple[str, ...] = _ARRAYS) -> str:
    digest = hashlib.sha256()
    for name in names:
        a = np.ascontiguousarray(arrays[name])
        digest.update(f"|{name}{a.dtype.str}{a.shape}|".encode())
        digest.update(a.data.cast("B"))
    return digest.hexdigest()


def _path(folder: Path, key: str) -> Path:
    return folder / f"{key}.npz"


def _stored_entry(key: str) -> Path | None:
    """The file of the entry ``key`` where the disk cache is on and holds one, else ``None``."""
    folder = cache_dir()
    if folder is None:
        return None
    path = _path(folder, key)
    return path if path.is_file() else None


def store_models(key: str, models) -> None:
    """Keep ``models`` (an :class:`~himit_torch.exact.option_models.OptionModels`) under
    ``key``: in this process, and on disk where the cache is on. A folder that cannot be
    written leaves the models in this process only."""
    _keep(key, models)
    folder = cache_dir()
    if folder is None:
        return
    transition = models.transition
    arrays = {
        "row_state": models.row_state.numpy(),
        "row_option": models.row_option.numpy(),
        "reward": models.reward.numpy(),
        "indptr": transition.crow_indices().numpy(),
        "indices": transition.col_indices().numpy(),
        "data": transition.values().numpy(),
    }
    header = {
        "format": _FORMAT,
        "key": key,
        "num_options": int(models.num_options),
        "num_states": int(transition.shape[1]),
        "sha256": _digest(arrays),
    }
    _write(folder, key, header, arrays)


def _write(folder: Path, key: str, header: dict, arrays: dict[str, Any]) -> None:
    """Write an entry atomically (a temporary file, then a rename); a folder that cannot be
    written leaves it unwritten."""
    buffer = io.BytesIO()
    np.savez(buffer, header=np.array(json.dumps(header)), **arrays)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle, tmp = tempfile.mkstemp(dir=folder, prefix=f"{key}.", suffix=".npz.tmp")
        try:
            with os.fdopen(handle, "wb") as f:
                f.write(buffer.getbuffer())
            os.replace(tmp, _path(folder, key))
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError:
        pass  # (a read-only or full disk: the entry stays this process's)


def _open(path: Path, names: tuple[str, ...]) -> tuple[Any, dict[str, np.ndarray]] | None:
    """An entry's header (parsed JSON) and its arrays ``names``, or ``None`` where the file is
    not an archive of exactly those (read without pickle)."""
    try:
        with np.load(io.BytesIO(path.read_bytes()), allow_pickle=False) as entry:
            if set(entry.files) != {"header", *names}:
                return None
            return json.loads(str(entry["header"][()])), {name: entry[name] for name in names}
    except Exception:  # (whatever a damaged archive raises: zip, NPY or JSON errors)
        return None


def _read(path: Path, key: str, num_options: int, num_states: int) -> dict | None:
    """The arrays of the entry at ``path``, or ``None`` where it is missing or fails a check
    (module docstring)."""
    opened = _open(path, _ARRAYS)
    if opened is None:
        return None
    header, arrays = opened
    S, O = num_states, num_options
    M = arrays["row_state"].shape[0] if arrays["row_state"].ndim == 1 else -1
    checks = (
        isinstance(header, dict)
        and header.get("format") == _FORMAT
        and header.get("key") == key
        and header.get("num_options") == O
        and header.get("num_states") == S
        and all(arrays[n].dtype == _DTYPES[n] and arrays[n].ndim == 1 for n in _ARRAYS)
        and arrays["row_state"].shape
        == arrays["row_option"].shape
        == arrays["reward"].shape
        == (M,)
        and arrays["indptr"].shape == (M + 1,)
        and arrays["indices"].shape == arrays["data"].shape
    )
    if not checks or header.get("sha256") != _digest(arrays):
        return None
    indptr, indices = arrays["indptr"], arrays["indices"]
    if (
        indptr[0] != 0
        or indptr[-1] != indices.size
        or (np.diff(indptr) < 0).any()
        or (indices.size and (indices.min() < 0 or indices.max() >= S))
    ):
        return None
    return arrays


def load_models(key: str, options, build: Callable[[dict[str, np.ndarray], int, int], Any]):
    """The models kept under ``key`` for ``options``, or ``None``: this process's first, then
    the disk's, checked (module docstring) and made by ``build(arrays, num_options)`` (the
    arrays :func:`store_models` writes: ``row_state``, ``row_option``, ``reward`` and the
    transition's CSR ``indptr``, ``indices``, ``data``); a damaged entry is removed (the caller
    computes the models again and stores them)."""
    known = _BY_CONTENT.get(key)
    if known is not None:
        _BY_CONTENT.move_to_end(key)
        return known
    path = _stored_entry(key)
    if path is None:
        return None
    arrays = _read(path, key, int(options.num_options), int(options.num_states))
    if arrays is not None:
        # its rows are the options' available (state, option) pairs, option by option
        pairs = options.initiation.nonzero().cpu().numpy()
        if not (
            np.array_equal(arrays["row_option"], pairs[:, 0])
            and np.array_equal(arrays["row_state"], pairs[:, 1])
        ):
            arrays = None
    if arrays is None:
        path.unlink(missing_ok=True)  # damaged: never trusted, computed again
        return None
    models = build(arrays, int(options.num_options), int(options.num_states))
    _keep(key, models)
    return models


# ======================================================================= plans
# The key each model this process holds was computed or read under, by the models object while
# it is alive: what a value iteration on those models is cached by (exact.planning).
_MODEL_KEYS: dict[int, tuple[weakref.ref, str]] = {}
_PLAN_ARRAYS = ("values", "policy", "q")
_PLAN_DTYPES = {"values": np.float64, "policy": np.int64, "q": np.float64}
#: The plans this process has computed or read last, by key (small: ``[S]`` and ``[M]`` arrays).
_PLANS: OrderedDict[str, tuple[dict, dict[str, np.ndarray]]] = OrderedDict()
_PLANS_KEPT = 64


def remember_key(models, key: str) -> None:
    """Note that ``models`` are the models kept under ``key`` (:func:`models_key`), so that what
    is computed from them alone (:func:`plan_key`) can be kept by content too."""
    try:
        _MODEL_KEYS[id(models)] = (weakref.ref(models), key)
        weakref.finalize(models, _MODEL_KEYS.pop, id(models), None)
    except TypeError:  # (an object that takes no weak reference: not remembered)
        pass


def key_of(models) -> str | None:
    """The key ``models`` were kept under (:func:`remember_key`), or ``None`` (models made
    some other way: nothing computed from them is cached)."""
    known = _MODEL_KEYS.get(id(models))
    return known[1] if known is not None and known[0]() is models else None


def plan_key(models: str, solver: str, **settings: Any) -> str:
    """The cache's key of what ``solver`` computes from the models kept under the key
    ``models`` alone, with ``settings`` (e.g. a tolerance)."""
    described = {"format": _FORMAT, "models": models, "solver": solver, **settings}
    return hashlib.sha256(json.dumps(described, sort_keys=True).encode()).hexdigest()


def store_plan(key: str, values, policy, q, iterations: int) -> None:
    """Keep a value iteration's result under ``key`` (:func:`plan_key`): ``values [S]``,
    ``policy [S]`` and ``q [M]`` (tensors or arrays), in this process and on disk where the
    cache is on."""
    arrays = {
        "values": np.asarray(values, dtype=np.float64),
        "policy": np.asarray(policy, dtype=np.int64),
        "q": np.asarray(q, dtype=np.float64),
    }
    header = {
        "format": _FORMAT,
        "key": key,
        "kind": "plan",
        "num_states": int(arrays["values"].shape[0]),
        "num_rows": int(arrays["q"].shape[0]),
        "iterations": int(iterations),
        "sha256": _digest(arrays, _PLAN_ARRAYS),
    }
    _keep_plan(key, header, arrays)
    folder = cache_dir()
    if folder is not None:
        _write(folder, key, header, arrays)


def load_plan(
    key: str, num_states: int, num_rows: int, num_options: int
) -> tuple[dict, int] | None:
    """The arrays (``values``, ``policy``, ``q``: fresh copies) and iteration count kept under
    ``key`` for models of ``num_states`` states, ``num_rows`` rows and ``num_options`` options,
    or ``None``: this process's first, then the disk's, checked as a models entry is (its header
    names ``key``, its shapes, dtypes and SHA-256; every policy entry an option or −1); a
    damaged entry is removed."""
    known = _PLANS.get(key)
    if known is not None:
        _PLANS.move_to_end(key)
        header, arrays = known
        return {k: a.copy() for k, a in arrays.items()}, int(header["iterations"])
    path = _stored_entry(key)
    if path is None:
        return None
    found = _read_plan(path, key, num_states, num_rows, num_options)
    if found is None:
        path.unlink(missing_ok=True)  # damaged: never trusted, computed again
        return None
    header, arrays = found
    _keep_plan(key, header, arrays)
    return arrays, int(header["iterations"])


def _keep_plan(key: str, header: dict, arrays: dict[str, np.ndarray]) -> None:
    _PLANS[key] = (header, {k: a.copy() for k, a in arrays.items()})
    _PLANS.move_to_end(key)
    while len(_PLANS) > _PLANS_KEPT:
        _PLANS.popitem(last=False)


def _read_plan(path: Path, key: str, num_states: int, num_rows: int, num_options: int):
    """``(header, arrays)`` of the plan entry at ``path``, or ``None`` where it fails a check."""
    opened = _open(path, _PLAN_ARRAYS)
    if opened is None:
        return None
    header, arrays = opened
    shapes = {"values": (num_states,), "policy": (num_states,), "q": (num_rows,)}
    checks = (
        isinstance(header, dict)
        and header.get("format") == _FORMAT
        and header.get("kind") == "plan"
        and header.get("key") == key
        and header.get("num_states") == num_states
        and header.get("num_rows") == num_rows
        and type(header.get("iterations")) is int
        and all(
            arrays[n].dtype == _PLAN_DTYPES[n] and arrays[n].shape == shapes[n]
            for n in _PLAN_ARRAYS
        )
    )
    if not checks or header.get("sha256") != _digest(arrays, _PLAN_ARRAYS):
        return None
    policy = arrays["policy"]
    if policy.size and (policy.min() < -1 or policy.max() >= num_options):
        return None
    return header, arrays
